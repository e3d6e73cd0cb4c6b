"""surface_sample against surface_eval for every lobe family (Mitsuba 3's chi-square test, see
bsdf_helpers.chi2_test): the sampled directions follow the pdf, the pdf integrates to the fraction
of samples that are neither rejected nor deltas, and each sample's weight is eval / pdf. Planted
errors (a 3 % pdf error on one side, a 3 % roughness error) must be rejected."""
import numpy as np
import pytest

from volpath_native.bsdfs import LABEL_SINGULAR, LABEL_TRANSPARENT, SurfaceNode as S
from volpath_native.bsdfs.batch import Hit

from bsdf_helpers import chi2_test, direction

TANGENT = (0.6, 0.8, 0.0)
CASES = {
    "lambert": (S.for_kind("diffuse"), 40, False),
    "oren_nayar": (S.for_kind("diffuse", roughness=0.8, color=(0.9, 0.5, 0.2)), 40, False),
    "translucent": (S.for_kind("translucent"), 40, False),
    "ggx": (S.for_kind("glossy", distribution="ggx", roughness=0.5), 50, False),
    "ggx_anisotropic": (S.for_kind("glossy", distribution="ggx", roughness=0.5, anisotropic=0.6), 50, False),
    "multi_ggx_coloured": (S.for_kind("glossy", roughness=0.7, color=(0.9, 0.4, 0.1)), 70, False),
    "beckmann": (S.for_kind("glossy", distribution="beckmann", roughness=0.5), 50, False),
    "beckmann_anisotropic": (S.for_kind("glossy", distribution="beckmann", roughness=0.6, anisotropic=-0.5), 30,
                             False),
    "glass_entering": (S.for_kind("glass", roughness=0.5), 45, False),
    "glass_leaving": (S.for_kind("glass", roughness=0.5), 30, True),
    "glass_leaving_grazing": (S.for_kind("glass", roughness=0.7), 70, True),
    "glass_beckmann": (S.for_kind("glass", roughness=0.5, distribution="beckmann"), 45, False),
    "refraction_ggx": (S.for_kind("refraction", roughness=0.5, distribution="ggx"), 45, False),
    "refraction_beckmann_leaving": (S.for_kind("refraction", roughness=0.6), 20, True),
    "metallic_f82": (S.for_kind("metallic", roughness=0.4, anisotropic=0.3), 60, False),
    "metallic_physical": (S.for_kind("metallic", roughness=0.4, fresnel="physical"), 60, False),
    "principled_layers": (S(roughness=0.4, coat_weight=0.5, coat_roughness=0.3, coat_tint=(0.8, 0.9, 1.0),
                            metallic=0.2, transmission=0.3, diffuse_roughness=0.5, sheen_weight=0.5,
                            specular_tint=(1.0, 0.8, 0.6)), 50, False),
    "principled_backface": (S(roughness=0.5, transmission=0.7), 35, True),
    "sheen": (S.for_kind("sheen", roughness=0.4), 60, False),
    "mix_with_deltas": ([S.for_kind("glass", weight=0.3), S.for_kind("diffuse", weight=0.4),
                         S.for_kind("transparent", weight=0.3)], 40, False),
}


def _hit(name):
    node, theta, back = CASES[name]
    return Hit(node, direction(theta, 20), backfacing=back, tangent=TANGENT)


@pytest.mark.parametrize("name", list(CASES))
def test_sampling_matches_pdf(name):
    hit = _hit(name)
    r = chi2_test(hit)
    assert r.passed, str(r)
    sigma = np.sqrt(r.valid_fraction * (1 - r.valid_fraction) / r.n_samples)
    assert abs(r.pdf_integral - r.valid_fraction) < 5 * sigma + 3 * r.quadrature_error + 3e-4, str(r)


@pytest.mark.parametrize("name", list(CASES))
def test_sample_weight_is_eval_over_pdf(name):
    hit = _hit(name)
    rng = np.random.default_rng(11)
    wo, w, pdf, label = hit.sample(rng.random((2000, 3)))
    rough = (label != 0) & (pdf > 0)
    f, pdf_eval = hit.eval(wo[rough])
    np.testing.assert_allclose(pdf[rough], pdf_eval, rtol=1e-9)
    np.testing.assert_allclose(w[rough], f / pdf_eval[:, None], rtol=1e-8, atol=1e-14)
    deltas = (label & (LABEL_SINGULAR | LABEL_TRANSPARENT)) != 0
    assert np.all(pdf[deltas] == 0)
    assert np.all(np.isfinite(w)) and np.all(w >= 0)
    assert np.all(w[label == 0] == 0)


def test_chi2_rejects_planted_pdf_error_on_transmission():
    """Rough glass with its transmission pdf scaled by 1.03 fails the same test."""
    hit = _hit("glass_entering")
    r = chi2_test(hit, pdf_fn=lambda d: hit.eval(d)[1] * np.where(d @ np.array(hit.n) < 0, 1.03, 1.0))
    assert not r.passed, str(r)


def test_chi2_rejects_planted_roughness_error():
    """Samples of roughness 0.5 do not pass as alpha scaled by 3 %."""
    hit = _hit("ggx")
    node = S.for_kind("glossy", distribution="ggx", roughness=0.5 * np.sqrt(1.03))
    other = Hit(node, hit.wi)
    r = chi2_test(hit, pdf_fn=lambda d: other.eval(d)[1])
    assert not r.passed, str(r)
