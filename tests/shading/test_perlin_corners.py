"""The vectorised Perlin corners (perlin_corners.py: the 8 corners' lookup3 hashes and gradients
as 8-lane LLVM code) equal the scalar hash_uint3/grad3 and hash_uint4/grad4, corner by corner and
bit for bit, compiled against uncompiled, on lattice values that wrap 32 bits; and compiled
perlin_3d (a float32 cell, as Cycles' SSE path) equals its uncompiled float32 version bit for bit
and the float64 scalar corners within rounding. Against Cycles, Noise
Texture agreement is checked in test_noise_texture.py."""
from __future__ import annotations

import numba
import numpy as np

from volpath_native.shading.textures import perlin
from volpath_native.shading.textures.hash import hash_uint3
from volpath_native.shading.textures.perlin_corners import (corner_gradients_3d, corner_gradients_4d,
                                                              perlin_cell_3d)

RNG = np.random.default_rng(5)
EDGE = [0, 1, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF]


def _lattices(count):
    """(X0, X1, Y0, Y1, Z0, Z1, W) as the masked uint32 patterns perlin passes (X1 = X0 + 1 wraps)."""
    rows = []
    for k in range(count):
        base = [int(v) for v in RNG.integers(0, 2**32, 4)] if k >= len(EDGE) else [EDGE[k]] * 4
        x, y, z, w = base
        rows.append((x, (x + 1) & 0xFFFFFFFF, y, (y + 1) & 0xFFFFFFFF, z, (z + 1) & 0xFFFFFFFF, w))
    return rows


@numba.njit(cache=False)
def _compiled_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    return corner_gradients_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz)


@numba.njit(cache=False)
def _compiled_4d(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw):
    return corner_gradients_4d(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw)


def test_corners_3d_equal_scalar_hash_and_gradient():
    for lattice in _lattices(200):
        fx, fy, fz = (float(v) for v in RNG.random(3))
        assert _compiled_3d(*lattice[:6], fx, fy, fz) == corner_gradients_3d(*lattice[:6], fx, fy, fz), lattice


def test_corners_4d_equal_scalar_hash_and_gradient():
    for lattice in _lattices(200):
        fx, fy, fz, fw = (float(v) for v in RNG.random(4))
        assert _compiled_4d(*lattice, fx, fy, fz, fw) == corner_gradients_4d(*lattice, fx, fy, fz, fw), lattice


def test_every_corner_differs_from_its_neighbours():
    """A corner order mixed up in both paths alike would pass the tests above; the corners of one
    cell are distinct hashes, so swapping two changes the gradient set's order (planted below)."""
    values = _compiled_3d(*_lattices(10)[7][:6], 0.3, 0.6, 0.2)
    assert len(set(values)) > 4
    swapped = (values[1], values[0]) + values[2:]
    assert swapped != corner_gradients_3d(*_lattices(10)[7][:6], 0.3, 0.6, 0.2)


@numba.njit(cache=False)
def _scalar_perlin_3d(x, y, z):
    """perlin_3d with the corners hashed one by one (the code before perlin_corners)."""
    X, fx = perlin.floorfrac(x)
    Y, fy = perlin.floorfrac(y)
    Z, fz = perlin.floorfrac(z)
    u, v, w = perlin.fade(fx), perlin.fade(fy), perlin.fade(fz)
    values = []
    for i in range(8):
        cx, cy, cz = X + (i & 1), Y + ((i >> 1) & 1), Z + ((i >> 2) & 1)
        values.append(perlin.grad3(hash_uint3(cx & 0xFFFFFFFF, cy & 0xFFFFFFFF, cz & 0xFFFFFFFF),
                                   fx - (i & 1), fy - ((i >> 1) & 1), fz - ((i >> 2) & 1)))
    v0, v1, v2, v3, v4, v5, v6, v7 = values
    u1, v_1, w1 = 1.0 - u, 1.0 - v, 1.0 - w
    return (w1 * (v_1 * (v0 * u1 + v1 * u) + v * (v2 * u1 + v3 * u))
            + w * (v_1 * (v4 * u1 + v5 * u) + v * (v6 * u1 + v7 * u)))


def test_perlin_3d_equals_its_uncompiled_float32_cell():
    """Bit for bit: the compiled vector cell (perlin_cell_3d) and the uncompiled float32 one."""
    points = np.concatenate([RNG.normal(0, 50, (500, 3)), RNG.uniform(-1e5, 1e5, (100, 3))]).astype(np.float32)
    for p in points:
        args = [float(v) for v in p]
        assert perlin.perlin_3d(*args) == perlin.perlin_3d.py_func(*args), args


def test_perlin_3d_float32_is_within_rounding_of_float64():
    """The float32 cell (Cycles' own precision) against the float64 scalar corners: a few ulps."""
    points = RNG.normal(0, 50, (2000, 3)).astype(np.float32)
    worst = max(abs(perlin.perlin_3d(*map(float, p)) - _scalar_perlin_3d(*map(float, p))) for p in points)
    assert worst < 2e-6, worst


def test_planted_corner_order_error_in_the_cell_is_caught():
    """Swapping the y and z far corners in the float32 cell must change values."""
    args = (7, 8, 11, 12, 13, 14, 0.3, 0.6, 0.2)
    real = perlin_cell_3d(*args)
    assert perlin_cell_3d(7, 8, 13, 14, 11, 12, 0.3, 0.2, 0.6) != real


def test_fbm_octave_groups_sum_as_the_loop():
    # noise.fbm runs 3D octaves four at a time as straight-line code; its value must be the loop's
    # (fractal_noise.h noise_fbm: octave by octave, fscale *= lacunarity in float32) bit for bit
    from volpath_native.shading.textures.noise import fbm

    def loop_fbm(x, y, z, detail, roughness, lacunarity):
        fscale, amp, maxamp, total = np.float32(1.0), 1.0, 0.0, 0.0
        for _ in range(int(detail) + 1):
            total += perlin.snoise_3d(fscale * x, fscale * y, fscale * z) * amp
            maxamp += amp
            amp *= roughness
            fscale = np.float32(fscale * lacunarity)
        rmd = detail - np.floor(detail)
        if rmd != 0.0:
            t = perlin.snoise_3d(fscale * x, fscale * y, fscale * z)
            a = 0.5 * total / maxamp + 0.5
            return a + rmd * ((0.5 * (total + t * amp) / (maxamp + amp) + 0.5) - a)
        return 0.5 * total / maxamp + 0.5

    points = RNG.uniform(-40, 40, (40, 3)).astype(np.float32)
    for detail in (0.0, 2.5, 3.0, 3.7, 7.0, 8.25, 15.0):
        for roughness, lacunarity in ((0.5, np.float32(2.0)), (0.8, np.float32(1.7))):
            for x, y, z in points:
                got = fbm(3, x, y, z, np.float32(0.0), detail, roughness, lacunarity, True)
                assert got == loop_fbm(x, y, z, detail, roughness, lacunarity), (detail, roughness, x, y, z)
