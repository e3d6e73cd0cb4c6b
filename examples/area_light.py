"""A square area light under the ceiling of a foggy Cornell box (its emitting face is in view)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

BOX = 2.0


def build(resolution=(64, 64), samples=64, density=0.5, albedo=0.8):
    scene = sb.new_scene(resolution, samples)
    sb.add_cornell_box(scene, BOX)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, BOX / 2), (BOX - 0.01,) * 3, fog)
    # Facing down, 10 cm under the ceiling (inside the fog).
    sb.add_area_light(scene, (0.0, 0.2, BOX - 0.1), (0.0, 0.2, 0.0), power_w=150.0, size=0.6)
    sb.cornell_camera(scene, BOX)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
