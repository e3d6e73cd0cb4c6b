"""An emissive, scattering medium (Principled Volume emission) as the only light in a Cornell box.

Volume emission is radiance per unit length, not scaled by density (Cycles svm/closure.h).
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
    glow = sb.principled_volume_material("Glow", density=1.0, color=(0.6, 0.6, 0.6),
                                         emission_color=(1.0, 0.6, 0.25), emission_strength=3.0)
    sb.add_box(scene, "Glow", (0.0, 0.1, 0.6), (0.8, 0.8, 0.8), glow)
    sb.cornell_camera(scene, BOX)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
