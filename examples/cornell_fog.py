"""Cornell box filled with homogeneous grey fog, lit by a point light under the ceiling.

The demo scene (`make demo`). Fog: Principled Volume, density 0.6 /m, albedo 0.7 -> optical
thickness 1.2 across the 2 m box, so single and multiple scattering both matter.
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

BOX = 2.0


def build(resolution=(64, 64), samples=64, density=0.6, albedo=0.7):
    scene = sb.new_scene(resolution, samples)
    sb.add_cornell_box(scene, BOX)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    # Slightly inside the walls so the medium boundary never coincides with a wall.
    inset = 0.01
    sb.add_box(scene, "Fog", (0.0, 0.0, BOX / 2), (BOX - inset, BOX - inset, BOX - inset), fog)
    sb.add_point_light(scene, (0.0, 0.0, BOX * 0.8), power_w=100.0)
    sb.cornell_camera(scene, BOX)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
