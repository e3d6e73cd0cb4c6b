"""The surface shader of one hit (bsdfs/closures.py): deltas (smooth glass, refraction, transparent)
against Fresnel, Principled alpha and layering, shadow transparency, mixing, back faces, the
normal fix-up, closure limits, and finite output for any input."""
import numpy as np
import pytest

from volpath_native.bsdfs import (LABEL_DIFFUSE, LABEL_GLOSSY, LABEL_REFLECT, LABEL_SINGULAR, LABEL_TRANSMIT,
                                  LABEL_TRANSPARENT, MAX_CLOSURES, SurfaceNode as S)
from volpath_native.bsdfs.batch import Hit
from volpath_native.bsdfs.closures import (CLOSURE_DIFFUSE, CLOSURE_GLASS, CLOSURE_REFLECTION,
                                           ensure_valid_specular_reflection, layering_weight, surface_is_transmissive,
                                           surface_transparency)
from volpath_native.bsdfs.fresnel import fresnel_dielectric

from bsdf_helpers import albedo, direction

Z = 4.5


def _binomial_ok(k, n, p):
    return abs(k - n * p) < Z * np.sqrt(n * p * (1 - p)) + 1


@pytest.mark.parametrize("backfacing", [False, True])
def test_smooth_glass_is_fresnel_weighted(backfacing):
    theta = 50.0 if not backfacing else 30.0
    wi = direction(theta, 10)
    hit = Hit(S.for_kind("glass", ior=1.5, color=(1.0, 1.0, 1.0)), wi, backfacing=backfacing)
    eta = 1 / 1.5 if backfacing else 1.5
    F, cos_t = fresnel_dielectric(np.cos(np.radians(theta)), eta)
    n = 100_000
    wo, w, pdf, label = hit.sample(np.random.default_rng(2).random((n, 3)))
    refl = label == (LABEL_REFLECT | LABEL_SINGULAR)
    trans = label == (LABEL_TRANSMIT | LABEL_SINGULAR)
    assert np.all(refl | trans) and np.all(pdf == 0)
    assert _binomial_ok(refl.sum(), n, F)
    np.testing.assert_allclose(w, 1.0, rtol=1e-12)  # tint F / P with P = F
    np.testing.assert_allclose(wo[refl], [[-wi[0], -wi[1], wi[2]]] * refl.sum(), atol=1e-12)
    sin_t = np.hypot(wo[trans][:, 0], wo[trans][:, 1])
    np.testing.assert_allclose(sin_t, np.sin(np.radians(theta)) / eta, rtol=1e-10)  # Snell
    np.testing.assert_allclose(wo[trans][:, 2], cos_t, rtol=1e-10)
    assert hit.CB.ior[0] == pytest.approx(eta)


def test_principled_smooth_transmission_tint():
    """Principled transmission: reflection tint 1, transmission tint sqrt(base colour) per
    interface; the sample weight of each branch is tint x F / P_branch."""
    base = np.array([0.64, 0.25, 0.04])
    wi = direction(40)
    hit = Hit(S(color=base, roughness=0.0, transmission=1.0), wi)
    F = fresnel_dielectric(np.cos(np.radians(40)), 1.5)[0]
    T = (1 - F) * np.sqrt(base)
    p_reflect = F / (F + T.mean())
    wo, w, pdf, label = hit.sample(np.random.default_rng(4).random((50_000, 3)))
    refl = (label & LABEL_REFLECT) != 0
    assert _binomial_ok(refl.sum(), len(label), p_reflect)
    np.testing.assert_allclose(w[refl], F / p_reflect, rtol=1e-9)
    np.testing.assert_allclose(w[~refl], np.broadcast_to(T / (1 - p_reflect), w[~refl].shape), rtol=1e-9)


def test_refraction_node_total_internal_reflection():
    color = (0.9, 0.8, 0.7)
    inside_grazing = Hit(S.for_kind("refraction", color=color, roughness=0.0, ior=1.5), direction(60), backfacing=True)
    wo, w, pdf, label = inside_grazing.sample(np.random.default_rng(0).random((100, 3)))
    assert np.all(label == 0) and np.all(w == 0)  # TIR: no reflection lobe, the path ends
    steep = Hit(S.for_kind("refraction", color=color, roughness=0.0, ior=1.5), direction(20), backfacing=True)
    wo, w, pdf, label = steep.sample(np.random.default_rng(0).random((100, 3)))
    assert np.all(label == LABEL_TRANSMIT | LABEL_SINGULAR)
    np.testing.assert_allclose(w, np.broadcast_to(color, w.shape))  # no (1 - F) factor


