"""The texture opcodes through the interpreter: operand order and outputs of every TEX_* op equal
the direct function's at random points (the functions themselves are checked against Cycles by the
test_*_texture.py oracle tests)."""
from __future__ import annotations

import numpy as np
import pytest

from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.interpreter import run_program_many
from volpath_native.shading.images import empty_image_table
from volpath_native.shading.textures.gradient import gradient_texture
from volpath_native.shading.textures.magic import magic_texture
from volpath_native.shading.textures.noise import NOISE_HETERO_TERRAIN, noise_texture
from volpath_native.shading.textures.voronoi import VORONOI_F2, VORONOI_MINKOWSKI, voronoi_texture
from volpath_native.shading.textures.wave import WAVE_PROFILE_TRI, WAVE_RINGS, wave_texture
from volpath_native.shading.textures.white_noise import white_noise_texture

POINTS = np.random.default_rng(3).uniform(-2.0, 2.0, (40, 3))


def run(builder, first, count):
    program = builder.build()
    regs = np.zeros(program.n_registers)
    out = np.zeros((len(POINTS), count))
    run_program_many(program.code, program.init, program.tables, regs, np.zeros((2, 3, 4)),
                     np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)), POINTS, out, first, count,
                     empty_image_table())
    return out


def direct(function, arguments):
    return np.array([function(*arguments(p)) for p in POINTS], np.float64).reshape(len(POINTS), -1)


def test_noise_op():
    b = ProgramBuilder("noise")
    params = (0.7, 2.5, 3.3, 0.6, 2.1, 0.4, 1.7, 0.9)  # w scale detail roughness lacunarity offset gain distortion
    regs = [b.const(v) for v in params]
    out = b.alloc(4)
    b.emit("TEX_NOISE", 4, NOISE_HETERO_TERRAIN, 0, 1, P.R_P, *regs, out, out + 1)
    ours = run(b, out, 4)
    expected = direct(noise_texture, lambda p: (4, NOISE_HETERO_TERRAIN, False, True, p[0], p[1], p[2], *params))
    np.testing.assert_array_equal(ours, expected)


def test_voronoi_op():
    b = ProgramBuilder("voronoi")
    params = (0.3, 1.9, 1.5, 0.7, 2.2, 0.5, 1.3, 0.8)  # w scale detail roughness lacunarity smoothness exponent rand
    regs = [b.const(v) for v in params]
    out = b.alloc(9)
    b.emit("TEX_VORONOI", 3, VORONOI_F2, VORONOI_MINKOWSKI, 1, P.R_P, *regs, out, out + 1, out + 4, out + 7, out + 8)
    ours = run(b, out, 9)
    expected = direct(voronoi_texture, lambda p: (3, VORONOI_F2, VORONOI_MINKOWSKI, True, p[0], p[1], p[2], *params))
    np.testing.assert_array_equal(ours, expected)


@pytest.mark.parametrize("name", ["gradient", "wave", "magic", "white_noise"])
def test_simple_ops(name):
    b = ProgramBuilder(name)
    out = b.alloc(4)
    if name == "gradient":
        b.emit("TEX_GRADIENT", 4, P.R_P, out, out + 1)
        expected = direct(lambda *a: (gradient_texture(*a),) * 4, lambda p: (4, p[0], p[1], p[2]))
    elif name == "wave":
        params = (3.0, 2.0, 4.5, 1.5, 0.6, 0.3)  # scale distortion detail detail_scale roughness phase
        b.emit("TEX_WAVE", WAVE_RINGS, 3, WAVE_PROFILE_TRI, P.R_P, *[b.const(v) for v in params], out, out + 1)
        expected = direct(lambda *a: (wave_texture(*a),) * 4, lambda p: (WAVE_RINGS, 3, WAVE_PROFILE_TRI, *p, *params))
    elif name == "magic":
        b.emit("TEX_MAGIC", 5, P.R_P, b.const(2.5), b.const(1.7), out, out + 1)
        expected = direct(magic_texture, lambda p: (5, p[0], p[1], p[2], 2.5, 1.7))
    else:
        b.emit("TEX_WHITE_NOISE", 4, 1, P.R_P, b.const(0.25), out, out + 1)
        expected = direct(white_noise_texture, lambda p: (4, True, p[0], p[1], p[2], 0.25))
    np.testing.assert_array_equal(run(b, out, 4), expected)
