"""Microfacet distributions and the microfacet closure (bsdfs/microfacet.py): D is normalised
(int D cos = 1), the visible-normal distribution G1 (wi.h) D / cos_i integrates to 1 (so Lambda is
the exact Smith function), reflection lobes are reciprocal, and the deviations from Cycles we chose
are measured (Beckmann's exact Lambda vs Cycles' rational fit; rough-glass pairs whose microfacet
faces away, which Cycles evaluates and never samples)."""
import math

import numpy as np
import pytest

from volpath_native.bsdfs.fresnel import (FRESNEL_CONDUCTOR, FRESNEL_DIELECTRIC, FRESNEL_F82_TINT, FRESNEL_NONE,
                                          f82_tint_b)
from volpath_native.bsdfs.batch import distribution_many, microfacet_eval_many
from volpath_native.bsdfs.microfacet import BECKMANN, GGX, lambda_aniso, lambda_from_sq_alpha_tan, microfacet_eval

from bsdf_helpers import direction

ONE, ZERO = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
X, Y, N = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _hemisphere_grid(n_z=600, n_phi=256, power=3):
    """Quadrature nodes on the upper hemisphere, dense toward the pole (z = 1 - t^power)."""
    x, w = np.polynomial.legendre.leggauss(n_z)
    t = 0.5 * (x + 1)
    z = 1 - t ** power
    wz = 0.5 * w * power * t ** (power - 1)
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    Z, P = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(np.clip(1 - Z * Z, 0, None))
    return np.stack([r * np.cos(P), r * np.sin(P), Z], -1), wz[:, None] * (2 * np.pi / n_phi)


def _D(dist, ax, ay, h):
    out = np.empty(h.shape[:-1]).reshape(-1)
    distribution_many(dist, ax, ay, np.ascontiguousarray(h.reshape(-1, 3)), out)
    return out.reshape(h.shape[:-1])


CASES = [(GGX, 0.1, 0.1), (GGX, 0.5, 0.5), (GGX, 1.0, 1.0), (GGX, 0.15, 0.6),
         (BECKMANN, 0.1, 0.1), (BECKMANN, 0.5, 0.5), (BECKMANN, 0.9, 0.9), (BECKMANN, 0.6, 0.2)]


@pytest.mark.parametrize("dist,ax,ay", CASES)
def test_distribution_is_normalised(dist, ax, ay):
    h, w = _hemisphere_grid()
    d = _D(dist, ax, ay, h)
    assert np.sum(d * h[..., 2] * w) == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("dist,ax,ay", CASES)
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_visible_normals_are_normalised(dist, ax, ay, theta):
    """int G1(wi) max(0, wi.h) D(h) / cos_i dh = 1 holds only for the exact Smith Lambda."""
    wi = direction(theta, 30.0)
    h, w = _hemisphere_grid()
    d = _D(dist, ax, ay, h)
    lam = lambda_aniso(dist, ax, ay, tuple(wi))
    vis = np.maximum(h @ wi, 0) * d / wi[2] / (1 + lam)
    assert np.sum(vis * w) == pytest.approx(1.0, abs=3e-3)


def _eval(dist, ax, ay, ior, wi, wo, fresnel=FRESNEL_NONE, f0=ZERO, b=ZERO, cn=ZERO, ck=ZERO):
    return microfacet_eval(dist, True, False, ax, ay, ior, X, Y, N, tuple(wi), tuple(wo), fresnel, f0, ONE, b,
                           ONE, ONE, cn, ck)


@pytest.mark.parametrize("dist,ax,ay", CASES)
@pytest.mark.parametrize("fresnel", [FRESNEL_NONE, FRESNEL_DIELECTRIC, FRESNEL_F82_TINT, FRESNEL_CONDUCTOR])
def test_reflection_is_reciprocal(dist, ax, ay, fresnel):
    """f(wi, wo) = f(wo, wi), with f = eval / cos_o (single scattering; the Multiscatter-GGX scale
    depends on wi and is not reciprocal, in Cycles either)."""
    rng = np.random.default_rng(5)
    f0 = (0.9, 0.5, 0.2)
    b = f82_tint_b(f0, (0.6, 0.8, 1.0))
    for _ in range(40):
        wi = direction(rng.uniform(0, 88), rng.uniform(0, 360))
        wo = direction(rng.uniform(0, 88), rng.uniform(0, 360))
        args = dict(fresnel=fresnel, f0=f0, b=b, cn=(0.2, 0.5, 1.4), ck=(3.9, 2.4, 1.6))
        fa, _ = _eval(dist, ax, ay, 1.5, wi, wo, **args)
        fb, _ = _eval(dist, ax, ay, 1.5, wo, wi, **args)
        np.testing.assert_allclose(np.array(fa) / wo[2], np.array(fb) / wi[2], rtol=1e-9, atol=1e-14)


