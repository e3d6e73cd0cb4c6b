"""Compile functions of the non-texture shader nodes: NODE_COMPILERS[node.type](compiler, node)
returns {output socket identifier: register}. Each follows the node's Cycles compile
(C5 = blender/cycles v5.0.0, src/scene/shader_nodes.cpp) into the opcodes of
volpath_native.shading.program; the arithmetic is in shading/interpreter.py.
"""
from __future__ import annotations

import numpy as np

from volpath_native.shading import program as P

from .shader_compiler import LUMINANCE, ShaderCompiler, _socket


def _value(c: ShaderCompiler, node) -> dict:
    return {node.outputs[0].identifier: c.const(float(node.outputs[0].default_value))}


def _rgb(c: ShaderCompiler, node) -> dict:
    return {node.outputs[0].identifier: c.const(list(node.outputs[0].default_value)[:3])}


def _math(c: ShaderCompiler, node) -> dict:
    """MathNode: svm_math; use_clamp adds a [0, 1] clamp (MathNode::expand)."""
    if node.operation not in P.MATH:
        c.warn(node, f"operation {node.operation} is not supported; result 0")
        return {node.outputs[0].identifier: c.const(0.0)}
    out = c.alloc()
    c.emit("MATH", P.MATH[node.operation], c.float_input(node, 0), c.float_input(node, 1),
           c.float_input(node, 2), out)
    if node.use_clamp:
        clamped = c.alloc()
        c.emit("CLAMP", 0, out, c.const(0.0), c.const(1.0), clamped)
        out = clamped
    return {node.outputs[0].identifier: out}


def _vector_math(c: ShaderCompiler, node) -> dict:
    if node.operation not in P.VECTOR_MATH:
        c.warn(node, f"operation {node.operation} is not supported; result 0")
        return {}
    vector, value = c.alloc(3), c.alloc()
    scale = c.float_input(node, 3) if len(node.inputs) > 3 else c.const(1.0)
    c.emit("VECTOR_MATH", P.VECTOR_MATH[node.operation], c.vector_input(node, 0), c.vector_input(node, 1),
           c.vector_input(node, 2), scale, vector, value)
    return {"Vector": vector, "Value": value}


def _clamp(c: ShaderCompiler, node) -> dict:
    out = c.alloc()
    c.emit("CLAMP", 1 if node.clamp_type == "RANGE" else 0, c.float_input(node, "Value"),
           c.float_input(node, "Min"), c.float_input(node, "Max"), out)
    return {"Result": out}


def _map_range(c: ShaderCompiler, node) -> dict:
    kind = P.MAP_RANGE.get(node.interpolation_type, 0)
    clamp = 1 if node.clamp else 0
    if getattr(node, "data_type", "FLOAT") == "FLOAT_VECTOR":
        out = c.alloc(3)
        c.emit("MAP_RANGE_VECTOR", kind, clamp, c.vector_input(node, "Vector"), c.vector_input(node, "From_Min_FLOAT3"),
               c.vector_input(node, "From_Max_FLOAT3"), c.vector_input(node, "To_Min_FLOAT3"),
               c.vector_input(node, "To_Max_FLOAT3"), c.vector_input(node, "Steps_FLOAT3"), out)
        return {"Vector": out}
    out = c.alloc()
    c.emit("MAP_RANGE", kind, clamp, c.float_input(node, "Value"), c.float_input(node, "From Min"),
           c.float_input(node, "From Max"), c.float_input(node, "To Min"), c.float_input(node, "To Max"),
           c.float_input(node, "Steps"), out)
    return {"Result": out}


def _mix(c: ShaderCompiler, node) -> dict:
    """ShaderNodeMix (MixFloatNode / MixVectorNode / MixVectorNonUniformNode / MixColorNode)."""
    clamp_factor = 1 if node.clamp_factor else 0
    data_type = node.data_type
    if data_type == "FLOAT":
        out = c.alloc()
        c.emit("MIX_FLOAT", clamp_factor, c.float_input(node, "Factor_Float"), c.float_input(node, "A_Float"),
               c.float_input(node, "B_Float"), out)
        return {"Result_Float": out}
    if data_type == "VECTOR":
        factor = (c.vector_input(node, "Factor_Vector") if node.factor_mode == "NON_UNIFORM"
                  else c.vector_input(node, "Factor_Float"))
        out = c.alloc(3)
        c.emit("MIX_VECTOR", clamp_factor, factor, c.vector_input(node, "A_Vector"), c.vector_input(node, "B_Vector"), out)
        return {"Result_Vector": out}
    if data_type == "RGBA":
        out = c.alloc(3)
        c.emit("MIX_COLOR", P.MIX_BLEND.get(node.blend_type, 0), clamp_factor, 1 if node.clamp_result else 0,
               c.float_input(node, "Factor_Float"), c.color_input(node, "A_Color"), c.color_input(node, "B_Color"), out)
        return {"Result_Color": out}
    c.warn(node, f"data type {data_type} is not supported; result 0")
    return {}


