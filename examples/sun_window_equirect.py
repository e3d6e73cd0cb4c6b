"""The sun-window room with its world volume, seen by an equirectangular (360 degree) camera in
the middle of the room: the whole sphere of directions through fog lit by the room's lamp
(Cycles' panoramic camera, equirectangular mapping)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb
from examples import sun_window


def build(resolution=(64, 32), samples=64, density=0.08, albedo=0.9):
    scene = sun_window.build(resolution=resolution, samples=samples, density=density, albedo=albedo,
                             world_volume=True)
    camera = sb.add_camera(scene, (0.2, -0.3, 1.4), (1.0, 0.0, 1.4), name="Panorama")
    camera.data.type = "PANO"
    camera.data.panorama_type = "EQUIRECTANGULAR"
    return scene


if __name__ == "__main__":
    sb.main_for(build)
