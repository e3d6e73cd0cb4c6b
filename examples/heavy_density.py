"""A heavy, high-albedo medium: a 1 m cube with sigma_t = 25 /m (optical thickness 25) on a floor.

Multiple scattering dominates; bounce limits are the same in both engines (scene_builder).
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=25.0, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    cloud = sb.principled_volume_material("Dense", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Dense", (0.0, 0.0, 0.51), 1.0, cloud)
    sb.add_point_light(scene, (1.2, -1.0, 2.2), power_w=500.0)
    sb.add_camera(scene, (0.0, -4.0, 1.6), (0.0, 0.0, 0.5), lens_mm=40.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
