"""A procedural cloud: Principled Volume Density = Color Ramp(Noise Texture) x spherical Gradient x 6,
and a faint procedural colour, in a cube over a floor, lit by a sun and a point light (issue 18's
'noise cloud through a Color Ramp with a spherical Gradient falloff')."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def noise_cloud_material(name="Noise Cloud", density=6.0, emission=0.0):
    material = sb.principled_volume_material(name, density=1.0, color=(0.85, 0.85, 0.85))
    nodes, links = material.node_tree.nodes, material.node_tree.links
    volume = next(n for n in nodes if n.type == "PRINCIPLED_VOLUME")
    coords = nodes.new("ShaderNodeTexCoord")
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 2.5
    noise.inputs["Detail"].default_value = 3.0
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.45
    ramp.color_ramp.elements[1].position = 0.7
    sphere = nodes.new("ShaderNodeTexGradient")
    sphere.gradient_type = "QUADRATIC_SPHERE"
    falloff = nodes.new("ShaderNodeMath")
    falloff.operation = "MULTIPLY"
    scale = nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = density
    centred = nodes.new("ShaderNodeVectorMath")  # Generated 0..1 -> -1..1 around the box centre
    centred.operation = "MULTIPLY_ADD"
    centred.inputs[1].default_value = (2.0, 2.0, 2.0)
    centred.inputs[2].default_value = (-1.0, -1.0, -1.0)
    links.new(coords.outputs["Generated"], centred.inputs[0])
    links.new(centred.outputs["Vector"], noise.inputs["Vector"])
    links.new(centred.outputs["Vector"], sphere.inputs["Vector"])
    links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], falloff.inputs[0])
    links.new(sphere.outputs["Fac"], falloff.inputs[1])
    links.new(falloff.outputs["Value"], scale.inputs[0])
    links.new(scale.outputs["Value"], volume.inputs["Density"])
    # a slight colour variation from the noise's colour output
    tint = nodes.new("ShaderNodeMix")
    tint.data_type = "RGBA"
    tint.inputs["Factor"].default_value = 0.3
    tint.inputs["A"].default_value = (0.9, 0.9, 0.9, 1.0)
    links.new(noise.outputs["Color"], tint.inputs["B"])
    links.new(tint.outputs["Result"], volume.inputs["Color"])
    if emission > 0:
        volume.inputs["Emission Strength"].default_value = emission
        volume.inputs["Emission Color"].default_value = (1.0, 0.4, 0.1, 1.0)
    return material


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], floor)
    sb.add_box(scene, "Cloud", (0.0, 0.0, 1.3), (2.4, 2.4, 2.4), noise_cloud_material())
    sb.add_sun_light(scene, (0.5, 0.4, -1.0), strength=3.0)
    sb.add_point_light(scene, (-2.0, -1.5, 2.8), power_w=800.0)
    sb.set_world_background(scene, (0.05, 0.07, 0.1), 1.0)
    sb.add_camera(scene, (0.0, -6.0, 1.6), (0.0, 0.0, 1.2), lens_mm=35.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
