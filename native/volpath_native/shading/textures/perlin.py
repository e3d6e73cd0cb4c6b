"""Cycles' Perlin noise, 1D-4D (Cycles src/kernel/svm/noise.h).

Coordinates are float32 as in Cycles: the wrap (fmod 1e5), the precision correction, floor and
the fractional part decide lattice cells and hashes, and must round as Cycles does. The
interpolation runs in float64 (Cycles' float32, and its SSE/AVX evaluation order, differ from it
by a few ulps; cycles-volumes-from-blender.md section 3 "may be approximated").
"""
from __future__ import annotations

import numpy as np

from ...jit import inline_stage_kernel, stage_kernel
from .hash import hash_uint, hash_uint2, MASK32
from .perlin_corners import corner_gradients_4d, perlin_cell_3d

#: noise.h noise_scale1..4 (experimental OSL constants), as the float32 Cycles multiplies by
NOISE_SCALE_1D = float(np.float32(0.2500))
NOISE_SCALE_2D = float(np.float32(0.6616))
NOISE_SCALE_3D = float(np.float32(0.9820))
NOISE_SCALE_4D = float(np.float32(0.8344))
#: noise.h snoise_*: repeat every 1e5 (fmod), +0.5 where |p| >= 1e6
NOISE_WRAP = 100000.0
NOISE_PRECISION_LIMIT = 1000000.0


