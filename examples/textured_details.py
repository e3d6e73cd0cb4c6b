"""Normal maps, textured alpha and colour attributes: a glossy sphere whose Normal comes from a
tangent-space Normal Map of a packed Non-Color image (Blender's MikkTSpace tangents of its UV
map), a Principled leaf card whose Base Color and Alpha come from one RGBA image (Alpha output
linked: un-premultiplied as Cycles), and a box painted with a per-corner Color Attribute, in a
light fog under a spot light."""
import math
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb
from examples.textured_surfaces import packed_image, set_uvs

import bpy  # noqa: E402


def normal_map_image(name: str, size: int = 32):
    """A tangent-space normal map of bumps h = 0.08 sin(8 pi u) sin(4 pi v) (u across, v up)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    dhdu = 0.08 * 8 * math.pi * np.cos(8 * math.pi * u) * np.sin(4 * math.pi * v)
    dhdv = 0.08 * 4 * math.pi * np.sin(8 * math.pi * u) * np.cos(4 * math.pi * v)
    n = np.stack([-dhdu, -dhdv, np.ones_like(u)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rgba = np.concatenate([n * 0.5 + 0.5, np.ones_like(u)[..., None]], axis=-1)
    return packed_image(name, rgba, "Non-Color")


def normal_mapped_material(name: str, image):
    mat = sb.bsdf_material(name, Base_Color=(0.7, 0.5, 0.3), Roughness=0.35)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    normal_map = nodes.new("ShaderNodeNormalMap")
    normal_map.uv_map = "UVMap"
    links.new(tex.outputs["Color"], normal_map.inputs["Color"])
    links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def leaf_material(name: str):
    size = 16
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    inside = ((u - 0.5) ** 2 / 0.2 + (v - 0.5) ** 2 / 0.12) < 1.0
    alpha = np.where(inside, 1.0, 0.15 + 0.5 * u)
    rgba = np.stack([0.2 + 0.3 * v, 0.6 + 0.3 * u, 0.1 + 0.2 * u * v, alpha], axis=-1)
    image = packed_image(f"{name} image", rgba)
    mat = sb.bsdf_material(name, Roughness=0.6)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    return mat


def painted_material(name: str):
    mat = sb.bsdf_material(name, node_type="ShaderNodeBsdfDiffuse")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_DIFFUSE")
    attr = nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Paint"
    links.new(attr.outputs["Color"], bsdf.inputs["Color"])
    return mat


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    floor = sb.diffuse_material("Floor", (0.6, 0.6, 0.6))
    sb.add_quad(scene, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], floor)
    sphere = sb.add_uv_sphere(scene, "Bumpy", (-0.7, 0.2, 0.5), 0.5,
                              normal_mapped_material("Bumpy", normal_map_image("bumps")))
    centre = np.array([-0.7, 0.2, 0.5])

    def sphere_uv(co):
        d = np.array(co) - centre
        d /= max(np.linalg.norm(d), 1e-12)
        return (math.atan2(d[1], d[0]) / (2 * math.pi)) % 1.0, 0.5 + math.asin(max(-1.0, min(1.0, d[2]))) / math.pi
    set_uvs(sphere, sphere_uv, periodic_u=True)
    leaf = sb.add_quad(scene, "Leaf", [(-0.1, -0.6, 0.1), (0.6, -0.6, 0.1), (0.6, -0.6, 0.8), (-0.1, -0.6, 0.8)],
                       leaf_material("Leaf"))
    set_uvs(leaf, lambda co: ((co.x + 0.1) / 0.7, (co.z - 0.1) / 0.7))
    box = sb.add_box(scene, "Painted box", (1.1, 0.4, 0.3), 0.6, painted_material("Painted"))
    paint = box.data.color_attributes.new("Paint", "FLOAT_COLOR", "CORNER")
    rng = np.random.default_rng(5)
    paint.data.foreach_set("color", np.concatenate([rng.uniform(0.05, 0.95, (len(paint.data), 3)),
                                                    np.ones((len(paint.data), 1))], axis=1).reshape(-1))
    fog = sb.scatter_volume_material("Fog", density=0.08, color=(0.9, 0.9, 0.9))
    sb.add_box(scene, "Fog box", (0.0, 0.0, 1.5), (6.5, 6.5, 3.2), fog)
    sb.add_spot_light(scene, (1.5, -2.0, 2.8), (0.0, 0.3, 0.3), power_w=700.0, spot_size_deg=60.0, blend=0.3)
    sb.set_world_background(scene, (0.5, 0.6, 0.8), 0.2)
    sb.add_camera(scene, (0.0, -3.0, 1.3), (0.0, 0.2, 0.5), lens_mm=30.0)
    return scene


_ = bpy

if __name__ == "__main__":
    sb.main_for(build)
