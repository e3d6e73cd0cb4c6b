"""Camera motion blur in fog: a camera panning and sliding past a sphere under a spot in a fog
box, the shutter open for a whole frame (Cycles' camera motion steps and shutter; the scene's
objects stand still: VolPath blurs only the camera's motion)."""
import math
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=0.2, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (4.0, 4.0, 2.98), fog)
    ball = sb.diffuse_material("Ball", (0.8, 0.3, 0.2))
    sb.add_uv_sphere(scene, "Ball", (0.2, 0.3, 0.6), 0.45, ball)
    sb.add_spot_light(scene, (0.6, 0.8, 2.8), (-0.3, -0.2, 0.0), power_w=1000.0, spot_size_deg=35.0, blend=0.2)
    camera = sb.add_camera(scene, (-1.0, -6.5, 1.4), (0.0, 0.0, 1.0), lens_mm=32.0)
    scene.frame_set(1)
    camera.keyframe_insert("location", frame=1)
    camera.keyframe_insert("rotation_euler", frame=1)
    camera.location.x += 3.0
    camera.rotation_euler.z -= math.radians(20.0)  # turning right as it slides right: the image sweeps
    camera.keyframe_insert("location", frame=3)
    camera.keyframe_insert("rotation_euler", frame=3)
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 1.0
    return scene


if __name__ == "__main__":
    sb.main_for(build)
