"""The Material Output's Displacement in Cycles' default "Bump Only" method (issue 11): a sphere
object scaled by 1.6 whose Wave texture (Object coordinates) drives a Displacement node in Object
space (Midlevel 0.3, Scale 0.12: the object's scale makes it 0.19 in the world) plugged into the
output -- no Bump node -- on a grey floor, lit by a grazing area light from the left that shows
the bands' slopes, with a dim sky. The sphere's shadow terminator geometry offset is 0 (VolPath has
none)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

import bpy  # noqa: E402


def displaced_material(name: str):
    mat = sb.bsdf_material(name, Base_Color=(0.75, 0.7, 0.65), Roughness=0.35)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    output = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    coords = nodes.new("ShaderNodeTexCoord")
    wave = nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 1.0  # bands 0.31 apart in object space, 0.5 m in the world
    links.new(coords.outputs["Object"], wave.inputs["Vector"])
    displacement = nodes.new("ShaderNodeDisplacement")  # space Object (Blender's default)
    displacement.inputs["Midlevel"].default_value = 0.3
    displacement.inputs["Scale"].default_value = 0.12
    links.new(wave.outputs["Fac"], displacement.inputs["Height"])
    links.new(displacement.outputs["Displacement"], output.inputs["Displacement"])
    assert mat.displacement_method == "BUMP"  # Blender's default: "Bump Only"
    return mat


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    sphere = sb.add_uv_sphere(scene, "Displaced sphere", (0.0, 0.0, 0.0), 0.35, displaced_material("Displaced sphere"))
    sphere.location = (0.0, 0.2, 0.58)
    sphere.scale = (1.6, 1.6, 1.6)
    # Cycles' shadow terminator geometry offset (kernel/light/sample.h shadow_ray_offset,
    # default 0.1) lifts shadow rays off smooth triangles where the shading normal faces the light;
    # VolPath has none (README), and a bumped shading normal faces the light well past the facets' terminator
    sphere.shadow_terminator_geometry_offset = 0.0
    sb.add_area_light(scene, (-2.6, -1.0, 0.9), (0.0, 0.2, 0.58), power_w=120.0, size=0.4)
    sb.set_world_background(scene, (0.6, 0.7, 0.9), 0.1)
    sb.add_camera(scene, (0.0, -2.4, 1.0), (0.0, 0.2, 0.55), lens_mm=35.0)
    return scene


_ = bpy

if __name__ == "__main__":
    sb.main_for(build)
