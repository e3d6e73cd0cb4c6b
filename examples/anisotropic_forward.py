"""Anisotropic fog, g = 0.7 (see anisotropic.py)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import anisotropic, scene_builder as sb

ANISOTROPY = 0.7


def build(resolution=(64, 64), samples=64):
    return anisotropic.build(resolution, samples, anisotropy=ANISOTROPY)


if __name__ == "__main__":
    sb.main_for(build)