def test_transparent_and_alpha():
    wi = direction(35, 40)
    t = Hit(S.for_kind("transparent", color=(0.2, 0.5, 1.0)), wi)
    wo, w, pdf, label = t.sample(np.random.default_rng(0).random((10, 3)))
    assert np.all(label == LABEL_TRANSMIT | LABEL_TRANSPARENT) and np.all(pdf == 0)
    np.testing.assert_allclose(wo, [-wi] * 10, atol=1e-15)
    np.testing.assert_allclose(w, [(0.2, 0.5, 1.0)] * 10)
    assert surface_transparency(t.CB, t.count) == pytest.approx((0.2, 0.5, 1.0))
    # Principled alpha: 1 - alpha passes straight through, the rest is the shader scaled by alpha
    for a in [0.0, 0.25, 1.0]:
        h = Hit(S(alpha=a), wi)
        assert surface_transparency(h.CB, h.count) == pytest.approx((1 - a,) * 3)
    full, se_full = albedo(Hit(S(), wi))
    quarter, se_q = albedo(Hit(S(alpha=0.25), wi))
    assert abs(quarter[0] - (0.75 + 0.25 * full[0])) < 5 * (se_q[0] + 0.25 * se_full[0])


def test_glass_is_opaque_to_shadow_rays():
    for node in [S.for_kind("glass"), S.for_kind("refraction"), S(transmission=1.0)]:
        h = Hit(node, direction(30))
        assert surface_transparency(h.CB, h.count) == (0.0, 0.0, 0.0)
        assert surface_is_transmissive(h.CB, h.count)
    d = Hit(S.for_kind("diffuse"), direction(30))
    assert not surface_is_transmissive(d.CB, d.count)


def test_mixture_is_linear_in_mix_weights():
    wi = direction(40)
    a, b = S.for_kind("diffuse", color=(0.7, 0.2, 0.1)), S.for_kind("glossy", roughness=0.4)
    mix = Hit([S.for_kind("diffuse", color=(0.7, 0.2, 0.1), weight=0.3), S.for_kind("glossy", roughness=0.4,
                                                                              weight=0.7)], wi)
    wo = np.array([direction(t, p) for t, p in [(10, 0), (40, 180), (70, 90), (30, 200)]])
    fa, _ = Hit(a, wi).eval(wo)
    fb, _ = Hit(b, wi).eval(wo)
    fm, _ = mix.eval(wo)
    np.testing.assert_allclose(fm, 0.3 * fa + 0.7 * fb, rtol=1e-12)
    assert Hit(S(weight=0.0), wi).count == 0


def test_principled_layering_weights():
    """The diffuse base keeps base x (1 - albedo estimate of the specular layer) and a 100 %
    metallic or transmissive Principled has no diffuse lobe."""
    h = Hit(S(color=(0.5, 0.5, 0.5), roughness=0.3), direction(30))
    kinds = list(h.CB.kind[:h.count])
    assert kinds == [CLOSURE_REFLECTION, CLOSURE_DIFFUSE]
    spec_albedo_weight = h.CB.sample_weight[0]  # = weight x estimated albedo (white weight 1)
    np.testing.assert_allclose(h.CB.weight[1], 0.5 * (1 - spec_albedo_weight), rtol=1e-9)
    assert CLOSURE_DIFFUSE not in list(Hit(S(metallic=1.0), direction(30)).CB.kind[:1])
    t = Hit(S(transmission=1.0), direction(30))
    assert list(t.CB.kind[:t.count]) == [CLOSURE_GLASS]
    assert layering_weight((0.2, 0.1, 0.0), (1.0, 0.5, 0.5)) == pytest.approx((0.8, 0.4, 0.4))
    assert layering_weight((2.0, 0.0, 0.0), (1.0, 1.0, 1.0)) == (0.0, 0.0, 0.0)
    assert layering_weight((0.5, 0.5, 0.5), (0.0, 1.0, 1.0)) == pytest.approx((0.0, 0.5, 0.5))


def test_backface_keeps_specular_ior_and_inverts_glass():
    h = Hit(S(roughness=0.3, transmission=0.5, coat_weight=0.5, coat_ior=1.6), direction(30), backfacing=True)
    iors = {int(k): [] for k in h.CB.kind[:h.count]}
    for i in range(h.count):
        iors[int(h.CB.kind[i])].append(h.CB.ior[i])
    assert iors[CLOSURE_GLASS] == [pytest.approx(1 / 1.5)]
    assert sorted(iors[CLOSURE_REFLECTION]) == [pytest.approx(1.5), pytest.approx(1.6)]  # specular, coat


def test_ensure_valid_specular_reflection():
    rng = np.random.default_rng(9)
    ng = (0.0, 0.0, 1.0)
    for _ in range(300):
        wi = direction(rng.uniform(0, 89), rng.uniform(0, 360))
        n = direction(rng.uniform(0, 70), rng.uniform(0, 360))
        fixed = np.array(ensure_valid_specular_reflection(ng, tuple(wi), tuple(n)))
        assert np.linalg.norm(fixed) == pytest.approx(1.0, abs=1e-9)
        r = 2 * fixed @ wi * fixed - wi
        threshold = min(0.9 * wi[2], 0.01)
        assert r[2] >= threshold - 1e-6
        r0 = 2 * n @ wi * n - wi
        if r0[2] >= threshold:
            np.testing.assert_array_equal(fixed, n)
        else:  # tilted within the (n, ng) plane, exactly onto the threshold
            assert abs(np.cross(n, ng) @ fixed) < 1e-9
            assert r[2] == pytest.approx(threshold, abs=1e-6)
    assert ensure_valid_specular_reflection(ng, tuple(direction(80)), ng) == ng


