"""A coloured absorbing medium (Volume Absorption) in front of a bright emissive backdrop.

sigma_a = (1 - color) * density (Cycles svm/closure.h); transmittance through the 1 m cube is
exp(-sigma_a), so the backdrop shows through tinted.
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=1.5, color=(0.2, 0.55, 0.9)):
    scene = sb.new_scene(resolution, samples)
    backdrop = sb.emission_material("Backdrop", (1.0, 0.95, 0.9), 2.0)
    sb.add_quad(scene, "Backdrop", [(-2, 1.5, -1.0), (2, 1.5, -1.0), (2, 1.5, 2.0), (-2, 1.5, 2.0)], backdrop)
    glass = sb.absorption_volume_material("Absorber", density=density, color=color)
    box = sb.add_box(scene, "Absorber", (0.0, 0.0, 0.5), 1.0, glass)
    box.rotation_euler = (0.3, 0.2, 0.6)  # varying path lengths across the cube
    sb.add_camera(scene, (0.0, -4.5, 0.9), (0.0, 0.0, 0.5), lens_mm=40.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
