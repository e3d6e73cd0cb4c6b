"""Shader programs: Blender node trees flattened into opcodes + constants, one interpreter for all.

The add-on's compiler (addon/export/shader_compiler.py) turns a material's node tree into a
ShaderProgram; interpreter.run_program evaluates it at one point, inside the compiled stages (at
every tentative collision of a procedural medium) or for batches of points (majorant building,
tests). No code is generated per scene: every program runs on the same compiled interpreter, as
Cycles' SVM runs every shader on one kernel (intern/cycles/kernel/svm/svm.h, svm_eval_nodes).

Registers are float64 scalars (a vector or colour is three consecutive registers, named by the
first). At the start of an evaluation the registers are a copy of `init`: the program's constants
and unlinked socket values sit there, so an operand is always a register index, never an inline
float. The first registers are the fixed inputs and outputs below.

Instruction stream `code` (int32): [opcode, operand_0, ..., operand_{n-1}] repeated; the number of
operands is fixed per opcode (OPERAND_COUNT). Operands are register indices unless the spec names
them as literals (enums, table offsets, counts). `tables` (float64) holds lookup data (colour
ramps, curves) addressed by literal offsets.

Opcode ranges: 0-59 the core (interpreter.py), 60-99 surface nodes (surface_ops.py: image textures,
normal maps), 100-199 texture nodes (textures/ops.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# ---------------------------------------------------------------------------------------------
# Fixed registers
# ---------------------------------------------------------------------------------------------
#: inputs written by the caller before each evaluation
R_P = 0            # world-space position (3)
R_N = 3            # shading normal (3); 0 inside volumes (Cycles' sd->N is -ray direction there)
R_I = 6            # incoming direction, towards where the ray came from (3)
R_UV = 9           # UV map coordinate (u, v, 0) (3)
#: volume closure outputs, accumulated by the closure opcodes (zeroed by init)
R_SIGMA_A = 12     # absorption coefficient (3), 1/m
R_EMISSION = 15    # emission per unit length (3)
R_LOBES = 18       # MAX_LOBES x (sigma_s (3), g (1)): scattering closures, one slot per lobe
MAX_LOBES = 4
LOBE_STRIDE = 4
#: first register free for the compiler's constants and temporaries
R_FIRST_FREE = R_LOBES + MAX_LOBES * LOBE_STRIDE
#: surface programs (run at a surface hit, surface_ops.py) have no volume closures: their extra
#: inputs overlay the volume outputs
R_NG = R_SIGMA_A          # geometric normal, on the viewer's side (3)
R_BACKFACING = R_EMISSION  # 1.0 when the ray hit the back face (Cycles' SD_BACKFACING), else 0.0


@dataclass(frozen=True)
class OpSpec:
    code: int
    operands: tuple  # operand names, documented per opcode


OPS: dict = {}


def define(name: str, code: int, *operands: str):
    """Register an opcode; names of literal operands end with '#', registers of vectors with '3'."""
    if name in OPS or any(spec.code == code for spec in OPS.values()):
        raise ValueError(f"opcode {name} / {code} defined twice")
    OPS[name] = OpSpec(code, tuple(operands))
    return code


# ---------------------------------------------------------------------------------------------
# Core opcodes (interpreter.py). 'out' operands are registers written.
# ---------------------------------------------------------------------------------------------
# Math node (intern/cycles/kernel/svm/math_util.h svm_math): kind# is MATH_* below.
OP_MATH = define("MATH", 1, "kind#", "a", "b", "c", "out")
# Vector Math node (svm_vector_math): kind# VECTOR_MATH_*; writes a vector and a value.
OP_VECTOR_MATH = define("VECTOR_MATH", 2, "kind#", "a3", "b3", "c3", "scale", "out3", "out_value")
# Clamp node (svm/clamp.h): kind# 0 min-max, 1 range (bounds swapped when min > max).
OP_CLAMP = define("CLAMP", 3, "kind#", "value", "min", "max", "out")
# Map Range, float (svm/map_range.h): kind# MAP_RANGE_*; clamp# 0/1.
OP_MAP_RANGE = define("MAP_RANGE", 4, "kind#", "clamp#", "value", "from_min", "from_max", "to_min", "to_max",
                      "steps", "out")
# Mix node (float / vector non-uniform / colour blend): see MIX_* kinds; clamp_factor#, clamp_result#.
OP_MIX_FLOAT = define("MIX_FLOAT", 5, "clamp_factor#", "factor", "a", "b", "out")
OP_MIX_VECTOR = define("MIX_VECTOR", 6, "clamp_factor#", "factor3", "a3", "b3", "out3")
OP_MIX_COLOR = define("MIX_COLOR", 7, "blend#", "clamp_factor#", "clamp_result#", "factor", "a3", "b3", "out3")
# Colour ramp (svm/ramp.h rgb_ramp_lookup): table offset# of 257 RGBA entries, interpolate#.
OP_COLOR_RAMP = define("COLOR_RAMP", 8, "table#", "interpolate#", "factor", "out_color3", "out_alpha")
# Float Curve (svm/ramp.h svm_node_curve) and RGB / Vector Curves (svm_node_curves): a table of
# size# entries (1 float, or 3 for RGB / Vector) at offset#, sampled over [min_x, max_x] as Blender's
# sync bakes it (intern/cycles/blender/util.h curvemapping_*_to_array); extrapolate# 0/1.
OP_CURVE_FLOAT = define("CURVE_FLOAT", 9, "table#", "size#", "extrapolate#", "min_x", "max_x", "factor", "value",
                        "out")
OP_CURVE_RGB = define("CURVE_RGB", 10, "table#", "size#", "extrapolate#", "min_x", "max_x", "factor", "color3",
                      "out3")
# Separate / combine
OP_SEPARATE3 = define("SEPARATE3", 11, "mode#", "in3", "out_x", "out_y", "out_z")  # mode#: 0 xyz/rgb, 1 hsv, 2 hsl
OP_COMBINE3 = define("COMBINE3", 12, "mode#", "x", "y", "z", "out3")
# Conversions (svm/convert.h): colour -> float is luminance with the weights in registers l3
OP_COLOR_TO_FLOAT = define("COLOR_TO_FLOAT", 13, "in3", "weights3", "out")
OP_VECTOR_TO_FLOAT = define("VECTOR_TO_FLOAT", 14, "in3", "out")  # average
OP_FLOAT_TO_VECTOR = define("FLOAT_TO_VECTOR", 15, "in", "out3")
OP_COPY = define("COPY", 16, "count#", "src", "dst")
# Texture coordinates (svm/tex_coord.h): an affine transform (12 registers, row-major 3x4) of P
OP_TRANSFORM_POINT = define("TRANSFORM_POINT", 17, "matrix12", "in3", "out3")
OP_TRANSFORM_DIRECTION = define("TRANSFORM_DIRECTION", 18, "matrix12", "in3", "out3")
# Mapping node (svm/mapping_util.h svm_mapping): kind# 0 point, 1 texture, 2 vector, 3 normal
OP_MAPPING = define("MAPPING", 19, "kind#", "vector3", "location3", "rotation3", "scale3", "out3")
# Grid attribute at P (volumes): channel offset# and count# into the medium's attribute grid;
# reads 0 where the medium has no such grid (the compiler warns).
OP_ATTRIBUTE = define("ATTRIBUTE", 20, "channel#", "count#", "out3")
# Blackbody node (svm/math_util.h svm_math_blackbody_color_rec709, normalised as the node)
OP_BLACKBODY = define("BLACKBODY", 21, "temperature", "out3")
# Colour nodes
OP_INVERT = define("INVERT", 22, "factor", "color3", "out3")
OP_GAMMA = define("GAMMA", 23, "color3", "gamma", "out3")
OP_BRIGHT_CONTRAST = define("BRIGHT_CONTRAST", 24, "color3", "bright", "contrast", "out3")
OP_HUE_SAT = define("HUE_SAT", 25, "hue", "saturation", "value", "factor", "color3", "out3")
OP_RGB_TO_BW = define("RGB_TO_BW", 26, "color3", "weights3", "out")
# Texture Coordinate node from the evaluating object's frame (svm/tex_coord.h): kind# TEXCO_*.
# Inside volumes Generated is the object's texture space (mesh: (P_obj - L) / 2S + 0.5; Volume
# geometry in Cycles 5.0: raw P_obj; the medium's object_to_generated carries either).
OP_TEXCO = define("TEXCO", 27, "kind#", "out3")
TEXCO_GENERATED, TEXCO_OBJECT, TEXCO_POSITION, TEXCO_NORMAL, TEXCO_UV, TEXCO_INCOMING = range(6)
# Vector Map Range (svm/map_range.h svm_node_vector_map_range): per component
OP_MAP_RANGE_VECTOR = define("MAP_RANGE_VECTOR", 28, "kind#", "clamp#", "value3", "from_min3", "from_max3",
                             "to_min3", "to_max3", "steps3", "out3")
# Volume closures (svm/closure.h), accumulated into R_SIGMA_A / R_EMISSION / R_LOBES, each
# multiplied by the weight register (the product of the Mix/Add shader factors above it).
#   lobe# is the scattering slot (0..MAX_LOBES-1) the compiler gave this closure.
OP_PRINCIPLED_VOLUME = define("PRINCIPLED_VOLUME", 40, "lobe#", "weight", "color3", "density", "anisotropy",
                              "absorption3", "emission_strength", "emission3", "blackbody", "tint3",
                              "temperature")
OP_VOLUME_SCATTER = define("VOLUME_SCATTER", 41, "lobe#", "weight", "color3", "density", "anisotropy")
OP_VOLUME_ABSORPTION = define("VOLUME_ABSORPTION", 42, "weight", "color3", "density")
OP_VOLUME_EMISSION = define("VOLUME_EMISSION", 43, "weight", "color3", "strength")
OP_VOLUME_COEFFICIENTS = define("VOLUME_COEFFICIENTS", 44, "lobe#", "weight", "scatter3", "absorb3", "emit3",
                                "anisotropy")
# weight helpers for Mix Shader: out_a = w (1 - clamp(f)), out_b = w clamp(f)
OP_MIX_WEIGHTS = define("MIX_WEIGHTS", 45, "weight", "factor", "out_a", "out_b")

# Surface opcodes (60-99, shading/surface_ops.py)
# Image Texture node (svm/image.h svm_node_tex_image): image# is the index into the scene's image
# table (-1: missing, magenta); tile_count# > 0 makes it a UDIM set whose (tile number, image index)
# pairs sit in tables[tiles# ...]; interpolation# / extension# as images.INTERPOLATIONS /
# EXTENSIONS; projection# 0 flat, 2 sphere, 3 tube (Cycles' NODE_IMAGE_PROJ_*); unassociate# 1
# when the Alpha output is used (NODE_IMAGE_ALPHA_UNASSOCIATE).
OP_IMAGE_TEXTURE = define("IMAGE_TEXTURE", 60, "image#", "tiles#", "tile_count#", "interpolation#", "extension#",
                          "projection#", "unassociate#", "vector3", "out_color3", "out_alpha")
# Normal Map node (svm/tex_coord.h svm_node_normal_map): space# NORMAL_MAP_SPACES; tangent3 and
# sign are the UV map's MikkTSpace tangent and sign (world space, interpolated), normal3 the
# shading normal; writes the perturbed world-space normal on the viewer's side.
OP_NORMAL_MAP = define("NORMAL_MAP", 61, "space#", "strength", "color3", "tangent3", "sign", "normal3", "out3")
NORMAL_MAP_SPACES = {"TANGENT": 0, "OBJECT": 1, "WORLD": 2, "BLENDER_OBJECT": 3, "BLENDER_WORLD": 4}
# Texture Coordinate Normal on surfaces: the shading normal in object space (svm/tex_coord.h
# NODE_TEXCO_NORMAL, object_inverse_normal_transform)
OP_OBJECT_NORMAL = define("OBJECT_NORMAL", 62, "in3", "out3")
# Tangent node and Geometry > Tangent (C5 svm/tex_coord.h svm_node_tangent, geom/primitive.h
# primitive_tangent): kind# TANGENT_RADIAL_X/Y/Z read vector3 as Generated coordinates, TANGENT_UV
# as the UV map's object-space MikkTSpace tangent; the result is in world space, orthogonal to
# normal3 (the interpolated shading normal).
OP_TANGENT = define("TANGENT", 63, "kind#", "vector3", "normal3", "out3")
TANGENT_RADIAL_X, TANGENT_RADIAL_Y, TANGENT_RADIAL_Z, TANGENT_UV = range(4)
# Bump node (C5 svm/displace.h svm_node_set_bump, scene/shader_graph.cpp refine_bump_nodes): the
# height subgraph is compiled three times, at the hit and at the hit moved by the offsets ex3 and
# ey3 (in the plane of the geometric normal; the kernel writes them, surface_programs.py), between
# SWAPs that exchange the hit's inputs with the moved point's. h_c, h_x, h_y: the three heights.
OP_BUMP = define("BUMP", 64, "invert#", "normal3", "distance", "strength", "filter_width", "h_c", "h_x", "h_y", "ex3",
                 "ey3", "out3")
# exchange count# registers at a with those at b (a bump copy's inputs, and back)
OP_SWAP = define("SWAP", 65, "count#", "a", "b")
# Image Texture with Box projection (C5 svm/image.h svm_node_tex_image_box): the image sampled on
# the three axis planes of vector3, blended by the object-space normal3 with blend (Projection
# Blend); options as IMAGE_TEXTURE.
OP_IMAGE_BOX = define("IMAGE_BOX", 66, "image#", "interpolation#", "extension#", "unassociate#", "blend", "vector3",
                      "normal3", "out_color3", "out_alpha")

# Displacement node (C5 svm/displace.h svm_node_displacement): (height - midlevel) x scale along
# normal3; space# DISPLACEMENT_SPACES: Object scales the object-space normal and takes it back to
# world space (so the object's scale scales the displacement), World uses normal3 as it is.
OP_DISPLACEMENT = define("DISPLACEMENT", 67, "space#", "height", "midlevel", "scale", "normal3", "out3")
DISPLACEMENT_SPACES = {"OBJECT": 0, "WORLD": 1}
# Vector Displacement node (C5 svm/displace.h svm_node_vector_displacement), Object / World space:
# (vector3 - midlevel) x scale, taken from object to world space for Object (space# as above).
OP_VECTOR_DISPLACEMENT = define("VECTOR_DISPLACEMENT", 68, "space#", "vector3", "midlevel", "scale", "out3")

# Math kinds (Blender's NODE_MATH_* enum values: DNA_node_types.h), used by the compiler by name.
MATH_KINDS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "SINE", "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE",
              "ARCTANGENT", "POWER", "LOGARITHM", "MINIMUM", "MAXIMUM", "ROUND", "LESS_THAN", "GREATER_THAN",
              "MODULO", "ABSOLUTE", "ARCTAN2", "FLOOR", "CEIL", "FRACT", "SQRT", "INVERSE_SQRT", "SIGN",
              "EXPONENT", "RADIANS", "DEGREES", "SINH", "COSH", "TANH", "TRUNC", "SNAP", "WRAP", "COMPARE",
              "MULTIPLY_ADD", "PINGPONG", "SMOOTH_MIN", "SMOOTH_MAX", "FLOORED_MODULO")
MATH = {name: i for i, name in enumerate(MATH_KINDS)}
VECTOR_MATH_KINDS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "CROSS_PRODUCT", "PROJECT", "REFLECT",
                     "DOT_PRODUCT", "DISTANCE", "LENGTH", "SCALE", "NORMALIZE", "SNAP", "FLOOR", "CEIL",
                     "MODULO", "FRACTION", "ABSOLUTE", "MINIMUM", "MAXIMUM", "WRAP", "SINE", "COSINE",
                     "TANGENT", "REFRACT", "FACEFORWARD", "MULTIPLY_ADD", "POWER", "SIGN")
VECTOR_MATH = {name: i for i, name in enumerate(VECTOR_MATH_KINDS)}
MAP_RANGE_KINDS = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")
MAP_RANGE = {name: i for i, name in enumerate(MAP_RANGE_KINDS)}
MIX_BLEND_KINDS = ("MIX", "ADD", "MULTIPLY", "SCREEN", "OVERLAY", "SUBTRACT", "DIVIDE", "DIFFERENCE", "DARKEN",
                   "LIGHTEN", "DODGE", "BURN", "HUE", "SATURATION", "VALUE", "COLOR", "SOFT_LIGHT",
                   "LINEAR_LIGHT", "EXCLUSION")
MIX_BLEND = {name: i for i, name in enumerate(MIX_BLEND_KINDS)}

# Texture opcodes (100-199) are defined by textures/ops.py when it is imported.
TEXTURE_OP_BASE = 100
from .textures import ops as _texture_ops  # noqa: E402,F401  (registers its opcodes)


def operand_count_table() -> np.ndarray:
    table = np.full(max(spec.code for spec in OPS.values()) + 1, -1, np.int64)
    for spec in OPS.values():
        table[spec.code] = len(spec.operands)
    return table


#: operands per opcode (-1: not an opcode), indexed by opcode
OPERAND_COUNT = operand_count_table()


@dataclass
class ShaderProgram:
    """One compiled node tree. code/init/tables as the module docstring; `varying` is False when
    nothing depends on the shading point (the medium is homogeneous: evaluate once); attributes
    lists the grid attribute names the program reads (channel offsets assigned by the medium)."""

    name: str
    code: np.ndarray
    init: np.ndarray
    tables: np.ndarray = field(default_factory=lambda: np.zeros(1))
    varying: bool = True
    attributes: list = field(default_factory=list)

    def __post_init__(self):
        self.code = np.ascontiguousarray(self.code, dtype=np.int32).reshape(-1)
        self.init = np.ascontiguousarray(self.init, dtype=np.float64).reshape(-1)
        self.tables = np.ascontiguousarray(self.tables, dtype=np.float64).reshape(-1)
        if self.tables.size == 0:
            self.tables = np.zeros(1)

    @property
    def n_registers(self) -> int:
        return len(self.init)

    def validate(self) -> None:
        """Raise ValueError unless every instruction is a known opcode whose register operands lie
        inside the register file (the interpreter does not check: a bad program must never run)."""
        pc, n = 0, len(self.code)
        regs = self.n_registers
        if regs < R_FIRST_FREE:
            raise ValueError(f"shader program '{self.name}': " + f"{regs} registers, fewer than the {R_FIRST_FREE} fixed ones")
        by_code = {spec.code: (name, spec) for name, spec in OPS.items()}
        while pc < n:
            op = int(self.code[pc])
            if op not in by_code:
                raise ValueError(f"shader program '{self.name}': " + f"unknown opcode {op} at {pc}")
            name, spec = by_code[op]
            if pc + len(spec.operands) >= n:
                raise ValueError(f"shader program '{self.name}': " + f"{name} at {pc} is truncated")
            for k, operand in enumerate(spec.operands):
                value = int(self.code[pc + 1 + k])
                if operand.endswith("#"):
                    continue
                width = 12 if operand.endswith("12") else 3 if operand.endswith("3") else 1
                if not 0 <= value <= regs - width:
                    raise ValueError(f"shader program '{self.name}': " + f"{name} at {pc}: operand {operand} = {value} outside "
                                                   f"the {regs} registers")
            pc += 1 + len(spec.operands)