@inline_stage_kernel
def fade(t):
    """noise.h `fade`: t^3 (t (6t - 15) + 10)."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@inline_stage_kernel
def floorfrac(x):
    """util/math_base.h `floorfrac` on a float32: (int floor, float32 x - floor as float64). The
    floor is the truncation, one lower below zero: np.floor on float32 is a call to numba's helper
    on the portable target (no SSE4.1 roundss), 1.3 % of a noise cloud's render. perlin receives
    wrapped coordinates (|x| < 1e5 + 1), exact as integers."""
    x32 = np.float32(x)
    i = int(x32)
    if np.float32(i) > x32:
        i -= 1
    return i, float(x32 - np.float32(i))


@inline_stage_kernel
def _signed(h, bit, x):
    """-x where bit `bit` of h is set, else x (noise.h's `h & bit ? -x : x`), as a product by +-1
    (exact): a branch on a hash bit is unpredictable (measured: perlin_3d 115 -> 90 ns)."""
    return (1.0 - 2.0 * ((h & bit) != 0)) * x


@inline_stage_kernel
def grad1(h, x):
    """noise.h `grad1`: gradient 1 + (h & 7), negated by bit 3."""
    h = h & 15
    g = 1.0 + (h & 7)
    return (-g if h & 8 else g) * x


@inline_stage_kernel
def grad2(h, x, y):
    """noise.h `grad2`."""
    h = h & 7
    u = x if h < 4 else y
    v = 2.0 * (y if h < 4 else x)
    return _signed(h, 1, u) + _signed(h, 2, v)


@inline_stage_kernel
def grad3(h, x, y, z):
    """noise.h `grad3`."""
    h = h & 15
    u = x if h < 8 else y
    vt = x if (h == 12 or h == 14) else z
    v = y if h < 4 else vt
    return _signed(h, 1, u) + _signed(h, 2, v)


@inline_stage_kernel
def grad4(h, x, y, z, w):
    """noise.h `grad4`."""
    h = h & 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return _signed(h, 1, u) + _signed(h, 2, v) + _signed(h, 4, s)


@inline_stage_kernel
def lerp(a, b, t):
    """util/math_base.h `mix`."""
    return a + t * (b - a)


@stage_kernel
def perlin_1d(x):
    """noise.h `perlin_1d`."""
    X, fx = floorfrac(x)
    u = fade(fx)
    return lerp(grad1(hash_uint(X & MASK32), fx), grad1(hash_uint((X + 1) & MASK32), fx - 1.0), u)


@stage_kernel
def perlin_2d(x, y):
    """noise.h `perlin_2d` (scalar bi_mix)."""
    X, fx = floorfrac(x)
    Y, fy = floorfrac(y)
    u = fade(fx)
    v = fade(fy)
    X0, X1, Y0, Y1 = X & MASK32, (X + 1) & MASK32, Y & MASK32, (Y + 1) & MASK32
    v0 = grad2(hash_uint2(X0, Y0), fx, fy)
    v1 = grad2(hash_uint2(X1, Y0), fx - 1.0, fy)
    v2 = grad2(hash_uint2(X0, Y1), fx, fy - 1.0)
    v3 = grad2(hash_uint2(X1, Y1), fx - 1.0, fy - 1.0)
    return (1.0 - v) * (v0 * (1.0 - u) + v1 * u) + v * (v2 * (1.0 - u) + v3 * u)


@inline_stage_kernel
def _perlin_3d(x, y, z):
    """noise.h `perlin_3d` in float32, as Cycles' SSE/AVX paths compute it (the corners' hashes,
    gradients and the three mixes as vector code: perlin_corners.perlin_cell_3d)."""
    X, fx = floorfrac(x)
    Y, fy = floorfrac(y)
    Z, fz = floorfrac(z)
    return float(perlin_cell_3d(X & MASK32, (X + 1) & MASK32, Y & MASK32, (Y + 1) & MASK32, Z & MASK32,
                                (Z + 1) & MASK32, fx, fy, fz))


@stage_kernel
def perlin_3d(x, y, z):
    """_perlin_3d as a function of its own."""
    return _perlin_3d(x, y, z)


@stage_kernel
def _perlin_4d_slice(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw, u, v, t):
    """The tri_mix of the 8 corners at one w lattice value (noise.h `perlin_4d`, `quad_mix`)."""
    v0, v1, v2, v3, v4, v5, v6, v7 = corner_gradients_4d(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw)
    u1, v_1, t1 = 1.0 - u, 1.0 - v, 1.0 - t
    return (t1 * (v_1 * (v0 * u1 + v1 * u) + v * (v2 * u1 + v3 * u))
            + t * (v_1 * (v4 * u1 + v5 * u) + v * (v6 * u1 + v7 * u)))


@stage_kernel
def perlin_4d(x, y, z, w):
    """noise.h `perlin_4d`."""
    X, fx = floorfrac(x)
    Y, fy = floorfrac(y)
    Z, fz = floorfrac(z)
    W, fw = floorfrac(w)
    u, v, t, s = fade(fx), fade(fy), fade(fz), fade(fw)
    X0, X1, Y0, Y1, Z0, Z1 = X & MASK32, (X + 1) & MASK32, Y & MASK32, (Y + 1) & MASK32, Z & MASK32, (Z + 1) & MASK32
    a = _perlin_4d_slice(X0, X1, Y0, Y1, Z0, Z1, W & MASK32, fx, fy, fz, fw, u, v, t)
    b = _perlin_4d_slice(X0, X1, Y0, Y1, Z0, Z1, (W + 1) & MASK32, fx, fy, fz, fw - 1.0, u, v, t)
    return lerp(a, b, s)


@inline_stage_kernel
def wrap_coordinate(p):
    """noise.h `snoise_*`: fmod(p, 1e5) + 0.5 (|p| >= 1e6), in float32 (fmod is exact)."""
    p = np.float32(p)
    if abs(p) < np.float32(NOISE_WRAP):  # fmod is the identity there (and a libm call), no correction
        return p
    correction = np.float32(0.5) if abs(p) >= np.float32(NOISE_PRECISION_LIMIT) else np.float32(0.0)
    return np.float32(np.fmod(float(p), NOISE_WRAP)) + correction


@stage_kernel
def snoise_1d(x):
    """noise.h `snoise_1d`: signed noise in about [-1, 1]."""
    return NOISE_SCALE_1D * perlin_1d(wrap_coordinate(x))


@stage_kernel
def snoise_2d(x, y):
    """noise.h `snoise_2d`."""
    return NOISE_SCALE_2D * perlin_2d(wrap_coordinate(x), wrap_coordinate(y))


@inline_stage_kernel
def snoise_3d_inline(x, y, z):
    """noise.h `snoise_3d`, inlined into its caller (noise.fbm's groups of octaves)."""
    return NOISE_SCALE_3D * _perlin_3d(wrap_coordinate(x), wrap_coordinate(y), wrap_coordinate(z))


@stage_kernel
def snoise_3d(x, y, z):
    """noise.h `snoise_3d`."""
    return NOISE_SCALE_3D * perlin_3d(wrap_coordinate(x), wrap_coordinate(y), wrap_coordinate(z))


@stage_kernel
def snoise_4d(x, y, z, w):
    """noise.h `snoise_4d`."""
    return NOISE_SCALE_4D * perlin_4d(wrap_coordinate(x), wrap_coordinate(y), wrap_coordinate(z), wrap_coordinate(w))


@stage_kernel
def snoise(dimensions, x, y, z, w):
    """snoise_{dimensions}d of the first `dimensions` of (x, y, z, w) (float32 coordinates)."""
    if dimensions == 1:
        return snoise_1d(x)
    if dimensions == 2:
        return snoise_2d(x, y)
    if dimensions == 3:
        return snoise_3d(x, y, z)
    return snoise_4d(x, y, z, w)
