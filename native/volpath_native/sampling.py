"""Deterministic random numbers and sample warps.

Every random number is a pure function of (seed, pixel, sample, dimension): a counter-based hash
(splitmix64 finaliser, Steele et al. 2014), so an image does not depend on batch size, thread count
or the order in which paths are processed.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_INV_2_53 = 1.0 / float(1 << 53)

# Dimension layout: 2 camera dimensions, then DIMS_PER_EVENT per integrator iteration.
CAMERA_DIMS = 2
DIMS_PER_EVENT = 24


def _mix64(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser on a uint64 array (wrapping arithmetic)."""
    z = x + _GOLDEN
    return _mix64_inplace(z)


def _mix64_inplace(z: np.ndarray) -> np.ndarray:
    """The splitmix64 finaliser without the increment, overwriting z: two buffers instead of the
    six temporaries of the plain expression (the RNG runs on every wavefront stage)."""
    tmp = np.empty_like(z)
    with np.errstate(over="ignore"):
        np.right_shift(z, _S30, out=tmp)
        z ^= tmp
        z *= _MIX1
        np.right_shift(z, _S27, out=tmp)
        z ^= tmp
        z *= _MIX2
        np.right_shift(z, _S31, out=tmp)
        z ^= tmp
    return z


_S30, _S27, _S31, _S11 = (np.uint64(k) for k in (30, 27, 31, 11))


def path_keys(seed: int, pixel: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """One 64-bit key per path from (seed, pixel index, sample index)."""
    seed_key = _mix64(np.array([seed & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64))
    with np.errstate(over="ignore"):
        k = _mix64(seed_key ^ pixel.astype(np.uint64))
        return _mix64(k ^ (sample.astype(np.uint64) * _GOLDEN))


def uniform(keys: np.ndarray, dimension) -> np.ndarray:
    """Uniform float64 in [0, 1) for each key at the given dimension (scalar or per-path array)."""
    with np.errstate(over="ignore"):
        if np.ndim(dimension) == 0:
            z = keys ^ np.uint64(int(dimension) * int(_MIX2) & 0xFFFFFFFFFFFFFFFF)
            z += _GOLDEN
        else:
            z = keys ^ (np.asarray(dimension).astype(np.uint64) * _MIX2)
            z += _GOLDEN
        _mix64_inplace(z)
        z >>= _S11
    out = z.astype(np.float64)
    out *= _INV_2_53
    return out


def uniform_block(keys: np.ndarray, dimensions) -> np.ndarray:
    """Uniforms (len(dimensions), N) for scalar dimensions, identical to uniform() per row, drawn
    in one pass (fewer numpy calls when a stage needs several dimensions for the same paths)."""
    with np.errstate(over="ignore"):
        salts = np.array([int(d) * int(_MIX2) & 0xFFFFFFFFFFFFFFFF for d in dimensions], dtype=np.uint64)
        z = keys[None, :] ^ salts[:, None]
        z += _GOLDEN
        _mix64_inplace(z)
        z >>= _S11
    out = z.astype(np.float64)
    out *= _INV_2_53
    return out


def event_dimension(event: np.ndarray, offset: int) -> np.ndarray:
    """Dimension index of `offset` within a path's integrator iteration `event`."""
    return CAMERA_DIMS + event.astype(np.int64) * DIMS_PER_EVENT + offset


# ---------------------------------------------------------------------------------------------
# Warps
# ---------------------------------------------------------------------------------------------
def orthonormal_basis(n: np.ndarray):
    """Two tangents completing unit normals n (N,3) (Duff et al. 2017, branchless)."""
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    s = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, s


def local_to_world(n: np.ndarray, x, y, z) -> np.ndarray:
    """x t + y s + z n with (t, s) of orthonormal_basis, column by column (no (N,3) temporaries:
    every scattering and light sample goes through here)."""
    n0, n1, n2 = n[:, 0], n[:, 1], n[:, 2]
    sign = np.where(n2 >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    out = np.empty((len(n), 3))
    out[:, 0] = (1.0 + sign * n0 ** 2 * a) * x + b * y + n0 * z
    out[:, 1] = sign * b * x + (sign + n1 ** 2 * a) * y + n1 * z
    out[:, 2] = -sign * n0 * x - n1 * y + n2 * z
    return out


def cosine_hemisphere(n: np.ndarray, u1: np.ndarray, u2: np.ndarray):
    """Cosine-weighted direction around unit normals n; returns (directions, cos_theta)."""
    r = np.sqrt(u1)
    phi = 2.0 * np.pi * u2
    z = np.sqrt(np.maximum(1.0 - u1, 0.0))
    return local_to_world(n, r * np.cos(phi), r * np.sin(phi), z), z


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def uniform_cone(axis: np.ndarray, cos_max, u1: np.ndarray, u2: np.ndarray):
    """Uniform direction in the cone of half-angle acos(cos_max) around unit axes."""
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    phi = 2.0 * np.pi * u2
    return local_to_world(axis, sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)


def concentric_disk(u1: np.ndarray, u2: np.ndarray):
    """Shirley-Chiu concentric map of the unit square to the unit disk; returns (x, y)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    use_a = np.abs(a) > np.abs(b)
    safe_a = np.where(a == 0.0, 1.0, a)
    safe_b = np.where(b == 0.0, 1.0, b)
    r = np.where(use_a, a, b)
    phi = np.where(use_a, (np.pi / 4) * (b / safe_a), np.pi / 2 - (np.pi / 4) * (a / safe_b))
    return r * np.cos(phi), r * np.sin(phi)


def choose_by_cdf(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Index i with cdf[i-1] <= u < cdf[i] (cdf ascending, last entry 1)."""
    return np.minimum(np.searchsorted(cdf, u, side="right"), len(cdf) - 1)


# ---------------------------------------------------------------------------------------------
# Scalar forms for the compiled kernels (one path at a time; same maps as above)
# ---------------------------------------------------------------------------------------------
@kernel
def local_to_world1(n0, n1, n2, x, y, z):
    """x t + y s + z n for one unit normal n, with the basis of orthonormal_basis."""
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
