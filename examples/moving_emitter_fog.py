"""Moving lights made of geometry, in moving fog: an emissive panel that slides and turns inside a
box of fog that drifts sideways while the shutter is open for a whole frame, over a grey floor,
seen by a still camera. Cycles samples the panel where it is at each ray's time and enters the fog
box where it is then (object motion of an emitter and of a volume boundary)."""
import math
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=0.25, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    box = sb.add_box(scene, "Fog", (0.0, 0.0, 0.0), (1.6, 2.0, 1.6), fog)
    glow = sb.emission_material("Glow", (1.0, 0.8, 0.6), 12.0)
    panel = sb.add_quad(scene, "Panel", [(-0.3, -0.3, 0), (0.3, -0.3, 0), (0.3, 0.3, 0), (-0.3, 0.3, 0)], glow)
    sb.add_camera(scene, (0.0, -5.0, 1.6), (0.0, 0.0, 0.8), lens_mm=35.0)
    scene.frame_set(1)
    panel.location, panel.rotation_euler = (-1.0, 0.0, 1.2), (0.0, 0.0, 0.0)
    box.location = (-0.6, 0.0, 1.0)
    for obj in (panel, box):
        obj.keyframe_insert("location", frame=1)
    panel.keyframe_insert("rotation_euler", frame=1)
    panel.location, panel.rotation_euler = (1.0, 0.0, 1.0), (math.radians(100.0), 0.0, 0.0)
    box.location = (0.6, 0.0, 1.0)
    for obj in (panel, box):
        obj.keyframe_insert("location", frame=3)
    panel.keyframe_insert("rotation_euler", frame=3)
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 1.0
    return scene


if __name__ == "__main__":
    sb.main_for(build)
