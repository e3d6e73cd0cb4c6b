"""The one interpreter of shader programs (program.py): run_program evaluates a program at a point.

Each node's arithmetic follows Cycles' SVM kernel functions, cited per opcode (C5 = blender/cycles
v5.0.0, src/kernel/svm/ and src/util/); evaluation is in float64 where Cycles uses float32 (allowed
by the node contract: only hashes and lattice choices must be bit-exact, and those live in
textures/). No allocation: the caller passes the register file.

Inputs besides the program: `frame`, a (2, 3, 4) float64 array of affine maps -- world -> object
(frame[0]) and object -> generated texture space (frame[1]) of the evaluating object -- and the
medium's attribute grid (float32 (nx, ny, nz, channels), voxel (i, j, k) at index point (i, j, k),
`world_to_index` (3, 4)), read by ATTRIBUTE with trilinear interpolation (the expectation of Cycles
5.0's stochastic lookups, kernel/geom/primitive.h) and 0 outside the grid.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import inline_stage_kernel, stage_kernel
from .blackbody import blackbody_rec709_scalar
from .program import (MATH, VECTOR_MATH, VECTOR_MATH_KINDS, LOBE_STRIDE, MAX_LOBES, OP_ATTRIBUTE, OP_BLACKBODY, OP_BRIGHT_CONTRAST, OP_CLAMP, OP_COLOR_RAMP,
                      OP_COLOR_TO_FLOAT, OP_COMBINE3, OP_COPY, OP_CURVE_FLOAT, OP_CURVE_RGB, OP_FLOAT_TO_VECTOR,
                      OP_GAMMA, OP_HUE_SAT, OP_INVERT, OP_MAP_RANGE, OP_MAP_RANGE_VECTOR, OP_MAPPING, OP_MATH,
                      OP_MIX_COLOR, OP_MIX_FLOAT, OP_MIX_VECTOR, OP_MIX_WEIGHTS, OP_PRINCIPLED_VOLUME,
                      OP_RGB_TO_BW, OP_SEPARATE3, OP_TEXCO, OP_TRANSFORM_DIRECTION, OP_TRANSFORM_POINT,
                      OP_VECTOR_MATH, OP_VECTOR_TO_FLOAT, OP_VOLUME_ABSORPTION, OP_VOLUME_COEFFICIENTS,
                      OP_VOLUME_EMISSION, OP_VOLUME_SCATTER, OPERAND_COUNT, R_EMISSION, R_I, R_LOBES, R_N, R_P,
                      R_SIGMA_A, R_UV, TEXTURE_OP_BASE)
from .surface_ops import run_surface_op
from .textures.ops import run_texture_op

SURFACE_OP_BASE = 60  # opcodes 60-99: surface_ops.py

# Cycles' CLOSURE_WEIGHT_CUTOFF (kernel/types.h): closures below it are not added.
CLOSURE_WEIGHT_CUTOFF = 1e-5
# Principled Volume blackbody: Stefan-Boltzmann x 1e-6 / pi (svm/closure.h svm_node_principled_volume)
_BLACKBODY_SIGMA = 5.670373e-8 * 1e-6 / np.pi
_FLT_EPSILON = 1.1920928955078125e-07


# ---------------------------------------------------------------------------------------------
# Scalar helpers (C5 src/util/math_base.h)
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def _safe_divide(a, b):
    return a / b if b != 0.0 else 0.0


@inline_stage_kernel
def _compatible_pow(x, y):
    if y == 0.0:
        return 1.0
    if x == 0.0:
        return 0.0
    return x ** y


@inline_stage_kernel
def _safe_pow(a, b):
    if a < 0.0 and b != float(int(b)):
        return 0.0
    return _compatible_pow(a, b)


@inline_stage_kernel
def _fmod(a, b):
    """C fmodf: the remainder with the sign of a."""
    return np.fmod(a, b)


@inline_stage_kernel
def _wrap(value, vmax, vmin):
    r = vmax - vmin
    return value - r * math.floor((value - vmin) / r) if r != 0.0 else vmin


@inline_stage_kernel
def _sign(f):
    return 0.0 if f == 0.0 else (1.0 if f > 0.0 else -1.0)


@inline_stage_kernel
def _smoothmin(a, b, k):
    if k != 0.0:
        h = max(k - abs(a - b), 0.0) / k
        return min(a, b) - h * h * h * k * (1.0 / 6.0)
    return min(a, b)


@inline_stage_kernel
def _clamp(x, lo, hi):
    return min(max(x, lo), hi)


@inline_stage_kernel
def _smoothstep(e0, e1, x):
    if x < e0:
        return 0.0
    if x >= e1:
        return 1.0
    t = (x - e0) / (e1 - e0)
    return (3.0 - 2.0 * t) * (t * t)


@inline_stage_kernel
def _smootherstep(e0, e1, x):
    x = _clamp(_safe_divide(x - e0, e1 - e0), 0.0, 1.0)
    return x * x * x * (x * (x * 6.0 - 15.0) + 10.0)


@stage_kernel
def math_op(kind, a, b, c):
    """Math node (C5 svm/math_util.h svm_math); kind = program.MATH index."""
    if kind == 0:
        return a + b
    if kind == 1:
        return a - b
    if kind == 2:
        return a * b
    if kind == 3:
        return _safe_divide(a, b)
    if kind == 4:
        return math.sin(a)
    if kind == 5:
        return math.cos(a)
    if kind == 6:
        return math.tan(a)
    if kind == 7:
        return math.asin(_clamp(a, -1.0, 1.0))
    if kind == 8:
        return math.acos(_clamp(a, -1.0, 1.0))
    if kind == 9:
        return math.atan(a)
    if kind == 10:
        return _safe_pow(a, b)
    if kind == 11:  # safe_logf
        if a <= 0.0 or b <= 0.0:
            return 0.0
        return _safe_divide(math.log(a), math.log(b))
    if kind == 12:
        return min(a, b)
    if kind == 13:
        return max(a, b)
    if kind == 14:
        return math.floor(a + 0.5)
    if kind == 15:
        return 1.0 if a < b else 0.0
    if kind == 16:
        return 1.0 if a > b else 0.0
    if kind == 17:
        return _fmod(a, b) if b != 0.0 else 0.0
    if kind == 18:
        return abs(a)
    if kind == 19:  # compatible_atan2(y = a, x = b)
        return 0.0 if (a == 0.0 and b == 0.0) else math.atan2(a, b)
    if kind == 20:
        return math.floor(a)
    if kind == 21:
        return math.ceil(a)
    if kind == 22:
        return a - math.floor(a)
    if kind == 23:
        return math.sqrt(max(a, 0.0))
    if kind == 24:
        return 1.0 / math.sqrt(a) if a > 0.0 else 0.0
    if kind == 25:
        return _sign(a)
    if kind == 26:
        return math.exp(min(a, 709.0))
    if kind == 27:
        return a * (math.pi / 180.0)
    if kind == 28:
        return a * (180.0 / math.pi)
    if kind == 29:
        return math.sinh(_clamp(a, -709.0, 709.0))
    if kind == 30:
        return math.cosh(_clamp(a, -709.0, 709.0))
    if kind == 31:
        return math.tanh(a)
    if kind == 32:
        return math.floor(a) if a >= 0.0 else math.ceil(a)
    if kind == 33:
        return math.floor(_safe_divide(a, b)) * b
    if kind == 34:
        return _wrap(a, b, c)
    if kind == 35:
        return 1.0 if (a == b or abs(a - b) <= max(c, _FLT_EPSILON)) else 0.0
    if kind == 36:
        return a * b + c
    if kind == 37:  # pingpongf
        if b == 0.0:
            return 0.0
        f = (a - b) / (b * 2.0)
        return abs((f - math.floor(f)) * b * 2.0 - b)
    if kind == 38:
        return _smoothmin(a, b, c)
    if kind == 39:
        return -_smoothmin(-a, -b, c)
    if kind == 40:
        return a - math.floor(a / b) * b if b != 0.0 else 0.0
    return 0.0


# Component-wise Vector Math kinds (program.VECTOR_MATH index) -> the Math kind (program.MATH index)
# whose scalar function Cycles applies per component (C5 src/util/math_float3.h: safe_divide,
# safe_fmod, safe_pow, compatible_sign, floor(safe_divide(a, b)) * b are the scalar ones per
# component); -1 for kinds handled whole (cross, project, reflect, ...) or WRAP, whose vector form
# differs (safe_floored_fmod(a - min, max - min) + min).
_VECTOR_TO_MATH = np.full(len(VECTOR_MATH_KINDS), -1, np.int64)
for _vector_kind, _math_kind in (("ADD", "ADD"), ("SUBTRACT", "SUBTRACT"), ("MULTIPLY", "MULTIPLY"),
                                 ("DIVIDE", "DIVIDE"), ("SCALE", "MULTIPLY"), ("SNAP", "SNAP"), ("FLOOR", "FLOOR"),
                                 ("CEIL", "CEIL"), ("MODULO", "MODULO"), ("FRACTION", "FRACT"),
                                 ("ABSOLUTE", "ABSOLUTE"), ("MINIMUM", "MINIMUM"), ("MAXIMUM", "MAXIMUM"),
                                 ("SINE", "SINE"), ("COSINE", "COSINE"), ("TANGENT", "TANGENT"),
                                 ("MULTIPLY_ADD", "MULTIPLY_ADD"), ("POWER", "POWER"), ("SIGN", "SIGN")):
    _VECTOR_TO_MATH[VECTOR_MATH[_vector_kind]] = MATH[_math_kind]
_VECTOR_WRAP = VECTOR_MATH["WRAP"]
VECTOR_MATH_SCALE = VECTOR_MATH["SCALE"]


@stage_kernel
def _vector_math_component(kind, a, b, c, scale):
    """One component of a component-wise Vector Math kind, through math_op (SCALE multiplies by
    the scale; WRAP keeps the vector form)."""
    if kind == _VECTOR_WRAP:
        r = b - c
        return (a - c) - math.floor((a - c) / r) * r + c if r != 0.0 else c
    math_kind = _VECTOR_TO_MATH[kind]
    if math_kind < 0:
        return 0.0
    return math_op(math_kind, a, scale if kind == VECTOR_MATH_SCALE else b, c)


@stage_kernel
def _vector_math(regs, kind, a, b, c, scale, out, out_value):
    """Vector Math node (C5 svm/math_util.h svm_vector_math) on registers."""
    ax, ay, az = regs[a], regs[a + 1], regs[a + 2]
    bx, by, bz = regs[b], regs[b + 1], regs[b + 2]
    cx, cy, cz = regs[c], regs[c + 1], regs[c + 2]
    s = regs[scale]
    rx = ry = rz = 0.0
    value = 0.0
    if kind == 4:  # cross
        rx, ry, rz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    elif kind == 5:  # project
        ls = bx * bx + by * by + bz * bz
        f = (ax * bx + ay * by + az * bz) / ls if ls != 0.0 else 0.0
        rx, ry, rz = f * bx, f * by, f * bz
    elif kind == 6 or kind == 24:  # reflect / refract with safe_normalize(b)
        ln = math.sqrt(bx * bx + by * by + bz * bz)
        if ln != 0.0:
            bx, by, bz = bx / ln, by / ln, bz / ln
        d = ax * bx + ay * by + az * bz
        if kind == 6:
            rx, ry, rz = ax - 2.0 * d * bx, ay - 2.0 * d * by, az - 2.0 * d * bz
        else:
            k = 1.0 - s * s * (1.0 - d * d)
            if k >= 0.0:
                f = s * d + math.sqrt(k)
                rx, ry, rz = s * ax - f * bx, s * ay - f * by, s * az - f * bz
    elif kind == 25:  # faceforward(a, incident b, reference c)
        sign = 1.0 if (cx * bx + cy * by + cz * bz) < 0.0 else -1.0
        rx, ry, rz = sign * ax, sign * ay, sign * az
    elif kind == 7:
        value = ax * bx + ay * by + az * bz
    elif kind == 8:
        value = math.sqrt((ax - bx) ** 2 + (ay - by) ** 2 + (az - bz) ** 2)
    elif kind == 9:
        value = math.sqrt(ax * ax + ay * ay + az * az)
    elif kind == 11:  # safe_normalize
        ln = math.sqrt(ax * ax + ay * ay + az * az)
        rx, ry, rz = (ax / ln, ay / ln, az / ln) if ln != 0.0 else (ax, ay, az)
    else:
        rx = _vector_math_component(kind, ax, bx, cx, s)
        ry = _vector_math_component(kind, ay, by, cy, s)
        rz = _vector_math_component(kind, az, bz, cz, s)
    regs[out], regs[out + 1], regs[out + 2] = rx, ry, rz
    regs[out_value] = value


# ---------------------------------------------------------------------------------------------
# Colour helpers (C5 src/util/color.h, src/kernel/svm/color_util.h)
# ---------------------------------------------------------------------------------------------
@stage_kernel
def rgb_to_hsv(r, g, b):
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    delta = cmax - cmin
    s = delta / cmax if cmax != 0.0 else 0.0
    h = 0.0
    if s != 0.0:
        cr, cg, cb = (cmax - r) / delta, (cmax - g) / delta, (cmax - b) / delta
        if r == cmax:
            h = cb - cg
        elif g == cmax:
            h = 2.0 + cr - cb
        else:
            h = 4.0 + cg - cr
        h /= 6.0
        if h < 0.0:
            h += 1.0
    return h, s, cmax


@stage_kernel
def hsv_to_rgb(h, s, v):
    if s == 0.0:
        return v, v, v
    if h == 1.0:
        h = 0.0
    h *= 6.0
    i = math.floor(h)
    f = h - i
    p = v * (1.0 - s)
    q = v * (1.0 - s * f)
    t = v * (1.0 - s * (1.0 - f))
    if i == 0.0:
        return v, t, p
    if i == 1.0:
        return q, v, p
    if i == 2.0:
        return p, v, t
    if i == 3.0:
        return p, q, v
    if i == 4.0:
        return t, p, v
    return v, p, q


@stage_kernel
def rgb_to_hsl(r, g, b):
    cmax = max(r, max(g, b))
    cmin = min(r, min(g, b))
    lum = min(1.0, (cmax + cmin) / 2.0)
    h = s = 0.0
    if cmax != cmin:
        d = cmax - cmin
        s = d / (2.0 - cmax - cmin) if lum > 0.5 else d / (cmax + cmin)
        if cmax == r:
            h = (g - b) / d + (6.0 if g < b else 0.0)
        elif cmax == g:
            h = (b - r) / d + 2.0
        else:
            h = (r - g) / d + 4.0
    return h / 6.0, s, lum


@stage_kernel
def hsl_to_rgb(h, s, lum):
    nr = _clamp(abs(h * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    ng = _clamp(2.0 - abs(h * 6.0 - 2.0), 0.0, 1.0)
    nb = _clamp(2.0 - abs(h * 6.0 - 4.0), 0.0, 1.0)
    chroma = (1.0 - abs(2.0 * lum - 1.0)) * s
    return (nr - 0.5) * chroma + lum, (ng - 0.5) * chroma + lum, (nb - 0.5) * chroma + lum


@stage_kernel
def _blend_channel(kind, t, c1, c2):
    """Per-channel blend modes of svm_mix (C5 svm/color_util.h); HSV modes are handled whole."""
    tm = 1.0 - t
    if kind == 0:
        return tm * c1 + t * c2
    if kind == 1:
        return tm * c1 + t * (c1 + c2)
    if kind == 2:
        return tm * c1 + t * (c1 * c2)
    if kind == 3:  # screen
        return 1.0 - (tm + t * (1.0 - c2)) * (1.0 - c1)
    if kind == 4:  # overlay
        if c1 < 0.5:
            return c1 * (tm + 2.0 * t * c2)
        return 1.0 - (tm + 2.0 * t * (1.0 - c2)) * (1.0 - c1)
    if kind == 5:
        return tm * c1 + t * (c1 - c2)
    if kind == 6:  # divide
        return tm * c1 + t * c1 / c2 if c2 != 0.0 else c1
    if kind == 7:
        return tm * c1 + t * abs(c1 - c2)
    if kind == 8:
        return tm * c1 + t * min(c1, c2)
    if kind == 9:
        return tm * c1 + t * max(c1, c2)
    if kind == 10:  # dodge
        if c1 == 0.0:
            return c1
        tmp = 1.0 - t * c2
        if tmp <= 0.0:
            return 1.0
        tmp = c1 / tmp
        return 1.0 if tmp > 1.0 else tmp
    if kind == 11:  # burn
        tmp = tm + t * c2
        if tmp <= 0.0:
            return 0.0
        tmp = 1.0 - (1.0 - c1) / tmp
        return _clamp(tmp, 0.0, 1.0)
    if kind == 16:  # soft light
        scr = 1.0 - (1.0 - c2) * (1.0 - c1)
        return tm * c1 + t * ((1.0 - c1) * c2 * c1 + c1 * scr)
    if kind == 17:  # linear light
        return c1 + t * (2.0 * c2 - 1.0)
    if kind == 18:  # exclusion
        return max(tm * c1 + t * (c1 + c2 - 2.0 * c1 * c2), 0.0)
    return c1


@stage_kernel
def mix_color(kind, t, r1, g1, b1, r2, g2, b2):
    """svm_mix (C5 svm/color_util.h): blend mode `kind` (program.MIX_BLEND index)."""
    if kind == 12 or kind == 15:  # hue / color
        h2, s2, v2 = rgb_to_hsv(r2, g2, b2)
        if s2 == 0.0:
            return r1, g1, b1
        h, s, v = rgb_to_hsv(r1, g1, b1)
        h = h2
        if kind == 15:
            s = s2
        r, g, b = hsv_to_rgb(h, s, v)
        tm = 1.0 - t
        return tm * r1 + t * r, tm * g1 + t * g, tm * b1 + t * b
    if kind == 13:  # saturation
        h, s, v = rgb_to_hsv(r1, g1, b1)
        if s == 0.0:
            return r1, g1, b1
        s = (1.0 - t) * s + t * rgb_to_hsv(r2, g2, b2)[1]
        return hsv_to_rgb(h, s, v)
    if kind == 14:  # value
        h, s, v = rgb_to_hsv(r1, g1, b1)
        v = (1.0 - t) * v + t * rgb_to_hsv(r2, g2, b2)[2]
        return hsv_to_rgb(h, s, v)
    return _blend_channel(kind, t, r1, r2), _blend_channel(kind, t, g1, g2), _blend_channel(kind, t, b1, b2)


@stage_kernel
def _ramp_lookup(tables, offset, size, channels, channel, f, interpolate, extrapolate):
    """float_ramp_lookup / rgb_ramp_lookup (C5 svm/ramp.h) of one channel of a table of `size`
    entries of `channels` floats starting at tables[offset]."""
    if extrapolate and (f < 0.0 or f > 1.0):
        if f < 0.0:
            t0 = tables[offset + channel]
            dy = t0 - tables[offset + channels + channel]
            f = -f
        else:
            t0 = tables[offset + (size - 1) * channels + channel]
            dy = t0 - tables[offset + (size - 2) * channels + channel]
            f = f - 1.0
        return t0 + dy * f * (size - 1)
    if not f > 0.0:  # saturate, NaN -> 0
        f = 0.0
    f = min(f, 1.0) * (size - 1)
    i = min(max(int(f), 0), size - 1)
    t = f - i
    a = tables[offset + i * channels + channel]
    if interpolate and t > 0.0:
        a = (1.0 - t) * a + t * tables[offset + (i + 1) * channels + channel]
    return a


@stage_kernel
def _attribute(attributes, world_to_index, channel, px, py, pz):
    """Trilinear lookup of one attribute channel at a world point (0 outside the grid)."""
    m = world_to_index
    x = m[0, 0] * px + m[0, 1] * py + m[0, 2] * pz + m[0, 3]
    y = m[1, 0] * px + m[1, 1] * py + m[1, 2] * pz + m[1, 3]
    z = m[2, 0] * px + m[2, 1] * py + m[2, 2] * pz + m[2, 3]
    nx, ny, nz = attributes.shape[0], attributes.shape[1], attributes.shape[2]
    if not (0.0 <= x <= nx - 1 and 0.0 <= y <= ny - 1 and 0.0 <= z <= nz - 1) or nx < 2 or ny < 2 or nz < 2:
        return 0.0
    i = min(int(x), nx - 2)  # x >= 0 here: truncation is the floor, without libm's call
    j = min(int(y), ny - 2)
    k = min(int(z), nz - 2)
    fx, fy, fz = x - i, y - j, z - k
    total = 0.0
    for dx in range(2):
        wx = fx if dx else 1.0 - fx
        for dy in range(2):
            wy = wx * (fy if dy else 1.0 - fy)
            for dz in range(2):
                total += wy * (fz if dz else 1.0 - fz) * attributes[i + dx, j + dy, k + dz, channel]
    return total


@inline_stage_kernel
def _affine(m, x, y, z):
    return (m[0, 0] * x + m[0, 1] * y + m[0, 2] * z + m[0, 3],
            m[1, 0] * x + m[1, 1] * y + m[1, 2] * z + m[1, 3],
            m[2, 0] * x + m[2, 1] * y + m[2, 2] * z + m[2, 3])


@stage_kernel
def _euler_rotate(rx, ry, rz, x, y, z, transposed):
    """euler_to_transform (C5 src/util/transform.h) applied to a direction, or its transpose."""
    cx, cy, cz = math.cos(rx), math.cos(ry), math.cos(rz)
    sx, sy, sz = math.sin(rx), math.sin(ry), math.sin(rz)
    m00, m01, m02 = cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz
    m10, m11, m12 = cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz
    m20, m21, m22 = -sy, cy * sx, cy * cx
    if transposed:
        return (m00 * x + m10 * y + m20 * z, m01 * x + m11 * y + m21 * z, m02 * x + m12 * y + m22 * z)
    return (m00 * x + m01 * y + m02 * z, m10 * x + m11 * y + m12 * z, m20 * x + m21 * y + m22 * z)


@stage_kernel
def _mapping(regs, kind, v, loc, rot, scl, out):
    """Mapping node (C5 svm/mapping_util.h svm_mapping)."""
    x, y, z = regs[v], regs[v + 1], regs[v + 2]
    rx, ry, rz = regs[rot], regs[rot + 1], regs[rot + 2]
    sx, sy, sz = regs[scl], regs[scl + 1], regs[scl + 2]
    if kind == 0:  # point
        a, b, c = _euler_rotate(rx, ry, rz, x * sx, y * sy, z * sz, False)
        a, b, c = a + regs[loc], b + regs[loc + 1], c + regs[loc + 2]
    elif kind == 1:  # texture
        a, b, c = _euler_rotate(rx, ry, rz, x - regs[loc], y - regs[loc + 1], z - regs[loc + 2], True)
        a, b, c = _safe_divide(a, sx), _safe_divide(b, sy), _safe_divide(c, sz)
    elif kind == 2:  # vector
        a, b, c = _euler_rotate(rx, ry, rz, x * sx, y * sy, z * sz, False)
    else:  # normal
        a, b, c = _euler_rotate(rx, ry, rz, _safe_divide(x, sx), _safe_divide(y, sy), _safe_divide(z, sz), False)
        ln = math.sqrt(a * a + b * b + c * c)
        if ln != 0.0:
            a, b, c = a / ln, b / ln, c / ln
    regs[out], regs[out + 1], regs[out + 2] = a, b, c


@stage_kernel
def _map_range(kind, value, fmin, fmax, tmin, tmax, steps, clamp):
    """Map Range, float (C5 svm/map_range.h svm_node_map_range). Its clamp is the Clamp node (range
    type) that MapRangeNode::expand (scene/shader_nodes.cpp) puts after it for every interpolation
    type, so it also clamps the 0 of an empty from-range."""
    if fmax == fmin:
        result = 0.0
    else:
        if kind == 0:
            f = (value - fmin) / (fmax - fmin)
        elif kind == 1:
            f = (value - fmin) / (fmax - fmin)
            f = math.floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
        elif kind == 2:
            f = 1.0 - _smoothstep(fmax, fmin, value) if fmin > fmax else _smoothstep(fmin, fmax, value)
        else:
            f = 1.0 - _smootherstep(fmax, fmin, value) if fmin > fmax else _smootherstep(fmin, fmax, value)
        result = tmin + f * (tmax - tmin)
    if clamp:
        result = _clamp(result, tmax, tmin) if tmin > tmax else _clamp(result, tmin, tmax)
    return result


@stage_kernel
def _map_range_vector_component(kind, value, fmin, fmax, tmin, tmax, steps, clamp):
    """One component of svm_node_vector_map_range (C5 svm/map_range.h)."""
    f = _safe_divide(value - fmin, fmax - fmin)
    if kind == 1:
        f = math.floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
    elif kind == 2:
        f = _clamp(f, 0.0, 1.0)
        f = (3.0 - 2.0 * f) * (f * f)
    elif kind == 3:
        f = _clamp(f, 0.0, 1.0)
        f = f * f * f * (f * (f * 6.0 - 15.0) + 10.0)
    result = tmin + f * (tmax - tmin)
    if clamp:
        result = _clamp(result, tmax, tmin) if tmin > tmax else _clamp(result, tmin, tmax)
    return result


# ---------------------------------------------------------------------------------------------
# Volume closures (C5 svm/closure.h), accumulated into the output registers
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def _add_scatter(regs, lobe, sr, sg, sb, g):
    base = R_LOBES + lobe * LOBE_STRIDE
    regs[base] += sr
    regs[base + 1] += sg
    regs[base + 2] += sb
    regs[base + 3] = g


@inline_stage_kernel
def _add3(regs, at, r, g, b):
    regs[at] += r
    regs[at + 1] += g
    regs[at + 2] += b


@stage_kernel
def _principled_volume(regs, code, a):
    """svm_node_principled_volume: density, colour and temperature already carry their attribute
    factors (the compiler multiplies them in, as the node does when the attribute exists)."""
    lobe, w, col, dens, aniso, absorb = code[a], regs[code[a + 1]], code[a + 2], code[a + 3], code[a + 4], code[a + 5]
    strength, emit, bb, tint, temp = code[a + 6], code[a + 7], code[a + 8], code[a + 9], code[a + 10]
    density = w * max(regs[dens], 0.0)
    if density > CLOSURE_WEIGHT_CUTOFF:
        cr, cg, cb = regs[col], regs[col + 1], regs[col + 2]
        _add_scatter(regs, lobe, cr * density, cg * density, cb * density, regs[aniso])
        ar = max(math.sqrt(max(regs[absorb], 0.0)), 0.0)
        ag = max(math.sqrt(max(regs[absorb + 1], 0.0)), 0.0)
        ab = max(math.sqrt(max(regs[absorb + 2], 0.0)), 0.0)
        _add3(regs, R_SIGMA_A, max(1.0 - cr, 0.0) * max(1.0 - ar, 0.0) * density,
              max(1.0 - cg, 0.0) * max(1.0 - ag, 0.0) * density, max(1.0 - cb, 0.0) * max(1.0 - ab, 0.0) * density)
    e = regs[strength]
    if e > CLOSURE_WEIGHT_CUTOFF:
        _add3(regs, R_EMISSION, w * e * regs[emit], w * e * regs[emit + 1], w * e * regs[emit + 2])
    intensity = regs[bb]
    if intensity > CLOSURE_WEIGHT_CUTOFF:
        t = max(regs[temp], 0.0)
        if t > CLOSURE_WEIGHT_CUTOFF:
            power = _BLACKBODY_SIGMA * ((1.0 - intensity) + intensity * t * t * t * t)
            if power > 0.0:
                r, g, b = blackbody_rec709_scalar(t)
                s = w * power
                _add3(regs, R_EMISSION, s * r * regs[tint], s * g * regs[tint + 1], s * b * regs[tint + 2])


# ---------------------------------------------------------------------------------------------
# The interpreter
# ---------------------------------------------------------------------------------------------
@stage_kernel
def run_program(code, init, tables, regs, frame, attributes, world_to_index, px, py, pz, images):
    """Evaluate a program at world point (px, py, pz): registers start as `init` with the position
    in R_P; the volume closure outputs are then in R_SIGMA_A, R_EMISSION and R_LOBES. images: the
    scene's images.ImageTable (read by IMAGE_TEXTURE; images.empty_image_table() when none)."""
    for i in range(init.shape[0]):
        regs[i] = init[i]
    regs[R_P], regs[R_P + 1], regs[R_P + 2] = px, py, pz
    pc = 0
    n = code.shape[0]
    while pc < n:
        op = code[pc]
        a = pc + 1
        if op == OP_MATH:
            regs[code[a + 4]] = math_op(code[a], regs[code[a + 1]], regs[code[a + 2]], regs[code[a + 3]])
        elif op == OP_VECTOR_MATH:
            _vector_math(regs, code[a], code[a + 1], code[a + 2], code[a + 3], code[a + 4], code[a + 5], code[a + 6])
        elif op == OP_CLAMP:
            v, lo, hi = regs[code[a + 1]], regs[code[a + 2]], regs[code[a + 3]]
            if code[a] == 1 and lo > hi:  # range: bounds swapped (C5 svm/clamp.h)
                lo, hi = hi, lo
            regs[code[a + 4]] = min(max(v, lo), hi)
        elif op == OP_MAP_RANGE:
            regs[code[a + 8]] = _map_range(code[a], regs[code[a + 2]], regs[code[a + 3]], regs[code[a + 4]],
                                           regs[code[a + 5]], regs[code[a + 6]], regs[code[a + 7]], code[a + 1])
        elif op == OP_MAP_RANGE_VECTOR:
            for c in range(3):
                regs[code[a + 8] + c] = _map_range_vector_component(
                    code[a], regs[code[a + 2] + c], regs[code[a + 3] + c], regs[code[a + 4] + c],
                    regs[code[a + 5] + c], regs[code[a + 6] + c], regs[code[a + 7] + c], code[a + 1])
        elif op == OP_MIX_FLOAT:  # C5 svm/mix.h svm_node_mix_float
            t = regs[code[a + 1]]
            if code[a]:
                t = _clamp(t, 0.0, 1.0)
            regs[code[a + 4]] = (1.0 - t) * regs[code[a + 2]] + t * regs[code[a + 3]]
        elif op == OP_MIX_VECTOR:  # svm_node_mix_vector(_non_uniform): factor3 per component
            for c in range(3):
                t = regs[code[a + 1] + c]
                if code[a]:
                    t = _clamp(t, 0.0, 1.0)
                regs[code[a + 4] + c] = (1.0 - t) * regs[code[a + 2] + c] + t * regs[code[a + 3] + c]
        elif op == OP_MIX_COLOR:  # svm_node_mix_color
            t = regs[code[a + 3]]
            if code[a + 1]:
                t = _clamp(t, 0.0, 1.0)
            x, y = code[a + 4], code[a + 5]
            r, g, b = mix_color(code[a], t, regs[x], regs[x + 1], regs[x + 2], regs[y], regs[y + 1], regs[y + 2])
            if code[a + 2]:
                r, g, b = _clamp(r, 0.0, 1.0), _clamp(g, 0.0, 1.0), _clamp(b, 0.0, 1.0)
            o = code[a + 6]
            regs[o], regs[o + 1], regs[o + 2] = r, g, b
        elif op == OP_COLOR_RAMP:  # svm_node_rgb_ramp: 257 RGBA entries (Blender's colorramp_to_array)
            f = regs[code[a + 2]]
            o = code[a + 3]
            for c in range(3):
                regs[o + c] = _ramp_lookup(tables, code[a], 257, 4, c, f, code[a + 1] != 0, False)
            regs[code[a + 4]] = _ramp_lookup(tables, code[a], 257, 4, 3, f, code[a + 1] != 0, False)
        elif op == OP_CURVE_FLOAT:  # svm_node_curve: the value's position in [min_x, max_x] looked up
            size, extrapolate = code[a + 1], code[a + 2] != 0
            lo, hi = regs[code[a + 3]], regs[code[a + 4]]
            v = regs[code[a + 6]]
            # Cycles divides by the range unguarded; an empty range (all points at one x) reads the
            # first entry here instead of inf / NaN
            y = _ramp_lookup(tables, code[a], size, 1, 0, _safe_divide(v - lo, hi - lo), True, extrapolate)
            fac = regs[code[a + 5]]
            regs[code[a + 7]] = (1.0 - fac) * v + fac * y
        elif op == OP_CURVE_RGB:  # svm_node_curves: each channel through its column of the table
            size, extrapolate = code[a + 1], code[a + 2] != 0
            lo, hi = regs[code[a + 3]], regs[code[a + 4]]
            fac = regs[code[a + 5]]
            i, o = code[a + 6], code[a + 7]
            for c in range(3):
                v = regs[i + c]
                y = _ramp_lookup(tables, code[a], size, 3, c, _safe_divide(v - lo, hi - lo), True, extrapolate)
                regs[o + c] = (1.0 - fac) * v + fac * y
        elif op == OP_SEPARATE3:
            i = code[a + 1]
            x, y, z = regs[i], regs[i + 1], regs[i + 2]
            if code[a] == 1:
                x, y, z = rgb_to_hsv(x, y, z)
            elif code[a] == 2:
                x, y, z = rgb_to_hsl(x, y, z)
            regs[code[a + 2]], regs[code[a + 3]], regs[code[a + 4]] = x, y, z
        elif op == OP_COMBINE3:
            x, y, z = regs[code[a + 1]], regs[code[a + 2]], regs[code[a + 3]]
            if code[a] == 1:
                x, y, z = hsv_to_rgb(x, y, z)
            elif code[a] == 2:
                x, y, z = hsl_to_rgb(x, y, z)
            o = code[a + 4]
            regs[o], regs[o + 1], regs[o + 2] = x, y, z
        elif op == OP_COLOR_TO_FLOAT or op == OP_RGB_TO_BW:  # linear_rgb_to_gray (svm/convert.h)
            i, w = code[a], code[a + 1]
            regs[code[a + 2]] = regs[w] * regs[i] + regs[w + 1] * regs[i + 1] + regs[w + 2] * regs[i + 2]
        elif op == OP_VECTOR_TO_FLOAT:  # average (svm/convert.h CONVERT_VF)
            i = code[a]
            regs[code[a + 1]] = (regs[i] + regs[i + 1] + regs[i + 2]) * (1.0 / 3.0)
        elif op == OP_FLOAT_TO_VECTOR:
            v = regs[code[a]]
            o = code[a + 1]
            regs[o], regs[o + 1], regs[o + 2] = v, v, v
        elif op == OP_COPY:
            for c in range(code[a]):
                regs[code[a + 2] + c] = regs[code[a + 1] + c]
        elif op == OP_TRANSFORM_POINT or op == OP_TRANSFORM_DIRECTION:
            m, i, o = code[a], code[a + 1], code[a + 2]
            w = 1.0 if op == OP_TRANSFORM_POINT else 0.0
            x, y, z = regs[i], regs[i + 1], regs[i + 2]
            for r in range(3):
                regs[o + r] = regs[m + 4 * r] * x + regs[m + 4 * r + 1] * y + regs[m + 4 * r + 2] * z + w * regs[m + 4 * r + 3]
        elif op == OP_TEXCO:
            kind, o = code[a], code[a + 1]
            x, y, z = regs[R_P], regs[R_P + 1], regs[R_P + 2]
            if kind == 0 or kind == 1:
                x, y, z = _affine(frame[0], x, y, z)
                if kind == 0:
                    x, y, z = _affine(frame[1], x, y, z)
            elif kind == 3:
                x, y, z = regs[R_N], regs[R_N + 1], regs[R_N + 2]
            elif kind == 4:
                x, y, z = regs[R_UV], regs[R_UV + 1], regs[R_UV + 2]
            elif kind == 5:
                x, y, z = regs[R_I], regs[R_I + 1], regs[R_I + 2]
            regs[o], regs[o + 1], regs[o + 2] = x, y, z
        elif op == OP_MAPPING:
            _mapping(regs, code[a], code[a + 1], code[a + 2], code[a + 3], code[a + 4], code[a + 5])
        elif op == OP_ATTRIBUTE:
            o = code[a + 2]
            for c in range(code[a + 1]):
                regs[o + c] = _attribute(attributes, world_to_index, code[a] + c, px, py, pz)
        elif op == OP_BLACKBODY:  # svm_node_blackbody: max(colour, 0)
            r, g, b = blackbody_rec709_scalar(regs[code[a]])
            o = code[a + 1]
            regs[o], regs[o + 1], regs[o + 2] = max(r, 0.0), max(g, 0.0), max(b, 0.0)
        elif op == OP_INVERT:  # svm_node_invert: interp(c, 1 - c, fac)
            fac, i, o = regs[code[a]], code[a + 1], code[a + 2]
            for c in range(3):
                regs[o + c] = (1.0 - fac) * regs[i + c] + fac * (1.0 - regs[i + c])
        elif op == OP_GAMMA:  # svm_math_gamma_color
            i, gamma, o = code[a], regs[code[a + 1]], code[a + 2]
            for c in range(3):
                v = regs[i + c]
                regs[o + c] = 1.0 if gamma == 0.0 else (v ** gamma if v > 0.0 else v)
        elif op == OP_BRIGHT_CONTRAST:  # svm_brightness_contrast
            i, bright, contrast, o = code[a], regs[code[a + 1]], regs[code[a + 2]], code[a + 3]
            for c in range(3):
                regs[o + c] = max((1.0 + contrast) * regs[i + c] + bright - contrast * 0.5, 0.0)
        elif op == OP_HUE_SAT:  # svm_node_hsv (svm/hsv.h)
            fac, i, o = regs[code[a + 3]], code[a + 4], code[a + 5]
            h, s, v = rgb_to_hsv(regs[i], regs[i + 1], regs[i + 2])
            h = h + regs[code[a]] + 0.5
            h = h - math.floor(h)
            s = _clamp(s * regs[code[a + 1]], 0.0, 1.0)
            v = v * regs[code[a + 2]]
            r, g, b = hsv_to_rgb(h, s, v)
            regs[o] = max(fac * r + (1.0 - fac) * regs[i], 0.0)
            regs[o + 1] = max(fac * g + (1.0 - fac) * regs[i + 1], 0.0)
            regs[o + 2] = max(fac * b + (1.0 - fac) * regs[i + 2], 0.0)
        elif op == OP_PRINCIPLED_VOLUME:
            _principled_volume(regs, code, a)
        elif op == OP_VOLUME_SCATTER:  # svm_node_closure_volume: weight x Color x max(Density, 0)
            lobe, w, col, dens = code[a], regs[code[a + 1]], code[a + 2], regs[code[a + 3]]
            d = w * max(dens, 0.0)
            if d > 0.0:
                _add_scatter(regs, lobe, regs[col] * d, regs[col + 1] * d, regs[col + 2] * d, regs[code[a + 4]])
        elif op == OP_VOLUME_ABSORPTION:  # extinction (1 - Color) x max(Density, 0)
            w, col, dens = regs[code[a]], code[a + 1], regs[code[a + 2]]
            d = w * max(dens, 0.0)
            if d > 0.0:
                _add3(regs, R_SIGMA_A, (1.0 - regs[col]) * d, (1.0 - regs[col + 1]) * d, (1.0 - regs[col + 2]) * d)
        elif op == OP_VOLUME_EMISSION:
            w, col, s = regs[code[a]], code[a + 1], regs[code[a + 2]]
            _add3(regs, R_EMISSION, w * s * regs[col], w * s * regs[col + 1], w * s * regs[col + 2])
        elif op == OP_VOLUME_COEFFICIENTS:  # svm_node_volume_coefficients
            lobe, w, sc, ab, em = code[a], regs[code[a + 1]], code[a + 2], code[a + 3], code[a + 4]
            _add_scatter(regs, lobe, w * regs[sc], w * regs[sc + 1], w * regs[sc + 2], regs[code[a + 5]])
            _add3(regs, R_SIGMA_A, w * regs[ab], w * regs[ab + 1], w * regs[ab + 2])
            _add3(regs, R_EMISSION, w * regs[em], w * regs[em + 1], w * regs[em + 2])
        elif op == OP_MIX_WEIGHTS:  # svm_node_mix_closure: clamp(fac) splits the weight
            w, f = regs[code[a]], _clamp(regs[code[a + 1]], 0.0, 1.0)
            regs[code[a + 2]] = w * (1.0 - f)
            regs[code[a + 3]] = w * f
        elif op >= SURFACE_OP_BASE and op < TEXTURE_OP_BASE:
            run_surface_op(op, code, a, regs, tables, images, frame)
        elif op >= TEXTURE_OP_BASE:
            run_texture_op(op, code, a, regs, tables)
        pc = a + OPERAND_COUNT[op]


