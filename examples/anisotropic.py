"""Henyey-Greenstein anisotropy: a fog cube lit from behind by a point light, seen by the camera.

Forward scattering (g = 0.7) makes a bright halo around the hidden light; backward scattering
(g = -0.5) dims it and brightens the lit side. `anisotropic_forward.py` / `anisotropic_backward.py`
build the two variants the agreement suite uses.
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, anisotropy=0.7, density=0.4, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3, anisotropy=anisotropy)
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.0), (2.0, 2.0, 1.98), fog)
    # Behind the fog (outside it) as seen from the camera, a little off-axis: light reaching the
    # camera is mostly scattered by small angles (g > 0) or large ones (g < 0).
    sb.add_point_light(scene, (0.3, 1.4, 1.3), power_w=300.0)
    sb.add_camera(scene, (0.0, -5.0, 1.1), (0.0, 0.0, 1.0), lens_mm=35.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