def _mix_rgb(c: ShaderCompiler, node) -> dict:
    """Legacy MixRGB: factor always clamped (svm_mix_clamped_factor), use_clamp clamps the result."""
    out = c.alloc(3)
    c.emit("MIX_COLOR", P.MIX_BLEND.get(node.blend_type, 0), 1, 1 if node.use_clamp else 0,
           c.float_input(node, "Fac"), c.color_input(node, 1), c.color_input(node, 2), out)
    return {"Color": out}


def _color_ramp(c: ShaderCompiler, node) -> dict:
    """RGBRampNode: 257 entries of ColorRamp.evaluate(i / 256) (Blender's colorramp_to_array with
    RAMP_TABLE_SIZE 256), interpolated unless the ramp is Constant."""
    ramp = node.color_ramp
    table = np.array([ramp.evaluate(i / 256.0) for i in range(257)], dtype=np.float64)
    color, alpha = c.alloc(3), c.alloc()
    c.emit("COLOR_RAMP", c.table(table), 0 if ramp.interpolation == "CONSTANT" else 1,
           c.float_input(node, "Fac"), color, alpha)
    return {"Color": color, "Alpha": alpha}


#: Cycles' RAMP_TABLE_SIZE (scene/shader_nodes.h): curve and ramp tables hold 257 entries
RAMP_TABLE_SIZE = 256


def curve_table(mapping, curve_count: int, composite: bool):
    """(table (257, curve_count), min_x, max_x) of a CurveMapping as Blender's Cycles sync bakes it
    (intern/cycles/blender/util.h curvemapping_minmax, curvemapping_float_to_array /
    curvemapping_color_to_array): the x range spans the first to the last point over the first
    curve_count curves; entry i samples min_x + i / 256 (max_x - min_x) (float32, as there); with
    composite (RGB Curves) the R, G, B curves read the combined C curve's value."""
    f32 = np.float32
    curves = list(mapping.curves)
    min_x = f32(min(curves[k].points[0].location[0] for k in range(curve_count)))
    max_x = f32(max(curves[k].points[len(curves[k].points) - 1].location[0] for k in range(curve_count)))
    mapping.update()  # BKE_curvemapping_changed_all, as the sync does
    span = f32(max_x - min_x)
    columns = 3 if curve_count > 1 else 1
    table = np.zeros((RAMP_TABLE_SIZE + 1, columns))
    for i in range(RAMP_TABLE_SIZE + 1):
        t = float(f32(min_x + f32(f32(i) / f32(RAMP_TABLE_SIZE)) * span))
        if composite:
            t = mapping.evaluate(curves[3], t)
        for k in range(columns):
            table[i, k] = mapping.evaluate(curves[k], t)
    return table, float(min_x), float(max_x)


def _extrapolates(mapping) -> int:
    return 1 if getattr(mapping, "extend", "EXTRAPOLATED") == "EXTRAPOLATED" else 0


def _float_curve(c: ShaderCompiler, node) -> dict:
    """FloatCurveNode (svm_node_curve)."""
    table, min_x, max_x = curve_table(node.mapping, 1, False)
    out = c.alloc()
    c.emit("CURVE_FLOAT", c.table(table), len(table), _extrapolates(node.mapping), c.const(min_x), c.const(max_x),
           c.float_input(node, "Factor"), c.float_input(node, "Value"), out)
    return {"Value": out}


def _rgb_curves(c: ShaderCompiler, node) -> dict:
    """RGBCurvesNode (svm_node_curves): the C curve composed under R, G and B."""
    table, min_x, max_x = curve_table(node.mapping, 4, True)
    out = c.alloc(3)
    c.emit("CURVE_RGB", c.table(table), len(table), _extrapolates(node.mapping), c.const(min_x), c.const(max_x),
           c.float_input(node, "Fac"), c.color_input(node, "Color"), out)
    return {"Color": out}