@stage_kernel
def closure_coefficients(regs):
    """(sigma_s rgb, sigma_t rgb, emission rgb) from the volume closure outputs of an evaluated
    program. Negative or NaN coefficients read as 0 (Cycles keeps extinction and scattering
    non-negative: a negative closure weight adds nothing; the medium counts and reports them)."""
    sr = sg = sb = 0.0
    for k in range(MAX_LOBES):
        base = R_LOBES + k * LOBE_STRIDE
        sr += regs[base]
        sg += regs[base + 1]
        sb += regs[base + 2]
    sr, sg, sb = _non_negative(sr), _non_negative(sg), _non_negative(sb)
    ar, ag, ab = _non_negative(regs[R_SIGMA_A]), _non_negative(regs[R_SIGMA_A + 1]), _non_negative(regs[R_SIGMA_A + 2])
    er, eg, eb = regs[R_EMISSION], regs[R_EMISSION + 1], regs[R_EMISSION + 2]
    er = er if er == er else 0.0
    eg = eg if eg == eg else 0.0
    eb = eb if eb == eb else 0.0
    return sr, sg, sb, sr + ar, sg + ag, sb + ab, er, eg, eb


@inline_stage_kernel
def _non_negative(v):
    return v if v > 0.0 else 0.0  # NaN -> 0 too


@stage_kernel
def run_program_many(code, init, tables, regs, frame, attributes, world_to_index, points, outputs, first, count,
                     images):
    """Evaluate at each row of points (N, 3); copy registers [first, first + count) to outputs (N, count)."""
    for n in range(points.shape[0]):
        run_program(code, init, tables, regs, frame, attributes, world_to_index,
                    points[n, 0], points[n, 1], points[n, 2], images)
        for c in range(count):
            outputs[n, c] = regs[first + c]
