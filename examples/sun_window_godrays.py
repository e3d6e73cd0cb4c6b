"""Sun through a window into a room filled by a fog box: god rays (see sun_window.py)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb, sun_window


def build(resolution=(64, 64), samples=64):
    return sun_window.build(resolution, samples, density=0.15, world_volume=False)


if __name__ == "__main__":
    sb.main_for(build)