def test_beckmann_lambda_versus_cycles_rational_fit():
    """Cycles uses Walter et al.'s rational fit of Beckmann's Lambda; we keep the exact function so
    the pdf matches the sampler. Their masking terms G1 differ by less than 0.4 %."""
    worst = 0.0
    for s in np.geomspace(1e-3, 1e3, 400):  # s = alpha^2 tan^2
        a = 1 / math.sqrt(s)
        fit = 0.0 if a >= 1.6 else (1 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)
        exact = lambda_from_sq_alpha_tan(BECKMANN, s)
        worst = max(worst, abs(1 / (1 + exact) - 1 / (1 + fit)) * (1 + exact))
    assert 1e-4 < worst < 4e-3, worst


def _glass_transmission(alpha, eta, wi, valid_only):
    """int over the lower hemisphere of the GGX glass eval (exact dielectric Fresnel): ours, or
    Cycles' formula without the check that the microfacet faces both directions."""
    x, w = np.polynomial.legendre.leggauss(300)
    z = -(x + 1) / 2
    phi = (np.arange(192) + 0.5) * 2 * np.pi / 192
    Z, P = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1 - Z * Z)
    wo = np.stack([r * np.cos(P), r * np.sin(P), Z], -1)
    W = (w / 2)[:, None] * (2 * np.pi / 192)
    if valid_only:
        flat = np.ascontiguousarray(wo.reshape(-1, 3))
        f, pdf = np.empty((len(flat), 3)), np.empty(len(flat))
        microfacet_eval_many(GGX, True, True, alpha, alpha, eta, tuple(wi), flat, FRESNEL_DIELECTRIC, ZERO, ONE,
                             ZERO, ONE, ONE, ZERO, ZERO, f, pdf)
        ev = f[:, 0].reshape(Z.shape)
        return float(np.sum(ev * W))
    a2 = alpha * alpha
    hu = -(eta * wo + wi)
    lh = np.linalg.norm(hu, axis=-1)
    h = hu / lh[..., None]
    chi, cho = h @ wi, np.einsum("...i,...i", h, wo)
    g2 = eta * eta - 1 + chi * chi
    c = np.abs(chi)
    g = np.sqrt(np.clip(g2, 0, None))
    F = np.where(g2 > 0, 0.5 * (((c - g) / (c + g)) ** 2 + ((eta * eta * c - g) / (eta * eta * c + g)) ** 2), 1.0)
    D = a2 / (np.pi * ((1 - h[..., 2] ** 2) + a2 * h[..., 2] ** 2) ** 2)
    lam = lambda v: 0.5 * (np.sqrt(1 + a2 * np.maximum(1 / v ** 2 - 1, 0)) - 1)
    ev = (1 - F) * D / wi[2] * eta * eta / lh ** 2 * np.abs(chi * cho) / (1 + lam(wi[2]) + lam(Z))
    return float(np.sum(ev * W))


def test_rough_glass_pairs_cycles_evaluates_but_never_samples():
    """Cycles 5.0 evaluates rough transmission for pairs whose generalized half vector faces away
    from wi or wo (a TODO in bsdf_microfacet_eval); its sampler never produces them, so that energy
    reaches images only through light sampling. We reject them. Measured: roughness 0.5 adds 1.5 %
    (normal incidence) to 15 % (75 deg) of albedo entering ior 1.5; roughness 1 up to ~58 %."""
    wi = direction(45.0)
    ours = _glass_transmission(0.25, 1.5, wi, True)
    cycles = _glass_transmission(0.25, 1.5, wi, False)
    assert 0.02 < cycles - ours < 0.05, (ours, cycles)
    wi = direction(0.0)
    assert 0.005 < _glass_transmission(0.25, 1.5, wi, False) - _glass_transmission(0.25, 1.5, wi, True) < 0.03
