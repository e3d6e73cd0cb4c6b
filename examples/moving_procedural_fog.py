"""A moving procedural volume: a box of fog whose Density ramps along its own X axis (Texture
Coordinate > Object -> Separate XYZ -> Map Range), sliding and turning while the shutter is open for
a whole frame, in front of a bright sky, over a grey floor under a sun. Cycles shades a moving
volume with the object's transform at each ray's time (its density pattern travels with the
box); VolPath places the medium at each path's time (volpath_native/medium_motion.py)."""
import math
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def ramp_material(name="Ramp Fog", low=0.0, high=3.0, color=(0.35, 0.35, 0.35)):
    """Density = Map Range(Object X, -0.5 .. 0.5 -> low .. high) of a unit box (Principled Volume)."""
    material = sb.principled_volume_material(name, density=1.0, color=color)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    volume = next(n for n in nodes if n.type == "PRINCIPLED_VOLUME")
    coords = nodes.new("ShaderNodeTexCoord")
    separate = nodes.new("ShaderNodeSeparateXYZ")
    map_range = nodes.new("ShaderNodeMapRange")
    map_range.inputs["From Min"].default_value = -0.5
    map_range.inputs["From Max"].default_value = 0.5
    map_range.inputs["To Min"].default_value = low
    map_range.inputs["To Max"].default_value = high
    links.new(coords.outputs["Object"], separate.inputs["Vector"])
    links.new(separate.outputs["X"], map_range.inputs["Value"])
    links.new(map_range.outputs["Result"], volume.inputs["Density"])
    return material


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    box = sb.add_box(scene, "Fog", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), ramp_material())
    sb.add_sun_light(scene, (0.3, 0.4, -1.0), strength=2.0)
    sb.set_world_background(scene, (0.8, 0.85, 1.0), 1.5)
    sb.add_camera(scene, (0.0, -5.0, 1.2), (0.0, 0.0, 0.9), lens_mm=40.0)
    scene.frame_set(1)
    box.location, box.rotation_euler = (-0.7, 0.0, 1.0), (0.0, 0.0, 0.0)
    box.keyframe_insert("location", frame=1)
    box.keyframe_insert("rotation_euler", frame=1)
    box.location, box.rotation_euler = (0.7, 0.0, 0.9), (0.0, math.radians(20.0), math.radians(90.0))
    box.keyframe_insert("location", frame=3)
    box.keyframe_insert("rotation_euler", frame=3)
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 1.0
    return scene


if __name__ == "__main__":
    sb.main_for(build)
