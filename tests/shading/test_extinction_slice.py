"""extinction_program: a volume program without what only feeds a Principled Volume's Color gives
the same extinction and emission wherever that Color is <= 1 (and the density where it is not),
drops the colour's instructions and the Noise Texture's colour fBms, and refuses programs whose
extinction the Color changes otherwise (a non-black Absorption Color)."""
from __future__ import annotations

import numpy as np

from volpath_native.shading.builder import ProgramBuilder
from volpath_native.shading.extinction_slice import extinction_program
from volpath_native.shading.images import empty_image_table
from volpath_native.shading.interpreter import run_program_many
from volpath_native.shading.program import (LOBE_STRIDE, MATH, MAX_LOBES, MIX_BLEND, OPS, R_EMISSION, R_LOBES, R_P,
                                            R_SIGMA_A, TEXCO_OBJECT)
from volpath_native.shading.textures.noise import NOISE_FBM


def _noise_cloud(tint=0.9, absorption=0.0, absorption_linked=False):
    """Density = 6 x Noise Fac, Color = Mix(0.3, tint, Noise Color), emission 4 x density."""
    b = ProgramBuilder("cloud")
    p = b.alloc(3)
    b.emit("TEXCO", TEXCO_OBJECT, p)
    fac, colour = b.alloc(), b.alloc(3)
    b.emit("TEX_NOISE", 3, NOISE_FBM, 1, 1, p, b.const(0.0), b.const(2.5), b.const(3.0), b.const(0.5),
           b.const(2.0), b.const(0.0), b.const(1.0), b.const(0.0), fac, colour)
    density, strength = b.alloc(), b.alloc()
    b.emit("MATH", MATH["MULTIPLY"], fac, b.const(6.0), b.const(0.0), density)
    b.emit("MATH", MATH["MULTIPLY"], density, b.const(4.0), b.const(0.0), strength)
    mixed = b.alloc(3)
    b.emit("MIX_COLOR", MIX_BLEND["MIX"], 1, 0, b.const(0.3), b.const([tint] * 3), colour, mixed)
    absorb = b.const([absorption] * 3)
    if absorption_linked:
        absorb = b.alloc(3)
        b.emit("COPY", 3, colour, absorb)
    b.emit("PRINCIPLED_VOLUME", 0, b.const(1.0), mixed, density, b.const(0.2), absorb, strength,
           b.const([1.0, 0.4, 0.1]), b.const(0.0), b.const([1.0, 1.0, 1.0]), b.const(1000.0))
    return b.build()


def _coefficients(program, points):
    """(sigma_t (N, 3), emission (N, 3)) of the program at world points."""
    first = R_SIGMA_A
    count = R_LOBES + MAX_LOBES * LOBE_STRIDE - first
    out = np.zeros((len(points), count))
    frame = np.stack([np.eye(4)[:3], np.eye(4)[:3]])
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers), frame,
                     np.zeros((1, 1, 1, 1), np.float32), np.eye(4)[:3], np.ascontiguousarray(points), out, first, count,
                     empty_image_table())
    sigma_a = np.maximum(out[:, 0:3], 0.0)
    emission = out[:, R_EMISSION - first:R_EMISSION - first + 3]
    lobes = out[:, R_LOBES - first:].reshape(len(points), MAX_LOBES, LOBE_STRIDE)[:, :, :3].sum(axis=1)
    return sigma_a + np.maximum(lobes, 0.0), emission


def _noise_ops(program):
    pc, flags = 0, []
    by_code = {spec.code: (name, spec) for name, spec in OPS.items()}
    while pc < len(program.code):
        name, spec = by_code[int(program.code[pc])]
        if name == "TEX_NOISE":
            flags.append(int(program.code[pc + 4]))
        pc += 1 + len(spec.operands)
    return flags


POINTS = np.random.default_rng(4).uniform(-1.5, 1.5, (400, 3))


def test_the_reduced_program_keeps_extinction_and_emission():
    full = _noise_cloud()
    reduced = extinction_program(full)
    assert reduced is not None
    assert _noise_ops(full) == [1] and _noise_ops(reduced) == [0]  # the colour fBms skipped
    assert len(reduced.code) < len(full.code)  # the Mix is gone
    t_full, e_full = _coefficients(full, POINTS)
    t_reduced, e_reduced = _coefficients(reduced, POINTS)
    assert t_full.max() > 1.0
    np.testing.assert_allclose(t_reduced, t_full, rtol=1e-12, atol=1e-12)  # c + (1 - c) rounds
    np.testing.assert_array_equal(e_reduced, e_full)


def test_where_the_colour_exceeds_one_the_reduced_extinction_is_the_density():
    full = _noise_cloud(tint=3.0)  # c = 0.7 x 3 + 0.3 x noise > 1
    reduced = extinction_program(full)
    t_full, _ = _coefficients(full, POINTS)
    t_reduced, _ = _coefficients(reduced, POINTS)
    dense = t_reduced[:, 0] > 1e-6
    assert dense.sum() > 50
    assert np.all(t_full[dense] > 1.9 * t_reduced[dense])  # the difference a caller must add
    np.testing.assert_allclose(t_reduced[:, 0], t_reduced[:, 2])  # grey: the density


def test_programs_whose_colour_reaches_the_extinction_otherwise_are_not_sliced():
    assert extinction_program(_noise_cloud(absorption=0.5)) is None
    assert extinction_program(_noise_cloud(absorption_linked=True)) is None
