"""Deterministic random numbers and sample warps.

Every random number is a pure function of (seed, pixel, sample, dimension), so an image does not
depend on batch size, thread count or the order in which paths are processed. The path sampler
draws stratified numbers (sample_pattern.sample1, keys from sample_pattern.path_key1); uniform1 is
the independent generator, a counter-based hash (splitmix64 finaliser, Steele et al. 2014), for
draws whose number is unbounded (tracking in grid media) and for tables built at load time.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_INV_2_53 = 1.0 / float(1 << 53)

# Dimension layout: 2 camera dimensions, then DIMS_PER_EVENT per integrator iteration: offset o of
# iteration i is dimension CAMERA_DIMS + i * DIMS_PER_EVENT + o (path_kernels._u). Dimensions 2k
# and 2k + 1 are one stratified pair (sample_pattern): both counts are even, so the pairs of
# offsets (0, 1), (2, 3), ... of an iteration are pairs.
CAMERA_DIMS = 2
DIMS_PER_EVENT = 24
# The lens sample (depth of field) and the shutter time (motion blur) of a camera ray have
# dimensions of their own far above the per-iteration ones (and below the grid streams at 2^40,
# path_kernels), so renders without a lens or motion keep their random numbers.
LENS_U_DIM = 1 << 39
LENS_V_DIM = LENS_U_DIM + 1
SHUTTER_TIME_DIM = LENS_U_DIM + 2


@kernel
def _mix64(x):
    """splitmix64 (increment and finaliser) of one uint64, wrapping arithmetic."""
    z = x + _GOLDEN
    z ^= z >> np.uint64(30)
    z *= _MIX1
    z ^= z >> np.uint64(27)
    z *= _MIX2
    z ^= z >> np.uint64(31)
    return z


def seed_key(seed: int) -> np.uint64:
    """The uint64 key of a render seed (sample_pattern.path_key1's first argument)."""
    return np.uint64(_mix64(np.uint64(seed & 0xFFFFFFFFFFFFFFFF)))  # numba returns a Python int


@kernel
def uniform1(key, dimension):
    """Uniform float64 in [0, 1) for one key at one dimension, independent of every other (key,
    dimension). The key is hashed first: path keys of one pixel differ only in their low bits
    (sample_pattern.path_key1). Every operand is uint64: numba turns uint64 mixed with int64 into
    float64."""
    return np.float64(_mix64(_mix64(key) ^ (np.uint64(dimension) * _MIX2)) >> np.uint64(11)) * _INV_2_53


# ---------------------------------------------------------------------------------------------
# Warps, one sample per call (the compiled kernels call them per path; direction tuples (x, y, z))
# ---------------------------------------------------------------------------------------------
@kernel
def local_to_world1(n0, n1, n2, x, y, z):
    """x t + y s + z n for one unit normal n, with the tangents (t, s) of Duff et al. 2017,
    "Building an Orthonormal Basis, Revisited" (branchless)."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    return ((1.0 + sign * n0 * n0 * a) * x + b * y + n0 * z,
            sign * b * x + (sign + n1 * n1 * a) * y + n1 * z,
            -sign * n0 * x - n1 * y + n2 * z)


@kernel
def cosine_hemisphere1(n0, n1, n2, u1, u2):
    """Cosine-weighted direction around a unit normal; returns (x, y, z, cos_theta)."""
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    z = np.sqrt(max(1.0 - u1, 0.0))
    wx, wy, wz = local_to_world1(n0, n1, n2, r * np.cos(phi), r * np.sin(phi), z)
    return wx, wy, wz, z


@kernel
def uniform_sphere1(u1, u2):
    z = 1.0 - 2.0 * u1
    r = np.sqrt(max(1.0 - z * z, 0.0))
    phi = 2.0 * np.pi * u2
    return r * np.cos(phi), r * np.sin(phi), z


@kernel
def uniform_cone1(ax, ay, az, cos_max, u1, u2):
    """Uniform direction in the cone of half-angle acos(cos_max) around a unit axis."""
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = np.sqrt(max(1.0 - cos_t * cos_t, 0.0))
    phi = 2.0 * np.pi * u2
    return local_to_world1(ax, ay, az, sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)


@kernel
def concentric_disk1(u1, u2):
    """Shirley-Chiu concentric map of the unit square to the unit disk; returns (x, y)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r, phi = a, (np.pi / 4.0) * (b / a)
    else:
        r, phi = b, np.pi / 2.0 - (np.pi / 4.0) * (a / b)
    return r * np.cos(phi), r * np.sin(phi)