def _vector_curves(c: ShaderCompiler, node) -> dict:
    """VectorCurvesNode (svm_node_curves): X, Y, Z curves."""
    table, min_x, max_x = curve_table(node.mapping, 3, False)
    out = c.alloc(3)
    c.emit("CURVE_RGB", c.table(table), len(table), _extrapolates(node.mapping), c.const(min_x), c.const(max_x),
           c.float_input(node, "Fac"), c.vector_input(node, "Vector"), out)
    return {"Vector": out}


def _separate_xyz(c: ShaderCompiler, node) -> dict:
    x, y, z = c.alloc(), c.alloc(), c.alloc()
    c.emit("SEPARATE3", 0, c.vector_input(node, 0), x, y, z)
    return {"X": x, "Y": y, "Z": z}


def _combine_xyz(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("COMBINE3", 0, c.float_input(node, "X"), c.float_input(node, "Y"), c.float_input(node, "Z"), out)
    return {"Vector": out}


_COLOR_MODES = {"RGB": 0, "HSV": 1, "HSL": 2}


def _separate_color(c: ShaderCompiler, node, mode=None) -> dict:
    mode = _COLOR_MODES.get(mode or getattr(node, "mode", "RGB"), 0)
    regs = [c.alloc(), c.alloc(), c.alloc()]
    c.emit("SEPARATE3", mode, c.color_input(node, 0), *regs)
    return {out.identifier: reg for out, reg in zip(node.outputs, regs)}


def _combine_color(c: ShaderCompiler, node, mode=None) -> dict:
    mode = _COLOR_MODES.get(mode or getattr(node, "mode", "RGB"), 0)
    out = c.alloc(3)
    c.emit("COMBINE3", mode, c.float_input(node, 0), c.float_input(node, 1), c.float_input(node, 2), out)
    return {node.outputs[0].identifier: out}


def _texture_coordinate(c: ShaderCompiler, node) -> dict:
    """TextureCoordinateNode in a volume (svm/tex_coord.h): Generated = the object's texture space,
    Object = object space (or the From object's space), Normal / UV / Camera / Window / Reflection
    have no meaning at a volume point (warned if used)."""
    outputs = {}
    generated = c.alloc(3)
    c.emit("TEXCO", P.TEXCO_GENERATED, generated)
    outputs["Generated"] = generated
    obj = c.alloc(3)
    if node.object is not None:  # NODE_TEXCO_OBJECT_WITH_TRANSFORM: the other object's inverse
        inverse = np.linalg.inv(np.array(node.object.matrix_world, dtype=np.float64))[:3].reshape(-1)
        c.emit("TRANSFORM_POINT", _matrix_const(c, inverse), _position(c), obj)
    else:
        c.emit("TEXCO", P.TEXCO_OBJECT, obj)
    outputs["Object"] = obj
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    for name in ("Normal", "UV", "Camera", "Window", "Reflection"):
        if name in used:
            c.warn(node, f"output '{name}' is not evaluated inside volumes; read as 0")
        outputs[name] = c.const([0.0, 0.0, 0.0])
    return outputs


def _matrix_const(c: ShaderCompiler, values) -> int:
    """12 consecutive registers (a 3x4 row-major matrix); never shared with other constants."""
    reg = c.alloc(12)
    c.builder.init[reg:reg + 12] = [float(v) for v in values]
    return reg


def _position(c: ShaderCompiler) -> int:
    out = c.alloc(3)
    c.emit("TEXCO", P.TEXCO_POSITION, out)
    return out


def _geometry(c: ShaderCompiler, node) -> dict:
    outputs = {"Position": _position(c)}
    used = {link.from_socket.identifier for out in node.outputs for link in out.links}
    for out in node.outputs:
        if out.identifier != "Position":
            if out.identifier in used:
                c.warn(node, f"output '{out.name}' is not evaluated inside volumes; read as 0")
            outputs[out.identifier] = c.const([0.0, 0.0, 0.0] if out.type == "VECTOR" else 0.0)
    return outputs


def _mapping(c: ShaderCompiler, node) -> dict:
    kinds = {"POINT": 0, "TEXTURE": 1, "VECTOR": 2, "NORMAL": 3}
    kind = kinds.get(node.vector_type, 0)
    location = c.vector_input(node, "Location") if _socket(node.inputs, "Location") is not None \
        and _socket(node.inputs, "Location").enabled else c.const([0.0, 0.0, 0.0])
    out = c.alloc(3)
    c.emit("MAPPING", kind, c.vector_input(node, "Vector"), location, c.vector_input(node, "Rotation"),
           c.vector_input(node, "Scale"), out)
    return {"Vector": out}


def _grid_attribute(c: ShaderCompiler, node, name: str, width: int) -> int:
    if name not in c.available_attributes:
        c.warn(node, f"attribute '{name}' does not exist on this object; read as 0")
        return c.const([0.0, 0.0, 0.0])
    return c._attribute(name, width)


_COLOR_ATTRIBUTES = {"color"}


def _attribute(c: ShaderCompiler, node) -> dict:
    """AttributeNode (svm/attribute.h svm_node_attr): a grid's value; Fac of a colour is its average."""
    name = node.attribute_name
    if node.attribute_type != "GEOMETRY":
        c.warn(node, f"attribute type {node.attribute_type} is not supported; read as 0")
        zero = c.const([0.0, 0.0, 0.0])
        return {"Color": zero, "Vector": zero, "Fac": c.const(0.0), "Alpha": c.const(0.0)}
    width = 3 if name in _COLOR_ATTRIBUTES else 1
    value = _grid_attribute(c, node, name, width)
    fac = c.alloc()
    c.emit("VECTOR_TO_FLOAT", value, fac)
    return {"Color": value, "Vector": value, "Fac": fac, "Alpha": c.const(1.0)}


def _volume_info(c: ShaderCompiler, node) -> dict:
    """VolumeInfoNode: the color, density, flame and temperature attributes."""
    outputs = {}
    for identifier, name, width in (("Color", "color", 3), ("Density", "density", 1), ("Flame", "flame", 1),
                                    ("Temperature", "temperature", 1)):
        if any(out.identifier == identifier and out.is_linked for out in node.outputs):
            outputs[identifier] = _grid_attribute(c, node, name, width)
    return outputs


def _blackbody(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("BLACKBODY", c.float_input(node, "Temperature"), out)
    return {"Color": out}


def _invert(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("INVERT", c.float_input(node, "Fac"), c.color_input(node, "Color"), out)
    return {"Color": out}


def _gamma(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("GAMMA", c.color_input(node, "Color"), c.float_input(node, "Gamma"), out)
    return {"Color": out}


def _bright_contrast(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("BRIGHT_CONTRAST", c.color_input(node, "Color"), c.float_input(node, "Bright"),
           c.float_input(node, "Contrast"), out)
    return {"Color": out}


def _hue_saturation(c: ShaderCompiler, node) -> dict:
    out = c.alloc(3)
    c.emit("HUE_SAT", c.float_input(node, "Hue"), c.float_input(node, "Saturation"), c.float_input(node, "Value"),
           c.float_input(node, "Fac"), c.color_input(node, "Color"), out)
    return {"Color": out}


def _rgb_to_bw(c: ShaderCompiler, node) -> dict:
    out = c.alloc()
    c.emit("RGB_TO_BW", c.color_input(node, "Color"), c.const(LUMINANCE), out)
    return {"Val": out}


NODE_COMPILERS = {
    "VALUE": _value, "RGB": _rgb, "MATH": _math, "VECT_MATH": _vector_math, "CLAMP": _clamp,
    "MAP_RANGE": _map_range, "MIX": _mix, "MIX_RGB": _mix_rgb, "VALTORGB": _color_ramp,
    "SEPXYZ": _separate_xyz, "COMBXYZ": _combine_xyz, "SEPARATE_COLOR": _separate_color,
    "COMBINE_COLOR": _combine_color, "SEPRGB": lambda c, n: _separate_color(c, n, "RGB"),
    "COMBRGB": lambda c, n: _combine_color(c, n, "RGB"), "SEPHSV": lambda c, n: _separate_color(c, n, "HSV"),
    "COMBHSV": lambda c, n: _combine_color(c, n, "HSV"), "TEX_COORD": _texture_coordinate,
    "NEW_GEOMETRY": _geometry, "MAPPING": _mapping, "ATTRIBUTE": _attribute, "VOLUME_INFO": _volume_info,
    "BLACKBODY": _blackbody, "INVERT": _invert, "GAMMA": _gamma, "BRIGHTCONTRAST": _bright_contrast,
    "HUE_SAT": _hue_saturation, "RGBTOBW": _rgb_to_bw, "CURVE_FLOAT": _float_curve, "CURVE_RGB": _rgb_curves,
    "CURVE_VEC": _vector_curves,
}
