"""Textured surfaces: an sRGB image on a wall's Principled Base Color (Linear), a Non-Color
roughness map on a metallic floor (Closest, Extend), and a sphere whose colour is a Noise
Texture through a Mix Color node (procedural texture on a surface, Generated coordinates), under
an area light and a dim sky. Images are packed into the .blend (bytes, as Blender stores them)."""
import math
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from examples import scene_builder as sb

import bpy  # noqa: E402


def packed_image(name: str, pixels: np.ndarray, colorspace: str = "sRGB"):
    """A packed 8-bit image from float RGBA pixels (H, W, 4), row 0 at the bottom."""
    h, w = pixels.shape[:2]
    image = bpy.data.images.new(name, w, h, alpha=True)
    image.colorspace_settings.name = colorspace
    image.pixels.foreach_set(np.ascontiguousarray(pixels, np.float32).reshape(-1))
    image.pack()
    return image


def set_uvs(obj, uv_of_vertex, periodic_u=False):
    """A UV map from a function of each loop's vertex position (periodic_u: faces crossing the
    u = 1 -> 0 seam get u + 1 on their small side, as a sphere's UV map)."""
    mesh = obj.data
    layer = mesh.uv_layers.new(name="UVMap")
    for polygon in mesh.polygons:
        uvs = [uv_of_vertex(mesh.vertices[mesh.loops[i].vertex_index].co) for i in polygon.loop_indices]
        us = [u for u, _ in uvs]
        if periodic_u and max(us) - min(us) > 0.5:  # the face crosses the u seam
            uvs = [(u + 1.0 if u < 0.5 else u, v) for u, v in uvs]
        for i, uv in zip(polygon.loop_indices, uvs):
            layer.data[i].uv = uv
    return layer


def image_material(name: str, image, socket: str, base=None, interpolation="Linear", extension="REPEAT",
                   **inputs):
    mat = sb.bsdf_material(name, **inputs)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = interpolation
    tex.extension = extension
    links.new(tex.outputs["Color"], bsdf.inputs[socket])
    return mat


def noise_material(name: str):
    mat = sb.bsdf_material(name, Roughness=0.4)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    by_id = {s.identifier: s for s in mix.inputs}  # the Mix node repeats names per data type
    by_id["A_Color"].default_value = (0.05, 0.2, 0.7, 1.0)
    by_id["B_Color"].default_value = (0.9, 0.6, 0.1, 1.0)
    links.new(noise.outputs["Fac"], by_id["Factor_Float"])
    links.new(next(s for s in mix.outputs if s.identifier == "Result_Color"), bsdf.inputs["Base Color"])
    return mat


def build(resolution=(64, 64), samples=64):
    scene = sb.new_scene(resolution, samples)
    # 16 x 16 sRGB picture: smooth hue gradient with a checker, so both interpolation and
    # decoding show
    y, x = np.mgrid[0:16, 0:16] / 15.0
    checker = ((np.mgrid[0:16, 0:16][0] // 4 + np.mgrid[0:16, 0:16][1] // 4) % 2).astype(float)
    picture = np.stack([0.2 + 0.7 * x, 0.3 + 0.5 * y * checker, 0.9 - 0.6 * x * y, np.ones_like(x)], axis=-1)
    wall_image = packed_image("wall picture", picture)
    roughness = np.repeat(np.linspace(0.05, 0.9, 16).reshape(4, 4)[..., None], 4, axis=-1)
    roughness[..., 3] = 1.0
    rough_image = packed_image("roughness map", roughness, "Non-Color")

    wall = image_material("Picture wall", wall_image, "Base Color", Roughness=0.6)
    obj = sb.add_quad(scene, "Wall", [(-2, 1.0, 0), (2, 1.0, 0), (2, 1.0, 2.5), (-2, 1.0, 2.5)], wall)
    set_uvs(obj, lambda co: ((co.x + 2.0) / 4.0, co.z / 2.5))
    floor = image_material("Rough floor", rough_image, "Roughness", interpolation="Closest", extension="EXTEND",
                           Base_Color=(0.8, 0.75, 0.7), Metallic=1.0)
    obj = sb.add_quad(scene, "Floor", [(-2, -2, 0), (2, -2, 0), (2, 1.0, 0), (-2, 1.0, 0)], floor)
    set_uvs(obj, lambda co: ((co.x + 2.0) / 4.0, (co.y + 2.0) / 3.0))
    sb.add_uv_sphere(scene, "Noise ball", (0.6, -0.3, 0.45), 0.45, noise_material("Noise ball"))
    sb.add_area_light(scene, (0.0, -1.5, 2.4), (0.0, 0.0, 0.5), power_w=300.0, size=1.0)
    sb.set_world_background(scene, (0.6, 0.7, 0.9), 0.3)
    sb.add_camera(scene, (0.0, -3.4, 1.2), (0.0, 0.0, 0.8), lens_mm=32.0)
    return scene


_ = math

if __name__ == "__main__":
    sb.main_for(build)
