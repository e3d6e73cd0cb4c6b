"""A dense coloured medium inside a thin grey fog filling a Cornell box (a medium inside a medium).

Where volumes overlap their coefficients add (Cycles' volume stack).
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

BOX = 2.0


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    sb.add_cornell_box(scene, BOX)
    fog = sb.principled_volume_material("Fog", density=0.3, color=(0.8, 0.8, 0.8))
    sb.add_box(scene, "Fog", (0.0, 0.0, BOX / 2), (BOX - 0.01,) * 3, fog)
    core = sb.principled_volume_material("Core", density=3.0, color=(0.9, 0.5, 0.2))
    sb.add_box(scene, "Core", (0.0, 0.1, 0.55), (0.7, 0.7, 0.7), core)
    sb.add_point_light(scene, (0.0, 0.0, BOX * 0.85), power_w=100.0)
    sb.cornell_camera(scene, BOX)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
