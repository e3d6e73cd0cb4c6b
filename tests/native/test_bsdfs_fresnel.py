"""Fresnel terms (bsdfs/fresnel.py) against closed forms: normal incidence, grazing incidence,
Brewster's angle, total internal reflection, the conductor's k = 0 limit, F82-tint's defining
points, and the average-Fresnel fits against quadrature."""
import numpy as np
import pytest

from volpath_native.bsdfs.fresnel import (FRESNEL_NONE, F0_from_ior, closure_fresnel, conductor_Fss,
                                          f82_Fss, f82_tint_b, fresnel_conductor, fresnel_dielectric,
                                          fresnel_dielectric_Fss, fresnel_f82, ior_from_F0, schlick_remap_s)

ETAS = [1.1, 1.33, 1.5, 2.4, 1 / 1.5, 1 / 2.4]
GOLD_N, GOLD_K = (0.143, 0.374, 1.442), (3.983, 2.385, 1.603)


def _integral_2mu(f, n=400):
    x, w = np.polynomial.legendre.leggauss(n)
    mu = 0.5 * (x + 1)
    return float(np.sum(0.5 * w * 2 * mu * np.array([f(m) for m in mu])))


@pytest.mark.parametrize("eta", ETAS)
def test_dielectric_normal_and_grazing_incidence(eta):
    F, cos_t = fresnel_dielectric(1.0, eta)
    assert F == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-12)
    assert cos_t == pytest.approx(-1.0, abs=1e-12)  # straight through, on the other side
    assert fresnel_dielectric(1e-9, eta)[0] > 1 - 1e-6  # grazing: a mirror


@pytest.mark.parametrize("eta", [1.33, 1.5, 2.4])
def test_dielectric_brewster_angle(eta):
    """At tan(theta) = eta the p-polarised reflection vanishes: F = rs^2 / 2 = sin^2(ti - tt) / 2."""
    ti = np.arctan(eta)
    tt = np.arcsin(np.sin(ti) / eta)
    assert fresnel_dielectric(np.cos(ti), eta)[0] == pytest.approx(0.5 * np.sin(ti - tt) ** 2, rel=1e-10)


@pytest.mark.parametrize("eta", [1 / 1.33, 1 / 1.5, 1 / 2.4])
def test_total_internal_reflection(eta):
    cos_critical = np.sqrt(1 - eta * eta)
    for c in [0.0, 0.5 * cos_critical, cos_critical * (1 - 1e-9)]:
        assert fresnel_dielectric(c, eta) == (1.0, 0.0)
    F, cos_t = fresnel_dielectric(cos_critical * 1.001, eta)
    assert F < 1.0 and cos_t < 0.0
    # Snell: sin_t = sin_i / eta
    c = 0.99
    F, cos_t = fresnel_dielectric(c, eta)
    assert np.sqrt(1 - cos_t ** 2) == pytest.approx(np.sqrt(1 - c * c) / eta, rel=1e-12)
    # a refraction-only closure transmits nothing on TIR, reflects nothing ever
    one, zero = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
    r, t, _ = closure_fresnel(FRESNEL_NONE, False, True, eta, 0.1 * cos_critical, zero, one, zero, one, one, zero,
                              zero)
    assert r == zero and t == zero
    r, t, _ = closure_fresnel(FRESNEL_NONE, False, True, eta, 0.99, zero, one, zero, one, one, zero, zero)
    assert t == one


@pytest.mark.parametrize("n", [1.2, 1.5, 2.0])
def test_conductor_reduces_to_dielectric_without_absorption(n):
    for c in [1.0, 0.8, 0.4, 0.1]:
        assert fresnel_conductor(c, (n, n, n), (0.0, 0.0, 0.0))[0] == pytest.approx(fresnel_dielectric(c, n)[0],
                                                                                     rel=1e-12)


def test_conductor_normal_and_grazing_incidence():
    F = fresnel_conductor(1.0, GOLD_N, GOLD_K)
    for c in range(3):
        n, k = GOLD_N[c], GOLD_K[c]
        assert F[c] == pytest.approx(((n - 1) ** 2 + k * k) / ((n + 1) ** 2 + k * k), rel=1e-12)
    assert min(fresnel_conductor(1e-9, GOLD_N, GOLD_K)) > 1 - 1e-6


def test_f82_tint_defining_points():
    f0, tint = (0.9, 0.6, 0.2), (0.7, 0.9, 1.2)
    b = f82_tint_b(f0, tint)
    assert fresnel_f82(1.0, f0, b) == pytest.approx(f0, rel=1e-12)
    assert fresnel_f82(0.0, f0, b) == pytest.approx((1.0, 1.0, 1.0))
    c = 1 / 7
    schlick = [f + (1 - f) * (1 - c) ** 5 for f in f0]
    expected = [min(max(s * t, 0.0), 1.0) for s, t in zip(schlick, tint)]
    assert fresnel_f82(c, f0, b) == pytest.approx(expected, rel=1e-10)
    assert f82_tint_b(f0, (1.0, 1.0, 1.0)) == (0.0, 0.0, 0.0)
    # 2 int F mu dmu has the closed form mix(f0, 1, 1/21) - b/126 (no clamping active here)
    for ch in range(3):
        assert f82_Fss(f0, b)[ch] == pytest.approx(_integral_2mu(lambda m: fresnel_f82(m, f0, b)[ch]), abs=1e-9)


@pytest.mark.parametrize("eta", [1.05, 1.33, 1.5, 2.0, 1 / 1.33, 1 / 1.5])
def test_dielectric_average_fit(eta):
    """Kulla & Conty's fit of 2 int F mu dmu (what Cycles uses) is within 6e-3 of quadrature."""
    exact = _integral_2mu(lambda m: fresnel_dielectric(m, eta)[0])
    assert abs(fresnel_dielectric_Fss(eta) - exact) < 6e-3, exact


def test_conductor_average_is_its_f82_fit():
    exact = [_integral_2mu(lambda m: fresnel_conductor(m, GOLD_N, GOLD_K)[c]) for c in range(3)]
    assert np.allclose(conductor_Fss(GOLD_N, GOLD_K), exact, atol=0.02), exact


def test_generalized_schlick_remap():
    for eta in [1.5, 1 / 1.5]:
        for c in [1.0, 0.7, 0.3, 0.05]:
            s, _ = schlick_remap_s(c, eta)
            F = fresnel_dielectric(c, eta)[0]
            f0 = F0_from_ior(eta)
            assert f0 + (1 - f0) * s == pytest.approx(F, abs=1e-12)  # f0 = F0(eta), f90 = 1: the real curve
    assert schlick_remap_s(0.1, 1 / 1.5)[0] == 1.0  # TIR -> f90
    for f0 in [0.0, 0.04, 0.5, 0.9]:
        assert F0_from_ior(ior_from_F0(f0)) == pytest.approx(f0, abs=1e-12)


def test_planted_fresnel_error_is_caught():
    """The closed-form comparison above can fail: a 3 % error in eta moves F0 by far more than its
    tolerance."""
    F = fresnel_dielectric(1.0, 1.5 * 1.03)[0]
    assert F != pytest.approx(((1.5 - 1) / (1.5 + 1)) ** 2, rel=1e-6)
