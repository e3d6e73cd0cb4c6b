"""Microfacet distributions and the microfacet closure (reflection, refraction or both), as Cycles
5.0 kernel/closure/bsdf_microfacet.h (bsdf_microfacet_eval / bsdf_microfacet_sample):

- D: GGX (Trowbridge-Reitz) and Beckmann, isotropic and anisotropic (Walter et al. 2007, EGSR).
- Smith masking in the height-correlated form G2 = 1 / (1 + L(wi) + L(wo)) with GGX's Lambda of
  Heitz 2014 (JCGT 3(2), eq. 72). Beckmann uses the exact Lambda, (erf(a) - 1)/2 + e^(-a^2)/(2 a
  sqrt(pi)); Cycles uses Walter's rational fit of it (within 0.35 %), we keep the exact one so the
  pdf is the density the visible-normal sampler really draws from.
- Sampling: visible normals. GGX: Heitz 2018, "Sampling the GGX Distribution of Visible Normals"
  (JCGT 7(4)). Beckmann: Heitz & d'Eon 2014 in the stretched configuration, the slope's CDF
  inverted by safeguarded Newton iteration (Jakob's "improved visible normal sampling routine"
  solves the same equation).
- eval returns f |cos_o| (Cycles' convention), pdf includes the reflect/refract choice made with
  P_reflect = avg(R) / avg(R + T).

Transmission: Cycles evaluates every (wi, wo) pair on opposite sides with the generalized half
vector and does not check that the microfacet faces both directions (a TODO in its eval); the
sampler can never produce such pairs. We reject them as pbrt-v4 (DielectricBxDF::f) does, so
eval and pdf describe exactly what sample() draws; the energy Cycles' NEE adds there is reported
by tests/native/test_bsdfs_microfacet.py.

Directions are world-space 3-tuples; (x, y, n) is the closure's frame (x along the anisotropy
tangent). wi points toward the viewer, dot(n, wi) > 0 is required.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel
from ..sampling import concentric_disk1
from .fresnel import closure_fresnel, reflect_probability
from .vector import dot, normalize, reflect, to_local, to_world

GGX = 0
BECKMANN = 1
ROUGHNESS_SQ_THRESHOLD = 2e-10  # BSDF_ROUGHNESS_SQ_THRESH (kernel/svm/types.h): below, a delta
_INV_SQRT_PI = 0.5641895835477563
_SQRT_PI = 1.7724538509055159


@kernel
def is_singular(alpha_x, alpha_y):
    return not alpha_x * alpha_y > ROUGHNESS_SQ_THRESHOLD


# --- distributions -----------------------------------------------------------------------------
@kernel
def D_iso(distribution, alpha2, cos_nh):
    c2 = min(cos_nh * cos_nh, 1.0)
    s2 = 1.0 - c2
    if distribution == BECKMANN:
        if c2 <= 0.0:
            return 0.0
        return np.exp(-s2 / (c2 * alpha2)) / (np.pi * alpha2 * c2 * c2)
    d = s2 + alpha2 * c2
    return alpha2 / (np.pi * d * d)


@kernel
def D_aniso(distribution, alpha_x, alpha_y, h):
    """h in the local frame (x, y, n)."""
    hx, hy, hz = h[0] / alpha_x, h[1] / alpha_y, h[2]
    c2 = hz * hz
    a2 = alpha_x * alpha_y
    if distribution == BECKMANN:
        if c2 <= 0.0:
            return 0.0
        return np.exp(-(hx * hx + hy * hy) / c2) / (np.pi * a2 * c2 * c2)
    l2 = hx * hx + hy * hy + c2
    return 1.0 / (np.pi * a2 * l2 * l2)


@kernel
def lambda_from_sq_alpha_tan(distribution, sq_alpha_tan):
    """Smith Lambda as a function of alpha^2 tan^2(theta)."""
    if distribution == BECKMANN:
        if sq_alpha_tan <= 0.0:
            return 0.0
        a = 1.0 / np.sqrt(sq_alpha_tan)
        if a > 26.0:  # erfc(a) and exp(-a^2) underflow: Lambda -> 0
            return 0.0
        return 0.5 * (math.erf(a) - 1.0) + np.exp(-a * a) / (2.0 * a * _SQRT_PI)
    return 0.5 * (np.sqrt(1.0 + sq_alpha_tan) - 1.0)


@kernel
def lambda_iso(distribution, alpha2, cos_n):
    c2 = cos_n * cos_n
    if c2 <= 0.0:
        return np.inf
    return lambda_from_sq_alpha_tan(distribution, alpha2 * max(1.0 / c2 - 1.0, 0.0))


@kernel
def lambda_aniso(distribution, alpha_x, alpha_y, v):
    """v in the local frame."""
    if v[2] == 0.0:
        return np.inf
    ax, ay = alpha_x * v[0], alpha_y * v[1]
    return lambda_from_sq_alpha_tan(distribution, (ax * ax + ay * ay) / (v[2] * v[2]))


# --- visible-normal sampling (local frame, wi.z > 0) -------------------------------------------
@kernel
def ggx_sample_vndf(wi, alpha_x, alpha_y, u1, u2):
    """Heitz 2018: a microfacet normal drawn with density G1(wi) max(0, wi.h) D(h) / wi.z."""
    vx, vy, vz = alpha_x * wi[0], alpha_y * wi[1], wi[2]
    inv = 1.0 / np.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx * inv, vy * inv, vz * inv
    lensq = vx * vx + vy * vy
    if lensq > 1e-14:
        il = 1.0 / np.sqrt(lensq)
        t1 = (-vy * il, vx * il, 0.0)
    else:
        t1 = (1.0, 0.0, 0.0)
    t2 = (vy * t1[2] - vz * t1[1], vz * t1[0] - vx * t1[2], vx * t1[1] - vy * t1[0])
    px, py = concentric_disk1(u1, u2)
    s = 0.5 * (1.0 + vz)
    py = (1.0 - s) * np.sqrt(max(1.0 - px * px, 0.0)) + s * py
    pz = np.sqrt(max(1.0 - px * px - py * py, 0.0))
    hx = px * t1[0] + py * t2[0] + pz * vx
    hy = px * t1[1] + py * t2[1] + pz * vy
    hz = px * t1[2] + py * t2[2] + pz * vz
    return normalize((alpha_x * hx, alpha_y * hy, max(hz, 0.0)))


@kernel
def _erfinv(y):
    """Inverse error function: a rational start (Winitzki 2008) polished by Newton steps on erf."""
    if y <= -1.0:
        return -np.inf
    if y >= 1.0:
        return np.inf
    a = 0.147
    ln = np.log((1.0 - y) * (1.0 + y))
    t = 2.0 / (np.pi * a) + 0.5 * ln
    x = math.copysign(np.sqrt(np.sqrt(t * t - ln / a) - t), y)
    for _ in range(3):
        err = math.erf(x) - y
        x -= err / (2.0 * _INV_SQRT_PI * np.exp(-x * x))
    return x


@kernel
def _beckmann_visible_slope_x(cot, u):
    """Slope x of the stretched (alpha = 1) Beckmann visible slopes for incidence cot(theta):
    density proportional to (cot - x) exp(-x^2) on x < cot; its CDF
    C(x) = cot sqrt(pi)/2 (1 + erf x) + exp(-x^2)/2 is inverted by Newton with bisection."""
    hi = min(cot, 9.0)
    lo = -9.0
    half_sqrt_pi = 0.5 * _SQRT_PI
    total = cot * half_sqrt_pi * (1.0 + math.erf(hi)) + 0.5 * np.exp(-hi * hi)
    target = u * total
    x = min(max(0.0, lo), hi) if cot > 0.0 else 0.5 * (lo + hi)
    for _ in range(60):
        c = cot * half_sqrt_pi * (1.0 + math.erf(x)) + 0.5 * np.exp(-x * x) - target
        if abs(c) < 1e-12 * max(total, 1e-300):
            break
        if c > 0.0:
            hi = x
        else:
            lo = x
        d = (cot - x) * np.exp(-x * x)
        nx = x - c / d if d > 0.0 else lo - 1.0
        x = nx if lo < nx < hi else 0.5 * (lo + hi)
        if hi - lo < 1e-13:
            break
    return x


@kernel
def beckmann_sample_vndf(wi, alpha_x, alpha_y, u1, u2):
    """Heitz & d'Eon 2014: stretch wi, draw the visible slope of the unit-roughness Beckmann
    distribution, rotate and unstretch it."""
    vx, vy, vz = alpha_x * wi[0], alpha_y * wi[1], wi[2]
    inv = 1.0 / np.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx * inv, vy * inv, vz * inv
    if vz >= 0.99999:
        r = np.sqrt(-np.log(max(1.0 - u1, 1e-300)))
        phi = 2.0 * np.pi * u2
        sx, sy = r * np.cos(phi), r * np.sin(phi)
    else:
        sin_t = np.sqrt(max(1.0 - vz * vz, 0.0))
        cot = vz / sin_t
        cos_p, sin_p = vx / sin_t, vy / sin_t
        x = _beckmann_visible_slope_x(cot, u1)
        y = _erfinv(2.0 * u2 - 1.0)
        sx, sy = cos_p * x - sin_p * y, sin_p * x + cos_p * y
    sx *= alpha_x
    sy *= alpha_y
    return normalize((-sx, -sy, 1.0))


# --- the closure --------------------------------------------------------------------------------
@kernel
def _d_lambdas(distribution, alpha_x, alpha_y, isotropic, h_l, i_l, o_l):
    if isotropic:
        a2 = alpha_x * alpha_y
        return (D_iso(distribution, a2, h_l[2]), lambda_iso(distribution, a2, i_l[2]),
                lambda_iso(distribution, a2, o_l[2]))
    return (D_aniso(distribution, alpha_x, alpha_y, h_l), lambda_aniso(distribution, alpha_x, alpha_y, i_l),
            lambda_aniso(distribution, alpha_x, alpha_y, o_l))


@kernel
def microfacet_eval(distribution, has_reflection, has_transmission, alpha_x, alpha_y, ior, x, y, n, wi, wo,
                    fresnel_type, f0, f90, f82_b, reflection_tint, transmission_tint, conductor_n, conductor_k):
    """(f |cos_o| per channel, pdf) of one microfacet closure; zero for singular closures and for
    directions on a side the closure has no lobe for."""
    zero = (0.0, 0.0, 0.0)
    cos_ni = dot(n, wi)
    cos_no = dot(n, wo)
    is_transmission = cos_no < 0.0
    if cos_ni <= 0.0 or is_singular(alpha_x, alpha_y) or (is_transmission and not has_transmission) \
            or (not is_transmission and not has_reflection) or cos_no == 0.0:
        return zero, 0.0
    if is_transmission:
        hu = (-(ior * wo[0] + wi[0]), -(ior * wo[1] + wi[1]), -(ior * wo[2] + wi[2]))
    else:
        hu = (wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2])
    len_h = np.sqrt(dot(hu, hu))
    if not len_h > 0.0:
        return zero, 0.0
    h = (hu[0] / len_h, hu[1] / len_h, hu[2] / len_h)
    if is_transmission:
        if dot(h, n) < 0.0:
            h = (-h[0], -h[1], -h[2])
        if dot(h, wi) <= 0.0 or dot(h, wo) >= 0.0:  # microfacet not visible from both sides
            return zero, 0.0
    cos_hi = dot(h, wi)
    r, t, _ = closure_fresnel(fresnel_type, has_reflection, has_transmission, ior, cos_hi, f0, f90, f82_b,
                              reflection_tint, transmission_tint, conductor_n, conductor_k)
    p_reflect = reflect_probability(r, t)
    lobe_pdf = 1.0 - p_reflect if is_transmission else p_reflect
    if lobe_pdf <= 0.0:
        return zero, 0.0
    isotropic = alpha_x == alpha_y or is_transmission
    d, lam_i, lam_o = _d_lambdas(distribution, alpha_x, alpha_y, isotropic, to_local(h, x, y, n),
                                 to_local(wi, x, y, n), to_local(wo, x, y, n))
    if is_transmission:
        common = d / cos_ni * (ior * ior / (len_h * len_h)) * abs(cos_hi * dot(h, wo))
    else:
        common = d / cos_ni * 0.25
    pdf = common * lobe_pdf / (1.0 + lam_i)
    g = common / (1.0 + lam_i + lam_o)
    c = t if is_transmission else r
    return (c[0] * g, c[1] * g, c[2] * g), pdf


@kernel
def microfacet_sample(distribution, has_reflection, has_transmission, alpha_x, alpha_y, ior, x, y, n, ng, wi,
                      u1, u2, u3, fresnel_type, f0, f90, f82_b, reflection_tint, transmission_tint,
                      conductor_n, conductor_k):
    """One direction from the closure: (wo, eval, pdf, refracted, singular, ok).
    Rough: eval = f |cos_o| and pdf as microfacet_eval. Singular: eval = R or T and pdf = the
    probability of that choice (the delta factor cancels). ok is False when the sample is
    rejected (wo on the wrong side of n or ng, or no energy)."""
    zero = (0.0, 0.0, 0.0)
    cos_ni = dot(n, wi)
    if cos_ni <= 0.0:
        return wi, zero, 0.0, False, False, False
    singular = is_singular(alpha_x, alpha_y)
    i_l = to_local(wi, x, y, n)
    if singular:
        h = n
        h_l = (0.0, 0.0, 1.0)
    else:
        if distribution == BECKMANN:
            h_l = beckmann_sample_vndf(i_l, alpha_x, alpha_y, u1, u2)
        else:
            h_l = ggx_sample_vndf(i_l, alpha_x, alpha_y, u1, u2)
        h = to_world(h_l, x, y, n)
    cos_hi = dot(h, wi)
    r, t, cos_ho = closure_fresnel(fresnel_type, has_reflection, has_transmission, ior, cos_hi, f0, f90, f82_b,
                                   reflection_tint, transmission_tint, conductor_n, conductor_k)
    if (r[0] == 0.0 and r[1] == 0.0 and r[2] == 0.0) and (t[0] == 0.0 and t[1] == 0.0 and t[2] == 0.0):
        return wi, zero, 0.0, False, singular, False
    p_reflect = reflect_probability(r, t)
    refract = u3 >= p_reflect
    if refract:
        inv_eta = 1.0 / ior
        k = inv_eta * cos_hi + cos_ho
        wo = normalize((k * h[0] - inv_eta * wi[0], k * h[1] - inv_eta * wi[1], k * h[2] - inv_eta * wi[2]))
    else:
        wo = reflect(wi, h)
    cos_no = dot(n, wo)
    if ((dot(ng, wo) < 0.0) != refract) or ((cos_no < 0.0) != refract) or cos_no == 0.0:
        return wo, zero, 0.0, refract, singular, False
    c = t if refract else r
    lobe_pdf = 1.0 - p_reflect if refract else p_reflect
    if refract and abs(ior - 1.0) < 1e-4:
        singular = True
    if singular:
        return wo, c, lobe_pdf, refract, True, True
    o_l = to_local(wo, x, y, n)
    isotropic = alpha_x == alpha_y or refract
    d, lam_i, lam_o = _d_lambdas(distribution, alpha_x, alpha_y, isotropic, h_l, i_l, o_l)
    if refract:
        den = cos_ho + cos_hi / ior
        common = d / cos_ni * abs(cos_hi * cos_ho) / (den * den)
    else:
        common = d / cos_ni * 0.25
    pdf = common * lobe_pdf / (1.0 + lam_i)
    g = common / (1.0 + lam_i + lam_o)
    return wo, (c[0] * g, c[1] * g, c[2] * g), pdf, refract, False, True
