"""Object motion blur in fog: a white sphere crossing a spot's beam in thin fog while the shutter
is open for a whole frame, beside a still copy of it (a linked duplicate: one mesh, two instances,
one moving), seen by a still camera (Cycles' object motion steps, shutter and instancing)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64, density=0.08, albedo=0.9):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    fog = sb.principled_volume_material("Fog", density=density, color=(albedo,) * 3)
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.5), (4.0, 4.0, 2.98), fog)
    white = sb.diffuse_material("Ball", (0.9, 0.9, 0.9))
    moving = sb.add_uv_sphere(scene, "Ball", (0.0, 0.0, 0.8), 0.5, white)
    still = moving.copy()  # shares the mesh
    still.location = (1.3, 1.0, 0.0)
    scene.collection.objects.link(still)
    sb.add_spot_light(scene, (0.0, -0.5, 2.9), (0.0, 0.0, 0.8), power_w=800.0, spot_size_deg=60.0, blend=0.3)
    sb.add_camera(scene, (0.0, -5.0, 1.2), (0.0, 0.0, 0.9), lens_mm=35.0)
    scene.frame_set(1)
    moving.location.x = -1.5
    moving.keyframe_insert("location", frame=1)
    moving.location.x = 1.5
    moving.keyframe_insert("location", frame=3)  # ~1.5 m (1.5 diameters) while the shutter is open
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 1.0
    return scene


if __name__ == "__main__":
    sb.main_for(build)
