"""Transparency and rough dielectrics: alpha-cut leaf cards (Principled Alpha, and a tinted
Transparent BSDF mixed with a Translucent leaf) in front of a rough glass sphere nested inside a
smooth glass box (glass in glass), on a diffuse floor under the sky and a sun."""
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.6, 0.55, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    rough = sb.bsdf_material("Rough glass", "ShaderNodeBsdfGlass", IOR=1.5, Roughness=0.3, Color=(0.9, 1.0, 0.9))
    sb.add_uv_sphere(scene, "Rough sphere", (0.3, 0.3, 0.45), 0.3, rough)
    clear = sb.bsdf_material("Glass box", "ShaderNodeBsdfGlass", IOR=1.45, Roughness=0.0)
    sb.add_box(scene, "Glass box", (0.3, 0.3, 0.45), 0.8, clear)
    leaf = sb.bsdf_material("Leaf card", Base_Color=(0.2, 0.6, 0.1), Roughness=0.5, Alpha=0.35)
    sb.add_quad(scene, "Leaf", [(-1.2, -0.6, 0.0), (-0.3, -0.6, 0.0), (-0.3, -0.6, 1.0), (-1.2, -0.6, 1.0)], leaf)
    mat, nodes, links, output = sb._material("Translucent leaf")
    transparent = nodes.new("ShaderNodeBsdfTransparent")
    transparent.inputs["Color"].default_value = (0.9, 0.7, 0.3, 1.0)
    translucent = nodes.new("ShaderNodeBsdfTranslucent")
    translucent.inputs["Color"].default_value = (0.3, 0.7, 0.2, 1.0)
    mix = nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.6
    links.new(transparent.outputs[0], mix.inputs[1])
    links.new(translucent.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], output.inputs["Surface"])
    sb.add_quad(scene, "Leaf 2", [(-0.9, -1.0, 0.0), (-0.9, -1.0, 0.9), (0.0, -1.2, 0.9), (0.0, -1.2, 0.0)], mat)
    sb.add_sun_light(scene, (0.3, 0.5, -1.0), strength=3.0, angle_deg=5.0)
    sb.set_world_background(scene, (0.5, 0.65, 0.9), 0.6)
    sb.add_camera(scene, (0.0, -3.4, 1.3), (0.0, 0.0, 0.45), lens_mm=38.0)
    return scene


if __name__ == "__main__":
    sb.main_for(build)
