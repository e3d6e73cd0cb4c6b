"""telescoping_transmittance (Cycles 5.0's shadow-ray estimator for heterogeneous volumes, Misso et
al. 2022) on shader-program media: unbiased against quadrature of the program, exact where the
density is constant, and planted errors (a wrong density, the biased T_k without its debiasing
term) must fail."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from volpath_native.grid_kernels import FLAG_LOOKUPS
from volpath_native.program_medium import ProgramMedium
from volpath_native.telescoping_transmittance import telescoping_many

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "native"))
from native_helpers import Z_LIMIT  # noqa: E402
from test_program_medium import _rays, object_matrix, quadrature_depth, wavy_program  # noqa: E402

T_MAX = 8.0


@pytest.fixture(scope="module")
def medium():
    return ProgramMedium("wavy", wavy_program(), object_matrix(), ([-1, -1, -1], [1, 1, 1]))


def _estimates(medium, o, d, n, seed, debias=True):
    tables = medium._call_tables()
    keys = (np.arange(n, dtype=np.uint64) + np.uint64(seed * 1_000_003)) * np.uint64(0x9E3779B97F4A7C15)
    out = np.empty((n, 3))
    telescoping_many(tables, np.repeat(o[None], n, 0), np.repeat(d[None], n, 0), np.full(n, T_MAX), keys, 0, out,
                     debias)
    return out, tables.flags[FLAG_LOOKUPS + 1] / n


def _z(medium, reference, n=20000, seed=3, debias=True):
    origins, dirs = _rays()
    zs = []
    for o, d, ref in zip(origins, dirs, reference):
        estimates = _estimates(medium, o, d, n, seed, debias)[0][:, 0]
        zs.append((estimates.mean() - ref) / (estimates.std() / np.sqrt(n) + 1e-12))
    return np.array(zs)


def test_matches_quadrature_and_planted_errors_fail(medium):
    origins, dirs = _rays()
    depth = quadrature_depth(medium, origins, dirs, T_MAX)
    assert np.all(depth > 0.5)
    z = _z(medium, np.exp(-depth))
    assert np.all(np.abs(z) < Z_LIMIT), z
    planted = _z(medium, np.exp(-1.08 * depth))  # the density 8 % off
    assert np.max(np.abs(planted)) > Z_LIMIT, planted
    biased = _z(medium, np.exp(-depth), debias=False)  # T_k alone: Jensen's bias, exp(-E[tau]) <= E[exp(-tau)]
    assert np.max(biased) > Z_LIMIT, biased


def test_constant_density_is_exact_with_one_lookup_per_segment():
    """The control is the density itself: every estimate is exp(-integral of the control)."""
    flat = ProgramMedium("flat", wavy_program(constant=True), object_matrix(), ([-1, -1, -1], [1, 1, 1]))
    origins, dirs = _rays()
    depth = quadrature_depth(flat, origins, dirs, T_MAX)
    for o, d, tau in zip(origins, dirs, depth):
        estimates, lookups = _estimates(flat, o, d, 200, seed=1)
        assert np.allclose(estimates, np.exp(-tau), rtol=1e-9, atol=0.0), (estimates[:3], np.exp(-tau))
        assert lookups >= 1.0  # range 0: the whole ray is one segment of k = 1 (x the debiasing order's 2^n)


def test_infinite_density_is_opaque_and_counted():
    from volpath_native.grid_kernels import FLAG_BUDGET
    dense = ProgramMedium("dense", wavy_program(), object_matrix(), ([-1, -1, -1], [1, 1, 1]))
    dense.extinction_extrema[..., 1] = np.inf  # in place: the kernels read this array
    origins, dirs = _rays()
    tables = dense._call_tables()
    out = np.empty((3, 3))
    telescoping_many(tables, origins, dirs, np.full(3, T_MAX), np.arange(3, dtype=np.uint64), 0, out)
    assert np.all(out == 0.0)
    assert tables.flags[FLAG_BUDGET] == 3
