"""Compile functions of the nodes that need a surface hit: SURFACE_NODE_COMPILERS[node.type](c, node)
-> {output identifier: register}, `c` a surface_programs.SurfaceShaderCompiler. Each follows the
node's Cycles compile (C5 = blender/cycles v5.0.0, src/scene/shader_nodes.cpp) into the surface
opcodes of volpath_native.shading (surface_ops.py) and the per-corner attributes the kernel
interpolates (names as volpath_native.surface_programs documents).
"""
from __future__ import annotations

import numpy as np

from volpath_native.shading import program as P
from volpath_native.shading.images import EXTENSIONS, INTERPOLATIONS

_PROJECTIONS = {"FLAT": 0, "SPHERE": 2, "TUBE": 3}


def _linked(node, identifier: str) -> bool:
    return any(o.identifier == identifier and o.is_linked for o in node.outputs)


def _image_texture(c, node) -> dict:
    """ImageTextureNode::compile / svm_node_tex_image."""
    owner = f"{c.owner}: node '{node.name}'"
    image = node.image
    frame = None
    if image is not None and image.source in ("SEQUENCE", "MOVIE"):
        frame = int(getattr(node.image_user, "frame_current", 0))
    tiles = c.images.tiles_of(image, owner)
    index = -1 if tiles else c.images.index_of(image, owner, frame)
    interpolation = node.interpolation
    if interpolation not in INTERPOLATIONS:
        c.warn(node, f"interpolation {interpolation} is not supported; rendered Linear")
    extension = node.extension
    if extension not in EXTENSIONS:
        c.warn(node, f"extension {extension} is not supported; rendered Repeat")
    projection = node.projection
    if projection not in _PROJECTIONS:
        c.warn(node, f"projection {projection} is not supported; rendered Flat")
    table = c.table([v for pair in tiles for v in pair]) if tiles else 0
    vector = c.uv_vector(node)
    color, alpha = c.alloc(3), c.alloc()
    c.emit("IMAGE_TEXTURE", index, table, len(tiles), INTERPOLATIONS.get(interpolation, 0),
           EXTENSIONS.get(extension, 0), _PROJECTIONS.get(projection, 0), int(_linked(node, "Alpha")), vector, color,
           alpha)
    return {"Color": color, "Alpha": alpha}


def _uv_attribute(c, node, map_name: str) -> int:
    """The (u, v, 0) registers of a UV map ('' = the active-render one, Cycles' ATTR_STD_UV)."""
    if not map_name:
        out = c.alloc(3)
        c.emit("TEXCO", P.TEXCO_UV, out)
        return out
    reg = c.attribute_input(f"uv:{map_name}", 2)
    out = c.alloc(3)
    c.emit("COMBINE3", 0, reg, reg + 1, c.const(0.0), out)
    return out


def _uv_map(c, node) -> dict:
    if getattr(node, "from_instancer", False):
        c.warn(node, "'From Instancer' is not supported; the instance's own UV map is used")
    return {"UV": _uv_attribute(c, node, node.uv_map)}


def _normal_map(c, node) -> dict:
    """NormalMapNode: tangent space reads the UV map's MikkTSpace tangent and sign (Blender's,
    exported per corner as 'tangent:<map>')."""
    space = P.NORMAL_MAP_SPACES.get(node.space)
    if space is None:
        c.warn(node, f"space {node.space} is not supported; rendered as Tangent")
        space = 0
    tangent = c.const([0.0, 0.0, 0.0, 0.0]) if space else c.attribute_input(f"tangent:{node.uv_map}", 4)
    out = c.alloc(3)
    c.emit("NORMAL_MAP", space, c.float_input(node, "Strength"), c.color_input(node, "Color"), tangent, tangent + 3,
           P.R_N, out)
    return {"Normal": out}


def _color_attribute(c, node) -> dict:
    """VertexColorNode (Color Attribute): RGBA per corner, '' = the default colour attribute."""
    reg = c.attribute_input(f"color:{node.layer_name}", 4)
    return {"Color": reg, "Alpha": reg + 3}


def _attribute(c, node) -> dict:
    """AttributeNode (svm/attribute.h): a mesh attribute by name as (x, y, z, alpha); Fac is the
    average of the first three."""
    if node.attribute_type != "GEOMETRY":
        c.warn(node, f"attribute type {node.attribute_type} is not supported on surfaces; read as 0")
        zero = c.const([0.0, 0.0, 0.0])
        return {"Color": zero, "Vector": zero, "Fac": c.const(0.0), "Alpha": c.const(0.0)}
    reg = c.attribute_input(f"attr:{node.attribute_name}", 4)
    fac = c.alloc()
    c.emit("VECTOR_TO_FLOAT", reg, fac)
    return {"Color": reg, "Vector": reg, "Fac": fac, "Alpha": reg + 3}


def _texture_coordinate(c, node) -> dict:
    """TextureCoordinateNode at a surface (svm/tex_coord.h svm_node_tex_coord)."""
    outputs = {}
    generated = c.alloc(3)
    c.emit("TEXCO", P.TEXCO_GENERATED, generated)
    outputs["Generated"] = generated
    obj = c.alloc(3)
    if node.object is not None:
        from .shader_nodes import _matrix_const, _position

        inverse = np.linalg.inv(np.array(node.object.matrix_world, dtype=np.float64))[:3].reshape(-1)
        c.emit("TRANSFORM_POINT", _matrix_const(c, inverse), _position(c), obj)
    else:
        c.emit("TEXCO", P.TEXCO_OBJECT, obj)
    outputs["Object"] = obj
    normal = c.alloc(3)
    c.emit("OBJECT_NORMAL", P.R_N, normal)
    outputs["Normal"] = normal
    outputs["UV"] = _uv_attribute(c, node, "")
    # Reflection: 2 dot(N, I) N - I, world space
    reflection, unused = c.alloc(3), c.alloc()
    minus_i = c.alloc(3)
    c.emit("VECTOR_MATH", P.VECTOR_MATH["SCALE"], P.R_I, P.R_I, P.R_I, c.const(-1.0), minus_i, unused)
    c.emit("VECTOR_MATH", P.VECTOR_MATH["REFLECT"], minus_i, P.R_N, P.R_N, c.const(1.0), reflection, unused)
    outputs["Reflection"] = reflection
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    for name in ("Camera", "Window"):
        if name in used:
            c.warn(node, f"output '{name}' is not evaluated by VolPath; read as 0")
        outputs[name] = c.const([0.0, 0.0, 0.0])
    return outputs


def _geometry(c, node) -> dict:
    """GeometryNode at a surface: Position, Normal (shading), True Normal, Incoming, Backfacing."""
    position = c.alloc(3)
    c.emit("TEXCO", P.TEXCO_POSITION, position)
    outputs = {"Position": position, "Normal": P.R_N, "True Normal": P.R_NG, "Incoming": P.R_I,
               "Backfacing": P.R_BACKFACING}
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    for out in node.outputs:
        if out.identifier not in outputs:
            if out.identifier in used:
                c.warn(node, f"output '{out.name}' is not evaluated by VolPath; read as 0")
            outputs[out.identifier] = c.const([0.0, 0.0, 0.0] if out.type == "VECTOR" else 0.0)
    return outputs


SURFACE_NODE_COMPILERS = {
    "TEX_IMAGE": _image_texture, "UVMAP": _uv_map, "NORMAL_MAP": _normal_map, "VERTEX_COLOR": _color_attribute,
    "ATTRIBUTE": _attribute, "TEX_COORD": _texture_coordinate, "NEW_GEOMETRY": _geometry,
}
