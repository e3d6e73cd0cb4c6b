"""Sunlight through a window into a closed room, with a world volume.

The room is a closed box of diffuse walls with a window hole in the +X wall.
world_volume=True (the default, the agreement case): a thin world volume (Principled Volume in the
World's Volume socket) fills all space. Cycles then lets NO sunlight in: a sun is infinitely far
away, so its shadow rays cross an infinite length of world medium (transmittance 0; measured:
the room is exactly black without other lights). A small lamp inside the room lights the fog,
and the test checks that VolPath follows the same convention for the sun.
world_volume=False: the classic god-ray set-up instead, a fog box filling the room, lit by the sun
through the window.
"""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

ROOM = 3.0


def _wall_with_window(scene, material, x, size, window):
    """The x = const wall of the room as four quads around a window (y0, y1, z0, z1)."""
    y0, y1, z0, z1 = window
    h = size / 2
    quads = [
        [(x, -h, 0), (x, h, 0), (x, h, z0), (x, -h, z0)],            # below the window
        [(x, -h, z1), (x, h, z1), (x, h, size), (x, -h, size)],      # above
        [(x, -h, z0), (x, y0, z0), (x, y0, z1), (x, -h, z1)],        # left of it
        [(x, y1, z0), (x, h, z0), (x, h, z1), (x, y1, z1)],          # right of it
    ]
    for i, quad in enumerate(quads):
        sb.add_quad(scene, f"WindowWall{i}", quad, material)


def build(resolution=(64, 64), samples=64, density=0.08, albedo=0.9, world_volume=True):
    scene = sb.new_scene(resolution, samples)
    white = sb.diffuse_material("Walls", (0.7, 0.7, 0.7))
    h = ROOM / 2
    for name, quad in {
        "Floor": [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)],
        "Ceiling": [(-h, -h, ROOM), (-h, h, ROOM), (h, h, ROOM), (h, -h, ROOM)],
        "Back": [(-h, h, 0), (h, h, 0), (h, h, ROOM), (-h, h, ROOM)],
        "Front": [(-h, -h, 0), (-h, -h, ROOM), (h, -h, ROOM), (h, -h, 0)],
        "Left": [(-h, -h, 0), (-h, h, 0), (-h, h, ROOM), (-h, -h, ROOM)],
    }.items():
        sb.add_quad(scene, name, quad, white)
    _wall_with_window(scene, white, h, ROOM, (-0.5, 0.5, 1.2, 2.2))
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    if world_volume:
        sb.set_world_background(scene, (0.0, 0.0, 0.0), 0.0, volume_material=fog)
        sb.add_point_light(scene, (-0.6, 0.8, 2.4), power_w=60.0, name="RoomLamp")
    else:
        sb.add_box(scene, "Fog", (0.0, 0.0, ROOM / 2), (ROOM - 0.02,) * 3, fog)
    # Sunlight travelling into the room through the window, downwards.
    sb.add_sun_light(scene, (-1.0, 0.25, -0.6), strength=20.0, angle_deg=1.0)
    sb.add_camera(scene, (-h + 0.2, -h + 0.2, 1.5), (h, 0.3, 1.0), lens_mm=18.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
