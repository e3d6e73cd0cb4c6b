"""Surfaces driven by nodes beyond their colour (issue 11): a striped image on an Emission node
lights the scene (seen by the camera, hit by bounces and sampled as a mesh light); a Principled
card emits a Gradient texture through a Color Ramp; a sphere is bump-mapped by a Wave texture through a
Bump node (Distance 0.15); a second sphere wears an image in Box projection (Object coordinates,
Blend 0.3); all on a grey floor with a dim sky and a grazing area light from the left."""
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb
from examples.textured_surfaces import packed_image, set_uvs

import bpy  # noqa: E402


def stripes_image(name: str):
    """Three horizontal bands (red, green, blue from the bottom) with a white corner patch."""
    size = 12
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    band = np.minimum((v * 3).astype(int), 2)
    rgb = np.eye(3)[band] * 0.9 + 0.05
    rgb[(u > 0.75) & (v > 0.75)] = 1.0
    return packed_image(name, np.concatenate([rgb, np.ones((size, size, 1))], axis=-1))


def emissive_panel_material(name: str, image):
    mat, nodes, links, output = sb._material(name)
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 6.0
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    links.new(tex.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs["Emission"], output.inputs["Surface"])
    return mat


def checker_card_material(name: str):
    mat = sb.bsdf_material(name, Base_Color=(0.2, 0.2, 0.2), Roughness=0.8, Emission_Strength=2.0)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    gradient = nodes.new("ShaderNodeTexGradient")  # Generated x across the card
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (1.0, 0.5, 0.05, 1.0)
    ramp.color_ramp.elements[1].color = (0.05, 0.3, 1.0, 1.0)
    links.new(gradient.outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Emission Color"])
    return mat


def bumped_material(name: str):
    mat = sb.bsdf_material(name, Base_Color=(0.75, 0.7, 0.65), Roughness=0.3)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    coords = nodes.new("ShaderNodeTexCoord")
    wave = nodes.new("ShaderNodeTexWave")
    wave.inputs["Scale"].default_value = 0.6  # bands 0.52 m apart: several pixels wide
    links.new(coords.outputs["Object"], wave.inputs["Vector"])
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = 0.15
    links.new(wave.outputs["Fac"], bump.inputs["Height"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def box_projected_material(name: str, image):
    mat = sb.bsdf_material(name, Roughness=0.7)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    coords = nodes.new("ShaderNodeTexCoord")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.projection = "BOX"
    tex.projection_blend = 0.3
    links.new(coords.outputs["Object"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def box_image(name: str):
    """An asymmetric pattern (a diagonal ramp and an off-centre dot) so mirrored planes show."""
    size = 16
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    rgb = np.stack([0.15 + 0.8 * u, 0.15 + 0.8 * v, 0.3 + 0.0 * u], axis=-1)
    rgb[((u - 0.7) ** 2 + (v - 0.3) ** 2) < 0.03] = (0.95, 0.95, 0.95)
    return packed_image(name, np.concatenate([rgb, np.ones((size, size, 1))], axis=-1))


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.5, 0.5, 0.5))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    panel = sb.add_quad(scene, "Panel", [(-1.6, 1.2, 0.1), (-0.2, 1.2, 0.1), (-0.2, 1.2, 1.5), (-1.6, 1.2, 1.5)],
                        emissive_panel_material("Panel", stripes_image("stripes")))
    set_uvs(panel, lambda co: ((co.x + 1.6) / 1.4, (co.z - 0.1) / 1.4))
    sb.add_quad(scene, "Card", [(0.4, 1.3, 0.05), (1.5, 1.3, 0.05), (1.5, 1.3, 1.15), (0.4, 1.3, 1.15)],
                checker_card_material("Card"))
    sb.add_uv_sphere(scene, "Bumpy sphere", (-0.7, 0.2, 0.45), 0.45, bumped_material("Bumpy sphere"))
    sb.add_uv_sphere(scene, "Boxed sphere", (0.75, 0.1, 0.45), 0.45, box_projected_material("Boxed sphere",
                                                                                          box_image("box")))
    # a grazing light from the left shows the bumps' slopes
    sb.add_area_light(scene, (-2.6, -1.2, 0.9), (-0.7, 0.2, 0.45), power_w=120.0, size=0.4)
    sb.set_world_background(scene, (0.6, 0.7, 0.9), 0.1)
    sb.add_camera(scene, (0.0, -3.2, 1.4), (0.0, 0.4, 0.6), lens_mm=30.0)
    return scene


_ = bpy

if __name__ == "__main__":
    sb.main_for(build)
