"""A tilted area light inside a fog box, seen by a camera 5 cm outside the fog: its near clip
(10 cm) lies inside, so camera rays start in the fog without crossing its boundary."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=0.05, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (5.9, 5.9, 2.98), fog)  # y from -2.95
    # One-sided, looking at a target: fog above and behind it too.
    sb.add_area_light(scene, (-0.5, -1.2, 2.0), (0.0, 0.0, 0.3), power_w=200.0, size=0.8)
    sb.add_camera(scene, (0.0, -3.0, 1.2), (0.0, 0.0, 0.4), lens_mm=40.0)  # clip_start 0.1 (default)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
