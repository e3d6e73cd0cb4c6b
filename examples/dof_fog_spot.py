"""Depth of field in fog: the spot's cone through fog, seen by a camera with a wide hexagonal
aperture focused in front of the fog box, so the cone, the fog and the floor blur into the
aperture's shape (Cycles' lens: F-stop, focus distance, blades, rotation)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=0.25, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (4.0, 4.0, 2.98), fog)
    sb.add_spot_light(scene, (0.6, 0.8, 2.8), (-0.3, -0.2, 0.0), power_w=1000.0, spot_size_deg=35.0, blend=0.2)
    camera = sb.add_camera(scene, (0.0, -6.5, 1.4), (0.0, 0.0, 1.1), lens_mm=80.0)
    dof = camera.data.dof
    dof.use_dof = True
    dof.focus_distance = 3.5  # in front of the fog: all of it blurred, by up to ~5 px at 32x32
    dof.aperture_fstop = 0.1  # a 40 cm lens radius
    dof.aperture_blades = 6
    dof.aperture_rotation = 0.4
    return scene


if __name__ == "__main__":
    sb.main_for(build)