def test_closures_beyond_the_limit_are_dropped():
    h = Hit([S.for_kind("diffuse", weight=0.05)] * (MAX_CLOSURES + 5), direction(10))
    assert h.count == MAX_CLOSURES
    a, _ = albedo(h)
    assert a[0] == pytest.approx(0.8 * 0.05 * MAX_CLOSURES, rel=2e-2)


def test_principled_emission_is_attenuated_by_alpha_sheen_and_coat_only():
    wi = direction(30)
    e = (1.0, 0.5, 0.25)
    plain = Hit(S(emission_color=e, emission_strength=2.0, weight=0.5), wi)
    np.testing.assert_allclose(plain.emission, np.array(e) * 2.0 * 0.5, rtol=1e-12)
    below = Hit(S(emission_color=e, emission_strength=2.0, metallic=1.0, transmission=1.0), wi)
    np.testing.assert_allclose(below.emission, np.array(e) * 2.0, rtol=1e-12)  # metal / glass do not dim it
    cut = Hit(S(emission_color=e, emission_strength=2.0, alpha=0.25), wi)
    np.testing.assert_allclose(cut.emission, np.array(e) * 2.0 * 0.25, rtol=1e-12)
    coated = Hit(S(emission_color=e, emission_strength=2.0, coat_weight=1.0), wi)
    coat_albedo = coated.CB.sample_weight[0]  # white coat weight x its albedo estimate
    np.testing.assert_allclose(coated.emission, np.array(e) * 2.0 * (1 - coat_albedo), rtol=1e-9)
    assert np.all(Hit(S.for_kind("glossy"), wi).emission == 0)


def test_filter_glossy_blur():
    wi = direction(30)
    mirror = Hit(S.for_kind("glossy", roughness=0.0, distribution="ggx"), wi)
    wo = np.array([direction(35, 180)])
    assert mirror.eval(wo)[1][0] == 0.0  # a delta is never evaluated
    mirror.blur(0.3)
    assert mirror.CB.alpha_x[0] == 0.3 and mirror.eval(wo)[1][0] > 0.0
    rough = Hit(S.for_kind("glossy", roughness=0.8, distribution="ggx"), wi).blur(0.3)
    assert rough.CB.alpha_x[0] == pytest.approx(0.64)  # never sharpened


def test_labels():
    cases = [(S.for_kind("diffuse"), LABEL_REFLECT | LABEL_DIFFUSE), (S.for_kind("translucent"),
             LABEL_TRANSMIT | LABEL_DIFFUSE), (S.for_kind("sheen"), LABEL_REFLECT | LABEL_DIFFUSE),
             (S.for_kind("glossy"), LABEL_REFLECT | LABEL_GLOSSY), (S.for_kind("glossy", roughness=0.0),
             LABEL_REFLECT | LABEL_SINGULAR)]
    for node, expected in cases:
        _, _, _, label = Hit(node, direction(30)).sample(np.random.default_rng(1).random((50, 3)))
        assert set(label[label != 0].tolist()) == {expected}


def test_any_input_gives_finite_output():
    """Random nodes (sanitised), including degenerate values, and random directions: every
    weight, eval and pdf is finite and non-negative."""
    rng = np.random.default_rng(123)
    specials = [0.0, 1.0, 1e-6, 1e6, 0.5]
    kinds = ["principled", "glossy", "glass", "refraction", "metallic", "transparent", "translucent", "sheen",
             "diffuse"]

    def value():
        return float(rng.choice(specials)) if rng.random() < 0.4 else float(rng.uniform(-0.5, 2.0))

    for trial in range(60):
        node = S.for_kind(kinds[trial % len(kinds)], roughness=value(), ior=value() * 3, metallic=value(),
                          transmission=value(), coat_weight=value(), sheen_weight=value(), alpha=value(),
                          anisotropic=value(), diffuse_roughness=value(), specular_ior_level=value(),
                          color=[value(), value(), value()], distribution=["ggx", "beckmann", "multi_ggx"][trial % 3],
                          fresnel=["f82", "physical"][trial % 2])
        node.sanitize()
        n = direction(rng.uniform(0, 60), rng.uniform(0, 360))
        wi = direction(rng.uniform(0, 89.9), rng.uniform(0, 360))
        hit = Hit(node, wi, n=n, ng=(0, 0, 1), backfacing=bool(trial % 2), tangent=(1.0, 0.0, 0.0))
        wo, w, pdf, label = hit.sample(rng.random((500, 3)))
        f, p = hit.eval(np.array([direction(rng.uniform(0, 180), rng.uniform(0, 360)) for _ in range(100)]))
        for a in (wo, w, pdf, f, p):
            assert np.all(np.isfinite(a)), node
        assert np.all(w >= 0) and np.all(f >= 0) and np.all(p >= 0) and np.all(pdf >= 0)
