"""Henyey-Greenstein sampling matches its analytic pdf (chi-square), forward for g > 0. hg_sample /
hg_eval are loops over the scalar kernels hg_sample1 / hg_eval1 that the compiled stages call."""
import numpy as np
import pytest

from volpath_native.phase import hg_eval, hg_sample

from native_helpers import chi2_critical


def tangents(axis):
    """Two unit vectors completing the unit axis to an orthonormal basis (for azimuth bins)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t = np.cross(axis, helper)
    t /= np.linalg.norm(t)
    return t, np.cross(axis, t)


def _hg_cdf(g, mu):
    """Analytic CDF of cos(theta) under HG (integral of 2 pi p(mu) dmu from -1)."""
    if abs(g) < 1e-6:
        return (mu + 1) / 2
    return (1 - g * g) / (2 * g) * (1 / np.sqrt(1 + g * g - 2 * g * mu) - 1 / (1 + g))


@pytest.mark.parametrize("g", [-0.7, 0.0, 0.3, 0.9])
def test_hg_sampling_chi_square(g):
    rng = np.random.default_rng(42)
    n = 200_000
    axis = np.array([0.3, -0.5, 0.81])
    axis /= np.linalg.norm(axis)
    d = np.tile(axis, (n, 1))
    wo, pdf = hg_sample(d, np.full(n, g), rng.random(n), rng.random(n))
    np.testing.assert_allclose(np.linalg.norm(wo, axis=1), 1.0, atol=1e-9)
    mu = wo @ axis
    np.testing.assert_allclose(pdf, hg_eval(g, mu), rtol=1e-9)
    # 2D binning: 16 bins in mu with equal probability, 8 in azimuth
    edges_p = np.linspace(0, 1, 17)
    grid = np.linspace(-1, 1, 200_001)
    cdf = _hg_cdf(g, grid)
    mu_edges = np.interp(edges_p, cdf / cdf[-1], grid)
    t, s = tangents(axis)
    phi = np.arctan2(wo @ s, wo @ t)
    counts, _, _ = np.histogram2d(mu, phi, bins=[mu_edges, np.linspace(-np.pi, np.pi, 9)])
    expected = n / counts.size
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert chi2 < chi2_critical(counts.size - 1), chi2
    if g > 0:
        assert mu.mean() > 0
    # the analytic pdf integrates to 1 and its mean cosine is g
    w = 2 * np.pi * hg_eval(g, grid)
    assert abs(np.trapz(w, grid) - 1) < 1e-3
    assert abs(np.trapz(w * grid, grid) - g) < 1e-3


def test_hg_chi_square_detects_a_wrong_sign():
    """The test above can fail: samples of g = 0.3 do not pass as g = -0.3."""
    rng = np.random.default_rng(7)
    n = 200_000
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    wo, _ = hg_sample(d, np.full(n, 0.3), rng.random(n), rng.random(n))
    mu_edges = np.interp(np.linspace(0, 1, 17), _hg_cdf(-0.3, np.linspace(-1, 1, 20001)), np.linspace(-1, 1, 20001))
    counts, _ = np.histogram(wo[:, 2], bins=mu_edges)
    chi2 = ((counts - n / 16) ** 2 / (n / 16)).sum()
    assert chi2 > chi2_critical(15)
