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
    if projection == "BOX" and tiles:
        c.warn(node, "Box projection of a UDIM image is not supported; rendered Flat")
        projection = "FLAT"
    if projection not in _PROJECTIONS and projection != "BOX":
        c.warn(node, f"projection {projection} is not supported; rendered Flat")
    table = c.table([v for pair in tiles for v in pair]) if tiles else 0
    vector = c.uv_vector(node)
    color, alpha = c.alloc(3), c.alloc()
    if projection == "BOX":  # svm_node_tex_image_box: blended by the shading normal in object space
        c.emit("IMAGE_BOX", index, INTERPOLATIONS.get(interpolation, 0), EXTENSIONS.get(extension, 0),
               int(_linked(node, "Alpha")), c.const(float(node.projection_blend)), vector, P.R_N, color, alpha)
        return {"Color": color, "Alpha": alpha}
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
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    # the active UV map only when read (an unused one would request, and warn about, a UV map)
    outputs["UV"] = _uv_attribute(c, node, "") if "UV" in used else c.const([0.0, 0.0, 0.0])
    # Reflection: 2 dot(N, I) N - I, world space
    reflection, unused = c.alloc(3), c.alloc()
    minus_i = c.alloc(3)
    c.emit("VECTOR_MATH", P.VECTOR_MATH["SCALE"], P.R_I, P.R_I, P.R_I, c.const(-1.0), minus_i, unused)
    c.emit("VECTOR_MATH", P.VECTOR_MATH["REFLECT"], minus_i, P.R_N, P.R_N, c.const(1.0), reflection, unused)
    outputs["Reflection"] = reflection
    for name in ("Camera", "Window"):
        if name in used:
            c.warn(node, f"output '{name}' is not evaluated by VolPath; read as 0")
        outputs[name] = c.const([0.0, 0.0, 0.0])
    return outputs


def radial_tangent(c, kind: int) -> int:
    """A radial tangent around the Generated texture space's X, Y or Z axis (svm_node_tangent)."""
    generated, out = c.alloc(3), c.alloc(3)
    c.emit("TEXCO", P.TEXCO_GENERATED, generated)
    c.emit("TANGENT", kind, generated, P.R_N, out)
    return out


_TANGENT_AXES = {"X": P.TANGENT_RADIAL_X, "Y": P.TANGENT_RADIAL_Y, "Z": P.TANGENT_RADIAL_Z}


def _tangent(c, node) -> dict:
    """TangentNode (C5 svm/tex_coord.h svm_node_tangent): radial around an axis of the Generated
    coordinates, or the named UV map's MikkTSpace tangent ('' = the active-render map, Cycles'
    ATTR_STD_UV_TANGENT; a mesh without it gives 0)."""
    if node.direction_type == "UV_MAP":
        reg = c.attribute_input(f"tangent:{node.uv_map}", 4)
        out = c.alloc(3)
        c.emit("TANGENT", P.TANGENT_UV, reg, P.R_N, out)
        return {"Tangent": out}
    return {"Tangent": radial_tangent(c, _TANGENT_AXES.get(node.axis, P.TANGENT_RADIAL_Z))}


def _bump(c, node) -> dict:
    """BumpNode (C5 svm/displace.h svm_node_set_bump): the Height subgraph at the hit and at the
    hit moved along two directions of the surface (SurfaceShaderCompiler.shifted), the Normal
    input (else the shading normal) bent by Distance x the height's surface gradient, mixed by
    Strength. Filter Width is a constant of the node in Cycles (a link to it is ignored there too)."""
    normal = c.vector_input(node, "Normal") if c._source(node.inputs["Normal"]) is not None else P.R_N
    height = node.inputs["Height"]
    if c._source(height) is None:  # nothing to differentiate: Cycles skips refine_bump_nodes
        return {"Normal": normal}
    width_socket = node.inputs.get("Filter Width")
    filter_width = float(width_socket.default_value) if width_socket is not None else 1.0
    if width_socket is not None and width_socket.is_linked:
        c.warn(node, "input 'Filter Width' is linked; Cycles and VolPath use its own value")
    if filter_width < 0.0:
        c.warn(node, f"Filter Width {filter_width:g} is negative; rendered without the bump")
    h_c = c.float_input(node, "Height")
    h_x = c.shifted(lambda: c.float_input(node, "Height"), 0)
    h_y = c.shifted(lambda: c.float_input(node, "Height"), 1)
    out = c.alloc(3)
    c.emit("BUMP", int(bool(node.invert)), normal, c.float_input(node, "Distance"), c.float_input(node, "Strength"),
           c.const(max(filter_width, 0.0)), h_c, h_x, h_y, c.bump_offsets, c.bump_offsets + 3, out)
    return {"Normal": out}


def _displacement(c, node) -> dict:
    """DisplacementNode (C5 svm/displace.h svm_node_displacement): (Height - Midlevel) x Scale along
    the Normal input (else the shading normal), in Object (default) or World space."""
    normal = c.vector_input(node, "Normal") if c._source(node.inputs["Normal"]) is not None else P.R_N
    out = c.alloc(3)
    c.emit("DISPLACEMENT", P.DISPLACEMENT_SPACES.get(node.space, 0), c.float_input(node, "Height"),
           c.float_input(node, "Midlevel"), c.float_input(node, "Scale"), normal, out)
    return {"Displacement": out}


def _vector_displacement(c, node) -> dict:
    """VectorDisplacementNode (C5 svm/displace.h svm_node_vector_displacement) in Object / World
    space; Tangent space (the default) needs the UV tangent frame of displace.h, not evaluated:
    warned, read as no displacement."""
    if node.space not in P.DISPLACEMENT_SPACES:
        c.warn(node, f"space '{node.space}' is not evaluated by VolPath (Object and World are); "
                     "read as no displacement")
        return {"Displacement": c.const([0.0, 0.0, 0.0])}
    out = c.alloc(3)
    c.emit("VECTOR_DISPLACEMENT", P.DISPLACEMENT_SPACES[node.space], c.vector_input(node, "Vector"),
           c.float_input(node, "Midlevel"), c.float_input(node, "Scale"), out)
    return {"Displacement": out}


def _geometry(c, node) -> dict:
    """GeometryNode at a surface: Position, Normal (shading), True Normal, Incoming, Backfacing,
    Tangent (primitive_tangent: the radial Z tangent of the Generated coordinates)."""
    position = c.alloc(3)
    c.emit("TEXCO", P.TEXCO_POSITION, position)
    outputs = {"Position": position, "Normal": P.R_N, "True Normal": P.R_NG, "Incoming": P.R_I,
               "Backfacing": P.R_BACKFACING}
    if any(o.identifier == "Tangent" and o.is_linked for o in node.outputs):
        outputs["Tangent"] = radial_tangent(c, P.TANGENT_RADIAL_Z)
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    for out in node.outputs:
        if out.identifier not in outputs:
            if out.identifier in used:
                c.warn(node, f"output '{out.name}' is not evaluated by VolPath; read as 0")
            outputs[out.identifier] = c.const([0.0, 0.0, 0.0] if out.type == "VECTOR" else 0.0)
    return outputs


SURFACE_NODE_COMPILERS = {
    "TEX_IMAGE": _image_texture, "UVMAP": _uv_map, "NORMAL_MAP": _normal_map, "VERTEX_COLOR": _color_attribute,
    "ATTRIBUTE": _attribute, "TEX_COORD": _texture_coordinate, "NEW_GEOMETRY": _geometry, "TANGENT": _tangent,
    "BUMP": _bump, "DISPLACEMENT": _displacement, "VECTOR_DISPLACEMENT": _vector_displacement,
}
