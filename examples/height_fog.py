"""Procedural height fog: a Principled Volume whose Density falls off with height (Texture
Coordinate > Object -> Separate XYZ -> Map Range), over a floor with a box, lit by a sun and a spot.
The medium is evaluated by the shader program at every collision (issue 18)."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def height_fog_material(name="Height Fog", bottom_density=1.2, top_density=0.0, color=(0.9, 0.9, 0.9)):
    """Density = Map Range(Object Z, 0 .. 2 -> bottom .. top), clamped (Principled Volume)."""
    material = sb.principled_volume_material(name, density=1.0, color=color)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    volume = next(n for n in nodes if n.type == "PRINCIPLED_VOLUME")
    coords = nodes.new("ShaderNodeTexCoord")
    separate = nodes.new("ShaderNodeSeparateXYZ")
    map_range = nodes.new("ShaderNodeMapRange")
    map_range.inputs["From Min"].default_value = 0.0
    map_range.inputs["From Max"].default_value = 2.0
    map_range.inputs["To Min"].default_value = bottom_density
    map_range.inputs["To Max"].default_value = top_density
    links.new(coords.outputs["Object"], separate.inputs["Vector"])
    links.new(separate.outputs["Z"], map_range.inputs["Value"])
    links.new(map_range.outputs["Result"], volume.inputs["Density"])
    return material


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    sb.add_box(scene, "Block", (0.6, 0.4, 0.4), (0.8, 0.8, 0.8), sb.diffuse_material("Block", (0.7, 0.3, 0.2)))
    sb.add_box(scene, "Fog", (0.0, 0.0, 1.0), (5.0, 5.0, 1.98), height_fog_material())
    sb.add_sun_light(scene, (0.4, 0.3, -1.0), strength=2.0)
    sb.add_spot_light(scene, (-0.8, -0.6, 2.6), (-0.3, 0.2, 0.0), power_w=600.0, spot_size_deg=40.0, blend=0.2)
    sb.add_camera(scene, (0.0, -6.0, 1.5), (0.0, 0.0, 0.7), lens_mm=30.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
