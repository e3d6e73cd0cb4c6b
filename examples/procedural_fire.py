"""An emissive procedural fire: the noise cloud's density (Color Ramp(Noise) x spherical Gradient)
also drives a Principled Volume's Emission Strength, with blackbody emission from a Temperature
made by a Map Range of the same density, in the dark (issue 18's 'emissive procedural fire')."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb
from examples.noise_cloud import noise_cloud_material


def fire_material(name="Procedural Fire"):
    material = noise_cloud_material(name, density=3.0)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    volume = next(n for n in nodes if n.type == "PRINCIPLED_VOLUME")
    density = volume.inputs["Density"].links[0].from_socket
    strength = nodes.new("ShaderNodeMath")
    strength.operation = "MULTIPLY"
    strength.inputs[1].default_value = 4.0
    links.new(density, strength.inputs[0])
    links.new(strength.outputs["Value"], volume.inputs["Emission Strength"])
    volume.inputs["Emission Color"].default_value = (1.0, 0.35, 0.08, 1.0)
    temperature = nodes.new("ShaderNodeMapRange")
    temperature.inputs["From Min"].default_value = 0.0
    temperature.inputs["From Max"].default_value = 3.0
    temperature.inputs["To Min"].default_value = 800.0
    temperature.inputs["To Max"].default_value = 1600.0
    links.new(density, temperature.inputs["Value"])
    links.new(temperature.outputs["Result"], volume.inputs["Temperature"])
    volume.inputs["Blackbody Intensity"].default_value = 0.5
    return material


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], floor)
    sb.add_box(scene, "Fire", (0.0, 0.0, 1.3), (2.4, 2.4, 2.4), fire_material())
    sb.add_camera(scene, (0.0, -6.0, 1.6), (0.0, 0.0, 1.2), lens_mm=35.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
