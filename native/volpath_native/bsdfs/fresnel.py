"""Fresnel terms of Cycles' microfacet closures (Cycles 5.0 kernel/closure/bsdf_util.h for the
formulas, kernel/closure/bsdf_microfacet.h microfacet_fresnel for how a closure combines them).

Conventions: cos_i = dot(h, wi) > 0 on the incident side; eta = inside IOR / outside IOR (a back
face passes 1/ior). Colours are 3-tuples.
- dielectric: exact unpolarised (rs^2 + rp^2) / 2, F = 1 on total internal reflection (TIR).
- conductor: exact complex-IOR Fresnel per channel (Born & Wolf; written with complex arithmetic
  as pbrt-v4 FrComplex, which is the same function).
- F82-tint (Kutz et al., "Novel aspects of the Adobe Standard Material"): Schlick minus
  b cos (1 - cos)^6, b chosen so that F(acos 1/7) = Schlick(acos 1/7) * tint.
- generalized Schlick with a negative exponent (Principled, Glass): the real dielectric curve
  remapped from [F0_real, 1] to [f0, f90]; TIR gives f90.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from .vector import average, mix, saturate

# MicrofacetFresnel in bsdf_microfacet.h (same numbering; DIELECTRIC_TINT is OSL-only there)
FRESNEL_NONE = 0
FRESNEL_DIELECTRIC = 1
FRESNEL_CONDUCTOR = 3
FRESNEL_GENERALIZED_SCHLICK = 4
FRESNEL_F82_TINT = 5

_F82_COS = 1.0 / 7.0  # cos(~81.8 deg), where F82-tint pins the tint


@kernel
def fresnel_dielectric(cos_i, eta):
    """(F, cos_t): unpolarised reflectance and the cosine of the refracted direction relative to
    the normal, negative (it points to the other side); cos_t = 0 and F = 1 on TIR."""
    eta_cos_t_sq = eta * eta - (1.0 - cos_i * cos_i)
    if eta_cos_t_sq <= 0.0:
        return 1.0, 0.0
    c = abs(cos_i)
    g = np.sqrt(eta_cos_t_sq)  # eta |cos_t|
    r_s = (c - g) / (c + g)
    r_p = (eta * eta * c - g) / (eta * eta * c + g)
    return 0.5 * (r_s * r_s + r_p * r_p), -g / eta


@kernel
def F0_from_ior(ior):
    r = (ior - 1.0) / (ior + 1.0)
    return r * r


@kernel
def ior_from_F0(f0):
    s = np.sqrt(min(max(f0, 0.0), 0.99))
    return (1.0 + s) / (1.0 - s)


@kernel
def fresnel_dielectric_Fss(eta):
    """Average single-scattering Fresnel 2 int_0^1 F(mu) mu dmu: the Kulla & Conty 2017 fit
    ("Revisiting Physically Based Shading at Imageworks") that Cycles uses."""
    if eta < 1.0:
        return 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    return (eta - 1.0) / (4.08567 + 1.00071 * eta)


@kernel
def _f82_1(cos_i, f0, b):
    s = saturate(1.0 - cos_i)
    s5 = s * s * s * s * s
    return min(max(f0 + (1.0 - f0) * s5 - b * cos_i * s5 * s, 0.0), 1.0)


@kernel
def fresnel_f82(cos_i, f0, b):
    return (_f82_1(cos_i, f0[0], b[0]), _f82_1(cos_i, f0[1], b[1]), _f82_1(cos_i, f0[2], b[2]))


@kernel
def _schlick_at_f82(f0):
    f = 1.0 - _F82_COS
    return f0 + (1.0 - f0) * f ** 5


@kernel
def f82_tint_b(f0, tint):
    """The b of F82-tint: F(1/7) = Schlick(1/7) * tint. b = 0 when the tint is exactly white
    (Cycles bsdf_microfacet_setup_fresnel_f82_tint)."""
    if tint[0] == 1.0 and tint[1] == 1.0 and tint[2] == 1.0:
        return (0.0, 0.0, 0.0)
    f = 1.0 - _F82_COS
    k = 1.0 / (_F82_COS * f ** 6)
    return (_schlick_at_f82(f0[0]) * k * (1.0 - tint[0]), _schlick_at_f82(f0[1]) * k * (1.0 - tint[1]),
            _schlick_at_f82(f0[2]) * k * (1.0 - tint[2]))


@kernel
def f82_b_from_value(f0, f82):
    """The b for which the F82 curve passes through f82 at cos = 1/7 (one channel)."""
    f = 1.0 - _F82_COS
    return (_schlick_at_f82(f0) - f82) / (_F82_COS * f ** 6)


@kernel
def f82_Fss(f0, b):
    """2 int_0^1 F82(mu) mu dmu = mix(f0, 1, 1/21) - b/126 (analytic)."""
    return (f0[0] + (1.0 - f0[0]) / 21.0 - b[0] / 126.0, f0[1] + (1.0 - f0[1]) / 21.0 - b[1] / 126.0,
            f0[2] + (1.0 - f0[2]) / 21.0 - b[2] / 126.0)


@kernel
def _conductor_1(cos_i, n, k):
    c = min(max(cos_i, 0.0), 1.0)
    eta = complex(n, k)
    sin2_t = (1.0 - c * c) / (eta * eta)
    cos_t = np.sqrt(1.0 - sin2_t)
    r_parl = (eta * c - cos_t) / (eta * c + cos_t)
    r_perp = (c - eta * cos_t) / (c + eta * cos_t)
    return 0.5 * (abs(r_parl) ** 2 + abs(r_perp) ** 2)


@kernel
def fresnel_conductor(cos_i, n, k):
    """Reflectance of a conductor of complex IOR n + ik (per channel) seen from a medium of IOR 1."""
    return (_conductor_1(cos_i, n[0], k[0]), _conductor_1(cos_i, n[1], k[1]), _conductor_1(cos_i, n[2], k[2]))


@kernel
def conductor_Fss(n, k):
    """Cycles fresnel_conductor_Fss: fit F82 through the exact values at cos 1 and 1/7 and take
    its analytic Fss."""
    f0 = fresnel_conductor(1.0, n, k)
    f82 = fresnel_conductor(_F82_COS, n, k)
    b = (f82_b_from_value(f0[0], f82[0]), f82_b_from_value(f0[1], f82[1]), f82_b_from_value(f0[2], f82[2]))
    fss = f82_Fss(f0, b)
    return (saturate(fss[0]), saturate(fss[1]), saturate(fss[2]))


@kernel
def schlick_remap_s(cos_i, ior):
    """(s, cos_t) of the negative-exponent generalized Schlick: s = saturate(inverse_lerp(F0, 1, F))
    with F the real dielectric Fresnel; s = 1 on TIR."""
    f_real, cos_t = fresnel_dielectric(cos_i, ior)
    f0_real = F0_from_ior(ior)
    return saturate((f_real - f0_real) / (1.0 - f0_real)), cos_t


@kernel
def closure_fresnel(fresnel_type, has_reflection, has_transmission, ior, cos_i, f0, f90, f82_b,
                    reflection_tint, transmission_tint, conductor_n, conductor_k):
    """(reflectance, transmittance, cos_t) of one microfacet closure at cos_i = dot(h, wi)
    (Cycles microfacet_fresnel). cos_t (< 0) is only meaningful for transmissive closures."""
    zero = (0.0, 0.0, 0.0)
    if fresnel_type == FRESNEL_DIELECTRIC:
        f, cos_t = fresnel_dielectric(cos_i, ior)
        r = (f, f, f)
        t = (1.0 - f, 1.0 - f, 1.0 - f)
    elif fresnel_type == FRESNEL_CONDUCTOR:
        r = fresnel_conductor(cos_i, conductor_n, conductor_k)
        t = zero
        cos_t = 0.0
    elif fresnel_type == FRESNEL_F82_TINT:
        r = fresnel_f82(cos_i, f0, f82_b)
        t = zero
        cos_t = 0.0
    elif fresnel_type == FRESNEL_GENERALIZED_SCHLICK:
        s, cos_t = schlick_remap_s(cos_i, ior)
        f = mix(f0, f90, s)
        r = (f[0] * reflection_tint[0], f[1] * reflection_tint[1], f[2] * reflection_tint[2])
        t = ((1.0 - f[0]) * transmission_tint[0], (1.0 - f[1]) * transmission_tint[1],
             (1.0 - f[2]) * transmission_tint[2])
    else:  # NONE: pure reflection or pure refraction, weight 1; refraction gets nothing on TIR
        r = (1.0, 1.0, 1.0)
        t = (1.0, 1.0, 1.0)
        cos_t = 0.0
        if has_transmission:
            f, cos_t = fresnel_dielectric(cos_i, ior)
            if f == 1.0:
                t = zero
    if not has_reflection:
        r = zero
    if not has_transmission:
        t = zero
    return r, t, cos_t


@kernel
def reflect_probability(r, t):
    """Chance of sampling reflection rather than transmission: avg(R) / avg(R + T)."""
    total = average(r) + average(t)
    return average(r) / total if total > 0.0 else 0.0
