"""The hash functions compiled and uncompiled agree (int64 wrap vs Python ints: the planted-error
tests run them uncompiled), on random and extreme inputs; every texture survives non-finite and
huge inputs without hanging or crashing. Against Cycles the hashes are checked bit for bit through
White Noise (test_simple_textures.py) and Voronoi's PCG cells (test_voronoi_texture.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from volpath_native.shading.textures import hash as H
from volpath_native.shading.textures.gradient import gradient_texture
from volpath_native.shading.textures.magic import magic_texture
from volpath_native.shading.textures.noise import noise_texture
from volpath_native.shading.textures.voronoi import voronoi_texture
from volpath_native.shading.textures.wave import wave_texture
from volpath_native.shading.textures.white_noise import white_noise_texture

RNG = np.random.default_rng(11)
UINTS = [0, 1, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF] + [int(v) for v in RNG.integers(0, 2**32, 20)]
INTS = [0, 1, -1, 2**31 - 1, -2**31] + [int(v) for v in RNG.integers(-2**31, 2**31, 20)]
FLOATS = [0.0, -0.0, 1.0, -1.5, 1e-45, 3.4e38, math.inf, -math.inf, 1e6 + 0.5] + list(RNG.normal(0, 100, 10))


@pytest.mark.parametrize("name, arity, values", [("hash_uint", 1, UINTS), ("hash_uint2", 2, UINTS),
                                                 ("hash_uint3", 3, UINTS), ("hash_uint4", 4, UINTS),
                                                 ("hash_pcg2d_i", 2, INTS), ("hash_pcg3d_i", 3, INTS),
                                                 ("hash_pcg4d_i", 4, INTS), ("float32_bits", 1, FLOATS)])
def test_compiled_equals_uncompiled(name, arity, values):
    compiled = getattr(H, name)
    for k in range(len(values)):
        args = [values[(k + a * 7) % len(values)] for a in range(arity)]
        assert compiled(*args) == compiled.py_func(*args), (name, args)


def test_float32_bits_matches_numpy():
    for f in FLOATS:
        assert H.float32_bits(f) == int(np.array(f, np.float32).view(np.uint32)), f


def test_uint_to_float_rounds_to_float32():
    """(float)0xFFFFFFFF rounds to 2^32: the maximum hash maps to exactly 1.0."""
    assert H.uint_to_float_incl(0xFFFFFFFF) == 1.0
    assert H.uint_to_float_incl(0xFFFFFF7F) == float(np.float32(0xFFFFFF7F)) * 2.0 ** -32


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 3.0e38, -1.0e30])
def test_textures_survive_extreme_inputs(value):
    """No crash or hang on non-finite or huge coordinates (Cycles' own results there are NaN or
    arbitrary; the interpreter's closure read-out maps NaN coefficients to 0)."""
    for dims in (1, 2, 3, 4):
        noise_texture(dims, 1, True, True, value, value, value, value, 5.0, 15.0, 0.5, 2.0, 0.0, 1.0, 1.0)
        for feature in range(5):
            voronoi_texture(dims, feature, 0, True, value, value, value, value, 5.0, 15.0, 0.5, 2.0, 1.0, 0.5, 1.0)
        white_noise_texture(dims, True, value, value, value, value)
    gradient_texture(4, value, value, value)
    wave_texture(1, 3, 2, value, value, value, 5.0, 2.0, 1.0e9, 1.0, 0.5, 0.0)
    magic_texture(10, value, value, value, 5.0, 1.0)
