"""Small scene builders for the add-on tests, made of plain bpy data calls (no operators, no
binary .blend files)."""
from __future__ import annotations

import math

import bpy
import numpy as np

CUBE_VERTICES = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1),
                 (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
# Counter-clockwise seen from outside: outward normals.
CUBE_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]


def add_camera(sc, name="Camera", location=(0.0, -6.0, 0.0), lens=50.0):
    cam = bpy.data.cameras.new(name)
    cam.lens = lens
    obj = bpy.data.objects.new(name, cam)
    obj.location = location
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # local -Z -> world +Y
    sc.collection.objects.link(obj)
    sc.camera = obj
    return obj


def add_mesh(sc, name, vertices=CUBE_VERTICES, faces=CUBE_FACES, material=None, location=(0, 0, 0),
             scale=(1, 1, 1), smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], [], [tuple(f) for f in faces])
    mesh.update()
    if smooth:
        for polygon in mesh.polygons:
            polygon.use_smooth = True
    obj = bpy.data.objects.new(name, mesh)
    if material is not None:
        mesh.materials.append(material)
    obj.location = location
    obj.scale = scale
    sc.collection.objects.link(obj)
    return obj


def add_light(sc, name, kind, energy, location=(0, 0, 0), rotation=(0, 0, 0), **settings):
    light = bpy.data.lights.new(name, kind)
    light.energy = energy
    for key, value in settings.items():
        setattr(light, key, value)
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    obj.rotation_euler = rotation
    sc.collection.objects.link(obj)
    return obj


def node_material(name, surface=None, volume=None):
    """A material whose output is fed by nodes built by the callables surface(tree) / volume(tree),
    each returning the output socket to connect (None: leave unconnected)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.target = "ALL"
    if surface is not None:
        tree.links.new(surface(tree), output.inputs["Surface"])
    if volume is not None:
        tree.links.new(volume(tree), output.inputs["Volume"])
    return mat


def shader(bl_idname, **inputs):
    """A node builder for node_material: shader('ShaderNodeBsdfDiffuse', Color=(1, 0, 0, 1))."""
    def build(tree):
        node = tree.nodes.new(bl_idname)
        for key, value in inputs.items():
            node.inputs[key.replace("_", " ")].default_value = value
        return node.outputs[0]
    return build


def export(sc):
    from addon.export import export_scene

    return export_scene(bpy.context.evaluated_depsgraph_get())


def read_exr(path) -> np.ndarray:
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise AssertionError(buf.geterror())
    return np.asarray(buf.get_pixels(oiio.FLOAT))
