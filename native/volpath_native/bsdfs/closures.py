"""The surface shader of one hit: a material's BSDF nodes expanded into weighted lobes
("closures"), then evaluated and sampled as one mixture -- Cycles 5.0:

- setup: kernel/svm/closure.h svm_node_closure_bsdf (node inputs -> closures, the Principled
  layering), kernel/closure/alloc.h bsdf_alloc (weights clamped >= 0, dropped below
  CLOSURE_WEIGHT_CUTOFF = 1e-5), kernel/closure/bsdf_microfacet.h bsdf_microfacet_setup_fresnel_*
  (sample weights scaled by the estimated albedo; "Multiscatter GGX" energy compensation,
  microfacet_ggx_preserve_energy), kernel/closure/bsdf_util.h closure_layering_weight.
- eval: kernel/integrator/surface_shader.h _surface_shader_bsdf_eval_mis: sum of weight_i f_i
  |cos| over non-singular closures and pdf = sum(sample_weight_i pdf_i) / sum(sample_weight_i)
  (one-sample MIS over closures, balance heuristic); kernel/closure/bsdf.h bsdf_eval applies
  bump_shadowing_term.
- sample: surface_shader_bsdf_bssrdf_pick (a closure in proportion to sample_weight, the random
  number rescaled and reused -- here for the reflect/refract choice of glass) and
  surface_shader_bsdf_sample_closure.
- transparency for shadow rays: surface_shader_transparency (Transparent BSDF and the Principled
  1 - alpha part only; glass and refraction are opaque to shadow rays in Cycles 5.0).

Every function here works on one path with 3-tuples and writes into a ClosureBuffer the caller
allocated once per thread (new_closure_buffer); nothing allocates, so they can be called from
stage kernels compiled with _nrt=False.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from ..jit import inline_stage_kernel, stage_kernel
from .diffuse import (lambert_eval, lambert_sample, oren_nayar_eval, oren_nayar_sample, oren_nayar_setup,
                      translucent_eval, translucent_sample)
from .fresnel import (FRESNEL_CONDUCTOR, FRESNEL_DIELECTRIC, FRESNEL_F82_TINT, FRESNEL_GENERALIZED_SCHLICK,
                      FRESNEL_NONE, F0_from_ior, closure_fresnel, conductor_Fss, f82_Fss, f82_tint_b,
                      fresnel_dielectric_Fss, ior_from_F0)
from .microfacet import BECKMANN, GGX, lambda_iso, microfacet_eval, microfacet_sample
from .nodes import (DIST_BECKMANN, DIST_MULTI_GGX, MAX_CLOSURES, METAL_PHYSICAL, NODE_DIFFUSE, NODE_GLASS,
                    NODE_GLOSSY, NODE_METALLIC, NODE_PRINCIPLED, NODE_REFRACTION, NODE_SHEEN, NODE_TRANSLUCENT,
                    NODE_TRANSPARENT)
from .sheen import sheen_eval, sheen_sample
from .tables import lookup1, lookup2, lookup2_layer, lookup3
from .vector import (average, cross, dot, length, max3, mix, normalize, orthonormals, orthonormals_tangent,
                     saturate, saturate3, scale)

CLOSURE_WEIGHT_CUTOFF = 1e-5

# closure kinds in a ClosureBuffer
CLOSURE_NONE, CLOSURE_DIFFUSE, CLOSURE_OREN_NAYAR, CLOSURE_TRANSLUCENT, CLOSURE_TRANSPARENT, CLOSURE_SHEEN, \
    CLOSURE_REFLECTION, CLOSURE_REFRACTION, CLOSURE_GLASS = range(9)

# sample labels (bit flags; the names of Cycles' LABEL_*, kernel/types.h -- note Cycles itself
# numbers TRANSMIT 1 and REFLECT 2)
LABEL_REFLECT = 1
LABEL_TRANSMIT = 2
LABEL_DIFFUSE = 4
LABEL_GLOSSY = 8
LABEL_SINGULAR = 16
LABEL_TRANSPARENT = 32

# Per-closure scratch of one thread. lobe_a / lobe_b: Oren-Nayar A, B or the sheen LTC a, b;
# multiscatter: Oren-Nayar's energy term. tangent / bitangent complete `normal` to the closure
# frame (anisotropy axis; for sheen, wi projected on the tangent plane). emission (3,): the hit's
# Principled emission after the alpha, sheen and coat layers (surface_emission).
ClosureBuffer = namedtuple("ClosureBuffer", [
    "kind", "distribution", "fresnel", "weight", "sample_weight", "normal", "tangent", "bitangent",
    "alpha_x", "alpha_y", "ior", "energy_scale", "f0", "f90", "f82_b", "reflection_tint", "transmission_tint",
    "conductor_n", "conductor_k", "lobe_a", "lobe_b", "multiscatter", "emission"])


def new_closure_buffer(max_closures: int = MAX_CLOSURES) -> ClosureBuffer:
    m = max_closures
    f1 = lambda: np.zeros(m)  # noqa: E731
    f3 = lambda: np.zeros((m, 3))  # noqa: E731
    return ClosureBuffer(
        kind=np.zeros(m, np.int32), distribution=np.zeros(m, np.int32), fresnel=np.zeros(m, np.int32),
        weight=f3(), sample_weight=f1(), normal=f3(), tangent=f3(), bitangent=f3(), alpha_x=f1(), alpha_y=f1(),
        ior=f1(), energy_scale=f1(), f0=f3(), f90=f3(), f82_b=f3(), reflection_tint=f3(), transmission_tint=f3(),
        conductor_n=f3(), conductor_k=f3(), lobe_a=f1(), lobe_b=f1(), multiscatter=f3(), emission=np.zeros(3))


# ---------------------------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _get3(a, i):
    return (a[i, 0], a[i, 1], a[i, 2])


@stage_kernel
def _set3(a, i, v):
    a[i, 0] = v[0]
    a[i, 1] = v[1]
    a[i, 2] = v[2]


@stage_kernel
def _mul3(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@stage_kernel
def _safe_ratio_max(a, b):
    """max_c(a_c / b_c), with 0 where b_c = 0 (Cycles safe_divide_color)."""
    m = -np.inf
    for c in range(3):
        r = a[c] / b[c] if b[c] != 0.0 else 0.0
        m = max(m, r)
    return m


@stage_kernel
def layering_weight(albedo, weight):
    """What a layer below keeps of `weight` under a layer of estimated albedo `albedo`
    (closure_layering_weight)."""
    return scale(weight, saturate(1.0 - _safe_ratio_max(albedo, weight)))


@stage_kernel
def rotate_around_axis(v, axis, angle):
    """Rodrigues' rotation of v about the unit axis."""
    c, s = np.cos(angle), np.sin(angle)
    k = dot(axis, v) * (1.0 - c)
    x = cross(axis, v)
    return (v[0] * c + x[0] * s + axis[0] * k, v[1] * c + x[1] * s + axis[1] * k,
            v[2] * c + x[2] * s + axis[2] * k)


@stage_kernel
def ensure_valid_specular_reflection(ng, wi, n):
    """Tilt the shading normal n toward ng just enough that the mirror direction of wi stays at
    least min(0.9 dot(ng, wi), 0.01) above the surface (Cycles bsdf_util.h; the derivation there
    reduces it to a quadratic in Nz^2 in the (ng, n) plane). n is returned unchanged when it
    equals ng or already reflects above that threshold."""
    if n[0] == ng[0] and n[1] == ng[1] and n[2] == ng[2]:
        return n
    c = 2.0 * dot(n, wi)
    r = (c * n[0] - wi[0], c * n[1] - wi[1], c * n[2] - wi[2])
    iz = dot(wi, ng)
    threshold = min(0.9 * iz, 0.01)
    if dot(ng, r) >= threshold:
        return n
    k = dot(n, ng)
    xv = (n[0] - k * ng[0], n[1] - k * ng[1], n[2] - k * ng[2])
    xl = length(xv)
    x = scale(xv, 1.0 / xl) if xl > 0.0 else n
    ix = dot(wi, x)
    a = ix * ix + iz * iz
    b = 2.0 * (a + iz * threshold)
    cc = (threshold + iz) * (threshold + iz)
    root = np.sqrt(max(b * b - 4.0 * a * cc, 0.0))
    nz2 = 0.25 * (b + root) / a if ix < 0.0 else 0.25 * (b - root) / a
    nx = np.sqrt(max(1.0 - nz2, 0.0))
    nz = np.sqrt(max(nz2, 0.0))
    return (nx * x[0] + nz * ng[0], nx * x[1] + nz * ng[1], nx * x[2] + nz * ng[2])


@stage_kernel
def _alloc(CB, count, kind, weight, n):
    """bsdf_alloc: the index of a new closure of `kind`, or -1 when its weight is below the cutoff
    or the buffer is full. Every field gets a neutral value."""
    w = (max(weight[0], 0.0), max(weight[1], 0.0), max(weight[2], 0.0))
    sw = abs(average(w))
    if not sw >= CLOSURE_WEIGHT_CUTOFF or count >= CB.kind.shape[0]:
        return -1
    i = count
    CB.kind[i] = kind
    CB.distribution[i] = GGX
    CB.fresnel[i] = FRESNEL_NONE
    _set3(CB.weight, i, w)
    CB.sample_weight[i] = sw
    _set3(CB.normal, i, n)
    t, s = orthonormals(n)
    _set3(CB.tangent, i, t)
    _set3(CB.bitangent, i, s)
    CB.alpha_x[i] = 1.0
    CB.alpha_y[i] = 1.0
    CB.ior[i] = 1.0
    CB.energy_scale[i] = 1.0
    one = (1.0, 1.0, 1.0)
    zero = (0.0, 0.0, 0.0)
    _set3(CB.f0, i, zero)
    _set3(CB.f90, i, one)
    _set3(CB.f82_b, i, zero)
    _set3(CB.reflection_tint, i, one)
    _set3(CB.transmission_tint, i, one)
    _set3(CB.conductor_n, i, zero)
    _set3(CB.conductor_k, i, zero)
    CB.lobe_a[i] = 0.0
    CB.lobe_b[i] = 0.0
    _set3(CB.multiscatter, i, zero)
    return i


@stage_kernel
def _add_transparent(CB, count, weight, n):
    """bsdf_transparent_setup: all transparency of a hit goes into one closure. Returns count."""
    if not abs(average(weight)) >= CLOSURE_WEIGHT_CUTOFF:
        return count
    for i in range(count):
        if CB.kind[i] == CLOSURE_TRANSPARENT:
            for c in range(3):
                CB.weight[i, c] += weight[c]
            CB.sample_weight[i] += abs(average(weight))
            return count
    i = _alloc(CB, count, CLOSURE_TRANSPARENT, weight, n)
    return count + 1 if i >= 0 else count


# ---------------------------------------------------------------------------------------------
# microfacet closures: setup, Fresnel setups, albedo estimate, energy compensation
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _setup_microfacet(CB, i, kind, distribution, alpha_x, alpha_y, ior, tangent):
    """bsdf_microfacet_{ggx,beckmann}[_refraction,_glass]_setup: alphas saturated, refraction and
    glass isotropic; the frame follows the tangent when the closure is anisotropic."""
    ax = saturate(alpha_x)
    ay = ax if kind != CLOSURE_REFLECTION else saturate(alpha_y)
    CB.kind[i] = kind
    CB.distribution[i] = distribution
    CB.alpha_x[i] = ax
    CB.alpha_y[i] = ay
    CB.ior[i] = ior
    CB.energy_scale[i] = 1.0
    CB.fresnel[i] = FRESNEL_NONE
    n = _get3(CB.normal, i)
    if ax != ay and dot(tangent, tangent) > 0.0:
        t, s = orthonormals_tangent(n, tangent)
        _set3(CB.tangent, i, t)
        _set3(CB.bitangent, i, s)


@stage_kernel
def _closure_fresnel_at(CB, i, cos_i):
    kind = CB.kind[i]
    return closure_fresnel(CB.fresnel[i], kind != CLOSURE_REFRACTION, kind != CLOSURE_REFLECTION, CB.ior[i],
                           cos_i, _get3(CB.f0, i), _get3(CB.f90, i), _get3(CB.f82_b, i),
                           _get3(CB.reflection_tint, i), _get3(CB.transmission_tint, i),
                           _get3(CB.conductor_n, i), _get3(CB.conductor_k, i))


@stage_kernel
def _user_roughness(CB, i):
    return np.sqrt(np.sqrt(CB.alpha_x[i] * CB.alpha_y[i]))


@stage_kernel
def estimate_albedo(CB, i, BT, wi, with_reflection, with_transmission):
    """bsdf_microfacet_estimate_albedo: Fresnel at the macro normal, the reflection part replaced
    by the albedo-weighted Schlick factor of the tables where one exists."""
    cos_ni = dot(wi, _get3(CB.normal, i))
    r, t, _ = _closure_fresnel_at(CB, i, cos_ni)
    zero = (0.0, 0.0, 0.0)
    if not with_reflection:
        r = zero
    if not with_transmission:
        t = zero
    if not (r[0] == 0.0 and r[1] == 0.0 and r[2] == 0.0):
        ft = CB.fresnel[i]
        rough = _user_roughness(CB, i)
        ior = CB.ior[i]
        if ft == FRESNEL_GENERALIZED_SCHLICK:
            z = np.sqrt(abs((ior - 1.0) / (ior + 1.0)))
            s = lookup3(BT.ggx_gen_schlick_ior_s, rough, cos_ni, z)
            r = _mul3(mix(_get3(CB.f0, i), _get3(CB.f90, i), s), _get3(CB.reflection_tint, i))
        elif ft == FRESNEL_F82_TINT:
            s = lookup3(BT.ggx_gen_schlick_s, rough, cos_ni, 0.5)
            r = mix(_get3(CB.f0, i), (1.0, 1.0, 1.0), s)
        elif ft == FRESNEL_DIELECTRIC and ior > 1.0:
            z = np.sqrt(abs((ior - 1.0) / (ior + 1.0)))
            s = lookup3(BT.ggx_gen_schlick_ior_s, rough, cos_ni, z)
            f0 = F0_from_ior(ior)
            v = f0 + (1.0 - f0) * s
            r = (v, v, v)
    return (r[0] + t[0], r[1] + t[1], r[2] + t[2])


@stage_kernel
def _preserve_energy(CB, i, BT, wi, fss):
    """microfacet_ggx_preserve_energy: scale the single-scattering lobe by 1/E(mu) and darken it
    by the Kulla-Conty multiple-scattering Fresnel F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)), so
    that f = f_ss (1 + F_ms (1 - E) / E)."""
    mu = dot(wi, _get3(CB.normal, i))
    rough = _user_roughness(CB, i)
    kind = CB.kind[i]
    if kind == CLOSURE_REFLECTION:
        e = lookup2(BT.ggx_E, rough, mu)
        e_avg = lookup1(BT.ggx_Eavg, rough)
    elif kind == CLOSURE_GLASS:
        ior = CB.ior[i]
        if ior < 1.0:
            ior = 1.0 / ior
            z = np.sqrt(abs((ior - 1.0) / (ior + 1.0)))
            e = lookup3(BT.ggx_glass_inv_E, rough, mu, z)
            e_avg = lookup2(BT.ggx_glass_inv_Eavg, rough, z)
        else:
            z = np.sqrt(abs((ior - 1.0) / (ior + 1.0)))
            e = lookup3(BT.ggx_glass_E, rough, mu, z)
            e_avg = lookup2(BT.ggx_glass_Eavg, rough, z)
    else:
        return
    if not e > 0.0:
        return
    missing = (1.0 - e) / e
    energy_scale = 1.0 + missing
    CB.energy_scale[i] = energy_scale
    if not (fss[0] == 1.0 and fss[1] == 1.0 and fss[2] == 1.0):
        # F_ss above 1 (a colour > 1) has a pole at 1 / (1 - E_avg) in Cycles' formula: clamped
        f0c, f1c, f2c = min(fss[0], 1.0), min(fss[1], 1.0), min(fss[2], 1.0)
        d0 = (1.0 + f0c * e_avg / (1.0 - f0c * (1.0 - e_avg)) * missing) / energy_scale
        d1 = (1.0 + f1c * e_avg / (1.0 - f1c * (1.0 - e_avg)) * missing) / energy_scale
        d2 = (1.0 + f2c * e_avg / (1.0 - f2c * (1.0 - e_avg)) * missing) / energy_scale
        d = (d0, d1, d2)
        CB.weight[i, 0] *= d[0]
        CB.weight[i, 1] *= d[1]
        CB.weight[i, 2] *= d[2]
        CB.sample_weight[i] *= (d[0] + d[1] + d[2]) / 3.0


@stage_kernel
def _fresnel_dielectric_setup(CB, i, BT, wi):
    """bsdf_microfacet_setup_fresnel_dielectric (the coat): always energy-compensated."""
    CB.fresnel[i] = FRESNEL_DIELECTRIC
    CB.sample_weight[i] *= average(estimate_albedo(CB, i, BT, wi, True, True))
    f = fresnel_dielectric_Fss(CB.ior[i])
    _preserve_energy(CB, i, BT, wi, (f, f, f))


@stage_kernel
def _fresnel_schlick_setup(CB, i, BT, wi, f0, f90, reflection_tint, transmission_tint, multiscatter):
    """bsdf_microfacet_setup_fresnel_generalized_schlick with a negative exponent."""
    f0 = saturate3(f0)
    CB.fresnel[i] = FRESNEL_GENERALIZED_SCHLICK
    _set3(CB.f0, i, f0)
    _set3(CB.f90, i, f90)
    _set3(CB.reflection_tint, i, reflection_tint)
    _set3(CB.transmission_tint, i, transmission_tint)
    CB.sample_weight[i] *= average(estimate_albedo(CB, i, BT, wi, True, True))
    if multiscatter:
        if transmission_tint[0] == 0.0 and transmission_tint[1] == 0.0 and transmission_tint[2] == 0.0:
            ior = CB.ior[i]
            f0r = F0_from_ior(ior)
            s = saturate((fresnel_dielectric_Fss(ior) - f0r) / (1.0 - f0r))
            fss = _mul3(reflection_tint, mix(f0, f90, s))
        else:
            fss = transmission_tint
        _preserve_energy(CB, i, BT, wi, fss)


@stage_kernel
def _fresnel_f82_setup(CB, i, BT, wi, f0, tint, multiscatter):
    CB.fresnel[i] = FRESNEL_F82_TINT
    _set3(CB.f0, i, f0)
    b = f82_tint_b(f0, tint)
    _set3(CB.f82_b, i, b)
    CB.sample_weight[i] *= average(estimate_albedo(CB, i, BT, wi, True, True))
    if multiscatter:
        _preserve_energy(CB, i, BT, wi, f82_Fss(f0, b))


@stage_kernel
def _fresnel_conductor_setup(CB, i, BT, wi, n, k, multiscatter):
    CB.fresnel[i] = FRESNEL_CONDUCTOR
    _set3(CB.conductor_n, i, n)
    _set3(CB.conductor_k, i, k)
    CB.sample_weight[i] *= average(estimate_albedo(CB, i, BT, wi, True, True))
    if multiscatter:
        _preserve_energy(CB, i, BT, wi, conductor_Fss(n, k))


@stage_kernel
def _reflection_albedo(CB, i, BT, wi):
    """bsdf_albedo(reflection only): closure weight times the albedo estimate."""
    kind = CB.kind[i]
    w = _get3(CB.weight, i)
    if kind == CLOSURE_REFLECTION or kind == CLOSURE_GLASS or kind == CLOSURE_REFRACTION:
        return _mul3(w, estimate_albedo(CB, i, BT, wi, True, False))
    return w


@stage_kernel
def _aniso_tangent(tangent, n, rotation):
    if rotation != 0.0:
        return rotate_around_axis(tangent, n, rotation * 2.0 * np.pi)
    return tangent


# ---------------------------------------------------------------------------------------------
# nodes -> closures
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _sheen_setup(CB, i, BT, wi, roughness):
    """bsdf_sheen_setup: the LTC of (mu, roughness); the closure is dropped when the fit is
    invalid there. Returns whether it was kept."""
    n = _get3(CB.normal, i)
    rough = min(max(roughness, 1e-3), 1.0)
    c = cross(n, wi)
    cl = length(c)
    if cl > 1e-12:
        s = scale(c, 1.0 / cl)
        t = cross(s, n)
    else:
        t, s = orthonormals(n)
    _set3(CB.tangent, i, t)
    _set3(CB.bitangent, i, s)
    mu = dot(n, wi)
    a = lookup2_layer(BT.sheen_ltc, 0, mu, rough)
    b = lookup2_layer(BT.sheen_ltc, 1, mu, rough)
    albedo = lookup2_layer(BT.sheen_ltc, 2, mu, rough)
    if abs(a) < 1e-5 or albedo < 1e-5:
        return False
    CB.lobe_a[i] = a
    CB.lobe_b[i] = b
    for ch in range(3):
        CB.weight[i, ch] *= albedo
    CB.sample_weight[i] *= albedo
    return True


@stage_kernel
def _diffuse_setup(CB, count, weight, n, wi, roughness, color):
    """Lambert below a roughness of 1e-5, else Oren-Nayar with `color` for its energy term."""
    if roughness < 1e-5:
        i = _alloc(CB, count, CLOSURE_DIFFUSE, weight, n)
    else:
        i = _alloc(CB, count, CLOSURE_OREN_NAYAR, weight, n)
        if i >= 0:
            a, b, ms = oren_nayar_setup(roughness, color, n, wi)
            CB.lobe_a[i] = a
            CB.lobe_b[i] = b
            _set3(CB.multiscatter, i, ms)
    return count + 1 if i >= 0 else count


@stage_kernel
def _principled(SN, BT, j, mix_weight, wi, n, ng, backfacing, tangent, CB, count):
    """CLOSURE_BSDF_PRINCIPLED_ID of svm_node_closure_bsdf, layer by layer."""
    base = (max(SN.color[j, 0], 0.0), max(SN.color[j, 1], 0.0), max(SN.color[j, 2], 0.0))
    clamped = (min(base[0], 1.0), min(base[1], 1.0), min(base[2], 1.0))
    ior = max(SN.ior[j], 1e-5)
    roughness = saturate(SN.roughness[j])
    metallic = saturate(SN.metallic[j])
    alpha = saturate(SN.alpha[j])
    valid_n = ensure_valid_specular_reflection(ng, wi, n)
    coat_n = n
    diffuse_roughness = saturate(SN.diffuse_roughness[j])
    spec_level = max(SN.specular_ior_level[j], 0.0)
    spec_tint = (max(SN.specular_tint[j, 0], 0.0), max(SN.specular_tint[j, 1], 0.0),
                 max(SN.specular_tint[j, 2], 0.0))
    anisotropic = saturate(SN.anisotropic[j])
    subsurface = saturate(SN.subsurface_weight[j])
    coat_weight = max(SN.coat_weight[j], 0.0)
    sheen_weight = max(SN.sheen_weight[j], 0.0)
    transmission = saturate(SN.transmission[j])
    multi = SN.distribution[j] == DIST_MULTI_GGX
    w = (mix_weight, mix_weight, mix_weight)

    alpha_x = roughness * roughness
    alpha_y = alpha_x
    t = (0.0, 0.0, 0.0)
    if anisotropic > 0.0 and dot(tangent, tangent) > 0.0:
        aspect = np.sqrt(1.0 - anisotropic * 0.9)
        alpha_x /= aspect
        alpha_y *= aspect
        t = _aniso_tangent(tangent, n, SN.anisotropic_rotation[j])

    if alpha < 1.0:
        count = _add_transparent(CB, count, scale(w, 1.0 - alpha), n)
        w = scale(w, alpha)

    if sheen_weight > CLOSURE_WEIGHT_CUTOFF:
        tint = (max(SN.sheen_tint[j, 0], 0.0), max(SN.sheen_tint[j, 1], 0.0), max(SN.sheen_tint[j, 2], 0.0))
        i = _alloc(CB, count, CLOSURE_SHEEN, scale(_mul3(tint, w), sheen_weight),
                   normalize(mix(n, coat_n, saturate(coat_weight))))
        if i >= 0:
            if _sheen_setup(CB, i, BT, wi, saturate(SN.sheen_roughness[j])):
                count += 1
                w = layering_weight(_get3(CB.weight, i), w)

    if coat_weight > CLOSURE_WEIGHT_CUTOFF:
        coat_roughness = saturate(SN.coat_roughness[j])
        coat_ior = max(SN.coat_ior[j], 1.0)
        coat_tint = (max(SN.coat_tint[j, 0], 0.0), max(SN.coat_tint[j, 1], 0.0), max(SN.coat_tint[j, 2], 0.0))
        valid_coat_n = ensure_valid_specular_reflection(ng, wi, coat_n)
        i = _alloc(CB, count, CLOSURE_REFLECTION, scale(w, coat_weight), valid_coat_n)
        if i >= 0:
            a = coat_roughness * coat_roughness
            _setup_microfacet(CB, i, CLOSURE_REFLECTION, GGX, a, a, coat_ior, (0.0, 0.0, 0.0))
            _fresnel_dielectric_setup(CB, i, BT, wi)
            count += 1
            w = layering_weight(_reflection_albedo(CB, i, BT, wi), w)
        if not (coat_tint[0] == 1.0 and coat_tint[1] == 1.0 and coat_tint[2] == 1.0):
            # Beer-Lambert through a coat of unit thickness along the refracted view ray
            cos_ni = dot(wi, valid_coat_n)
            cos_nt = np.sqrt(max(1.0 - (1.0 / coat_ior) ** 2 * (1.0 - cos_ni * cos_ni), 0.0))
            depth = 1.0 / cos_nt
            w = (w[0] * (1.0 + (coat_tint[0] ** depth - 1.0) * coat_weight),
                 w[1] * (1.0 + (coat_tint[1] ** depth - 1.0) * coat_weight),
                 w[2] * (1.0 + (coat_tint[2] ** depth - 1.0) * coat_weight))

    strength = SN.emission_strength[j]
    if strength != 0.0:  # attenuated by alpha, sheen and coat, not by the layers below
        for ch in range(3):
            CB.emission[ch] += SN.emission_color[j, ch] * strength * w[ch]

    if metallic > CLOSURE_WEIGHT_CUTOFF:
        i = _alloc(CB, count, CLOSURE_REFLECTION, scale(w, metallic), valid_n)
        if i >= 0:
            _setup_microfacet(CB, i, CLOSURE_REFLECTION, GGX, alpha_x, alpha_y, 1.0, t)
            f82 = (min(spec_tint[0], 1.0), min(spec_tint[1], 1.0), min(spec_tint[2], 1.0))
            _fresnel_f82_setup(CB, i, BT, wi, clamped, f82, multi)
            count += 1
        w = scale(w, 1.0 - metallic)

    if transmission > CLOSURE_WEIGHT_CUTOFF:
        i = _alloc(CB, count, CLOSURE_GLASS, scale(w, transmission), valid_n)
        if i >= 0:
            a = roughness * roughness
            _setup_microfacet(CB, i, CLOSURE_GLASS, GGX, a, a, 1.0 / ior if backfacing else ior, (0.0, 0.0, 0.0))
            f0 = scale(spec_tint, F0_from_ior(ior))
            tt = (np.sqrt(clamped[0]), np.sqrt(clamped[1]), np.sqrt(clamped[2]))
            _fresnel_schlick_setup(CB, i, BT, wi, f0, (1.0, 1.0, 1.0), (1.0, 1.0, 1.0), tt, multi)
            count += 1
        w = scale(w, 1.0 - transmission)

    eta = ior
    f0 = F0_from_ior(eta)
    if spec_level != 0.5:
        f0 *= 2.0 * spec_level
        eta = ior_from_F0(f0)
        if ior < 1.0:
            eta = 1.0 / eta

    if eta != 1.0:
        i = _alloc(CB, count, CLOSURE_REFLECTION, w, valid_n)
        if i >= 0:
            _setup_microfacet(CB, i, CLOSURE_REFLECTION, GGX, alpha_x, alpha_y, eta, t)
            _fresnel_schlick_setup(CB, i, BT, wi, scale(spec_tint, f0), (1.0, 1.0, 1.0), (1.0, 1.0, 1.0),
                                   (0.0, 0.0, 0.0), multi)
            count += 1
            w = layering_weight(_reflection_albedo(CB, i, BT, wi), w)

    if subsurface > CLOSURE_WEIGHT_CUTOFF:
        # no subsurface scattering: its BSSRDF weight becomes a Lambert lobe (documented fallback)
        count = _diffuse_setup(CB, count, scale(_mul3(clamped, w), subsurface), n, wi, 0.0, clamped)
    count = _diffuse_setup(CB, count, scale(_mul3(base, w), 1.0 - subsurface), n, wi, diffuse_roughness, base)
    return count


@stage_kernel
def _node_closures(SN, BT, j, wi, n, ng, backfacing, tangent, CB, count):
    """The closures of node row j appended from index count; returns the new count."""
    kind = SN.kind[j]
    mix_weight = SN.weight[j]
    if mix_weight == 0.0:
        return count
    if kind == NODE_PRINCIPLED:
        return _principled(SN, BT, j, mix_weight, wi, n, ng, backfacing, tangent, CB, count)
    color = (max(SN.color[j, 0], 0.0), max(SN.color[j, 1], 0.0), max(SN.color[j, 2], 0.0))
    w = scale(color, mix_weight)
    dist = SN.distribution[j]
    micro = BECKMANN if dist == DIST_BECKMANN else GGX
    multi = dist == DIST_MULTI_GGX
    if kind == NODE_DIFFUSE:
        return _diffuse_setup(CB, count, w, n, wi, SN.roughness[j], saturate3(color))
    if kind == NODE_TRANSPARENT:
        return _add_transparent(CB, count, w, n)
    if kind == NODE_TRANSLUCENT:
        i = _alloc(CB, count, CLOSURE_TRANSLUCENT, w, ensure_valid_specular_reflection(ng, wi, n))
        return count + 1 if i >= 0 else count
    if kind == NODE_SHEEN:
        i = _alloc(CB, count, CLOSURE_SHEEN, w, n)
        if i >= 0 and _sheen_setup(CB, i, BT, wi, saturate(SN.roughness[j])):
            return count + 1
        return count
    if kind == NODE_GLOSSY:
        vn = ensure_valid_specular_reflection(ng, wi, n)
        i = _alloc(CB, count, CLOSURE_REFLECTION, w, vn)
        if i < 0:
            return count
        a = saturate(SN.roughness[j]) ** 2
        aniso = min(max(SN.anisotropic[j], -0.99), 0.99)
        ax, ay, t = a, a, (0.0, 0.0, 0.0)
        if abs(aniso) > 1e-4 and dot(tangent, tangent) > 0.0:
            t = _aniso_tangent(tangent, vn, SN.anisotropic_rotation[j])
            if aniso < 0.0:
                ax, ay = a / (1.0 + aniso), a * (1.0 + aniso)
            else:
                ax, ay = a * (1.0 - aniso), a / (1.0 - aniso)
        _setup_microfacet(CB, i, CLOSURE_REFLECTION, micro, ax, ay, 1.0, t)
        if multi:
            _preserve_energy(CB, i, BT, wi, color)
        return count + 1
    if kind == NODE_REFRACTION:
        i = _alloc(CB, count, CLOSURE_REFRACTION, w, ensure_valid_specular_reflection(ng, wi, n))
        if i < 0:
            return count
        eta = max(SN.ior[j], 1e-5)
        r = SN.roughness[j]
        _setup_microfacet(CB, i, CLOSURE_REFRACTION, micro, r * r, r * r, 1.0 / eta if backfacing else eta,
                          (0.0, 0.0, 0.0))
        return count + 1
    if kind == NODE_GLASS:
        i = _alloc(CB, count, CLOSURE_GLASS, (mix_weight, mix_weight, mix_weight),
                   ensure_valid_specular_reflection(ng, wi, n))
        if i < 0:
            return count
        ior = max(SN.ior[j], 1e-5)
        a = saturate(SN.roughness[j]) ** 2
        _setup_microfacet(CB, i, CLOSURE_GLASS, micro, a, a, 1.0 / ior if backfacing else ior, (0.0, 0.0, 0.0))
        f0 = F0_from_ior(ior)
        _fresnel_schlick_setup(CB, i, BT, wi, (f0, f0, f0), (1.0, 1.0, 1.0), color, color, multi)
        return count + 1
    if kind == NODE_METALLIC:
        vn = ensure_valid_specular_reflection(ng, wi, n)
        i = _alloc(CB, count, CLOSURE_REFLECTION, (mix_weight, mix_weight, mix_weight), vn)
        if i < 0:
            return count
        r = saturate(SN.roughness[j])
        aniso = saturate(SN.anisotropic[j])
        ax, ay, t = r * r, r * r, (0.0, 0.0, 0.0)
        if aniso > 0.0 and dot(tangent, tangent) > 0.0:
            aspect = np.sqrt(1.0 - aniso * 0.9)
            ax, ay = ax / aspect, ay * aspect
            t = _aniso_tangent(tangent, n, SN.anisotropic_rotation[j])
        _setup_microfacet(CB, i, CLOSURE_REFLECTION, micro, ax, ay, 1.0, t)
        if SN.fresnel[j] == METAL_PHYSICAL:
            cn = (max(SN.conductor_n[j, 0], 0.0), max(SN.conductor_n[j, 1], 0.0), max(SN.conductor_n[j, 2], 0.0))
            ck = (max(SN.conductor_k[j, 0], 0.0), max(SN.conductor_k[j, 1], 0.0), max(SN.conductor_k[j, 2], 0.0))
            _fresnel_conductor_setup(CB, i, BT, wi, cn, ck, multi)
        else:
            tint = saturate3((SN.edge_tint[j, 0], SN.edge_tint[j, 1], SN.edge_tint[j, 2]))
            _fresnel_f82_setup(CB, i, BT, wi, saturate3(color), tint, multi)
        return count + 1
    return count


@inline_stage_kernel
def setup_surface_tangent(SN, BT, material, wi, n, ng, backfacing, tangent, CB):
    """setup_surface with a tangent for anisotropic closures ((0, 0, 0): none, isotropic)."""
    CB.emission[0] = CB.emission[1] = CB.emission[2] = 0.0
    count = 0
    start = SN.node_start[material]
    for j in range(start, start + SN.node_count[material]):
        count = _node_closures(SN, BT, j, wi, n, ng, backfacing, tangent, CB, count)
    return count


@inline_stage_kernel
def setup_surface(SN, BT, material, wi, n, ng, backfacing, CB):
    """Expand material `material`'s nodes into closures in CB; returns their count.
    wi: unit direction to the viewer; n, ng: shading and geometric normals on wi's side;
    backfacing: the ray hit the back face (glass and refraction use 1/ior)."""
    CB.emission[0] = CB.emission[1] = CB.emission[2] = 0.0
    count = 0
    start = SN.node_start[material]
    for j in range(start, start + SN.node_count[material]):
        count = _node_closures(SN, BT, j, wi, n, ng, backfacing, (0.0, 0.0, 0.0), CB, count)
    return count


# ---------------------------------------------------------------------------------------------
# evaluation and sampling of the mixture
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _is_diffuse_kind(kind):
    return kind == CLOSURE_DIFFUSE or kind == CLOSURE_OREN_NAYAR or kind == CLOSURE_TRANSLUCENT \
        or kind == CLOSURE_SHEEN


@stage_kernel
def bump_shadowing_term(ns, cn, wo, is_eval, is_diffuse):
    """kernel/closure/bsdf.h bump_shadowing_term: reject wo on the wrong side of the smooth
    normal ns when the closure normal cn differs from it, and soften diffuse closures with a GGX
    G1 (Conty Estevez et al. 2019)."""
    if cn[0] == ns[0] and cn[1] == ns[1] and cn[2] == ns[2]:
        return 1.0
    cos_nsi = dot(ns, wo)
    cos_nsn = dot(ns, cn)
    cos_ni = dot(cn, wo)
    if cos_nsi * cos_nsn * cos_ni < 0.0 and (is_eval or is_diffuse):
        return 0.0
    if not is_diffuse:
        return 1.0
    cos_i = abs(cos_nsi)
    cos_d = abs(cos_nsn)
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0
    if cos_i < 1e-6:
        return 0.0
    tan2_d = 1.0 / (cos_d * cos_d) - 1.0
    return 1.0 / (1.0 + lambda_iso(GGX, saturate(0.125 * tan2_d), cos_i))


@stage_kernel
def closure_eval(CB, i, wi, wo):
    """(f |cos_o| per channel, pdf) of closure i alone, without its weight."""
    kind = CB.kind[i]
    n = _get3(CB.normal, i)
    if kind == CLOSURE_DIFFUSE:
        v, pdf = lambert_eval(n, wo)
        return (v, v, v), pdf
    if kind == CLOSURE_OREN_NAYAR:
        return oren_nayar_eval(CB.lobe_a[i], CB.lobe_b[i], _get3(CB.multiscatter, i), n, wi, wo)
    if kind == CLOSURE_TRANSLUCENT:
        v, pdf = translucent_eval(n, wo)
        return (v, v, v), pdf
    if kind == CLOSURE_SHEEN:
        v, pdf = sheen_eval(CB.lobe_a[i], CB.lobe_b[i], _get3(CB.tangent, i), _get3(CB.bitangent, i), n, wo)
        return (v, v, v), pdf
    if kind == CLOSURE_REFLECTION or kind == CLOSURE_REFRACTION or kind == CLOSURE_GLASS:
        f, pdf = microfacet_eval(CB.distribution[i], kind != CLOSURE_REFRACTION, kind != CLOSURE_REFLECTION,
                                 CB.alpha_x[i], CB.alpha_y[i], CB.ior[i], _get3(CB.tangent, i),
                                 _get3(CB.bitangent, i), n, wi, wo, CB.fresnel[i], _get3(CB.f0, i),
                                 _get3(CB.f90, i), _get3(CB.f82_b, i), _get3(CB.reflection_tint, i),
                                 _get3(CB.transmission_tint, i), _get3(CB.conductor_n, i),
                                 _get3(CB.conductor_k, i))
        return scale(f, CB.energy_scale[i]), pdf
    return (0.0, 0.0, 0.0), 0.0  # transparent: a delta, never evaluated


@stage_kernel
def _eval_sum(CB, count, wi, wo, n, skip):
    """(sum weight_i f_i |cos|, sum sample_weight_i pdf_i, sum sample_weight_i) over closures
    other than `skip`; the sample-weight sum covers every closure but `skip`."""
    r = g = b = 0.0
    sum_pdf = 0.0
    sum_sw = 0.0
    for i in range(count):
        if i == skip:
            continue
        sw = CB.sample_weight[i]
        sum_sw += sw
        kind = CB.kind[i]
        if kind == CLOSURE_TRANSPARENT:
            continue
        bump = bump_shadowing_term(n, _get3(CB.normal, i), wo, True, _is_diffuse_kind(kind))
        if bump == 0.0:
            continue
        f, pdf = closure_eval(CB, i, wi, wo)
        if pdf != 0.0:
            r += f[0] * bump * CB.weight[i, 0]
            g += f[1] * bump * CB.weight[i, 1]
            b += f[2] * bump * CB.weight[i, 2]
            sum_pdf += pdf * sw
    return (r, g, b), sum_pdf, sum_sw


@inline_stage_kernel
def surface_eval(CB, count, BT, wi, wo, n, ng):
    """((r, g, b) = sum of weight x f x |cos|, pdf of surface_sample for wo) for the closures of
    one hit; wo below the surface evaluates the transmissive closures."""
    f, sum_pdf, sum_sw = _eval_sum(CB, count, wi, wo, n, -1)
    return f, (sum_pdf / sum_sw if sum_sw > 0.0 else 0.0)


@stage_kernel
def _closure_sample(CB, i, wi, ng, u1, u2, u3):
    """(wo, f |cos| or R/T for deltas, pdf or P_lobe for deltas, label, ok) of closure i."""
    kind = CB.kind[i]
    n = _get3(CB.normal, i)
    if kind == CLOSURE_DIFFUSE:
        wo, v, pdf, ok = lambert_sample(n, ng, u1, u2)
        return wo, (v, v, v), pdf, LABEL_REFLECT | LABEL_DIFFUSE, ok
    if kind == CLOSURE_OREN_NAYAR:
        wo, f, pdf, ok = oren_nayar_sample(CB.lobe_a[i], CB.lobe_b[i], _get3(CB.multiscatter, i), n, ng, wi, u1, u2)
        return wo, f, pdf, LABEL_REFLECT | LABEL_DIFFUSE, ok
    if kind == CLOSURE_TRANSLUCENT:
        wo, v, pdf, ok = translucent_sample(n, ng, u1, u2)
        return wo, (v, v, v), pdf, LABEL_TRANSMIT | LABEL_DIFFUSE, ok
    if kind == CLOSURE_SHEEN:
        wo, v, pdf, ok = sheen_sample(CB.lobe_a[i], CB.lobe_b[i], _get3(CB.tangent, i), _get3(CB.bitangent, i),
                                      n, ng, u1, u2)
        return wo, (v, v, v), pdf, LABEL_REFLECT | LABEL_DIFFUSE, ok
    if kind == CLOSURE_TRANSPARENT:
        return (-wi[0], -wi[1], -wi[2]), (1.0, 1.0, 1.0), 1.0, LABEL_TRANSMIT | LABEL_TRANSPARENT, True
    wo, f, pdf, refracted, singular, ok = microfacet_sample(
        CB.distribution[i], kind != CLOSURE_REFRACTION, kind != CLOSURE_REFLECTION, CB.alpha_x[i], CB.alpha_y[i],
        CB.ior[i], _get3(CB.tangent, i), _get3(CB.bitangent, i), n, ng, wi, u1, u2, u3, CB.fresnel[i],
        _get3(CB.f0, i), _get3(CB.f90, i), _get3(CB.f82_b, i), _get3(CB.reflection_tint, i),
        _get3(CB.transmission_tint, i), _get3(CB.conductor_n, i), _get3(CB.conductor_k, i))
    label = (LABEL_TRANSMIT if refracted else LABEL_REFLECT) | (LABEL_SINGULAR if singular else LABEL_GLOSSY)
    return wo, scale(f, CB.energy_scale[i]), pdf, label, ok


@inline_stage_kernel
def surface_sample(CB, count, BT, wi, n, ng, u_pick, u1, u2):
    """Sample the mixture: ((x, y, z) wo, (r, g, b) weight = f |cos| / pdf, pdf, label).
    A closure is picked in proportion to its sample weight; a rough sample is weighted against
    all closures (one-sample MIS); a delta (label SINGULAR or TRANSPARENT) returns pdf 0 and
    weight = closure weight x F / P_lobe / P_pick. An invalid sample returns weight 0, label 0."""
    zero = (0.0, 0.0, 0.0)
    if count <= 0:
        return wi, zero, 0.0, 0
    total = 0.0
    for i in range(count):
        total += CB.sample_weight[i]
    if not total > 0.0:
        return wi, zero, 0.0, 0
    r = u_pick * total
    pick = count - 1
    partial = 0.0
    for i in range(count):
        sw = CB.sample_weight[i]
        if r < partial + sw:
            pick = i
            break
        partial += sw
    sw = CB.sample_weight[pick]
    if not sw > 0.0:
        return wi, zero, 0.0, 0
    u3 = min(max((r - partial) / sw, 0.0), 1.0 - 1e-16)  # the pick's random number, rescaled
    wo, f, pdf, label, ok = _closure_sample(CB, pick, wi, ng, u1, u2, u3)
    if not ok or not pdf > 0.0:
        return wo, zero, 0.0, 0
    w = _get3(CB.weight, pick)
    kind = CB.kind[pick]
    if (label & LABEL_TRANSMIT) == 0:
        bump = bump_shadowing_term(n, _get3(CB.normal, pick), wo, False, _is_diffuse_kind(kind))
        f = scale(f, bump)
    if (label & (LABEL_SINGULAR | LABEL_TRANSPARENT)) != 0:
        k = total / (sw * pdf)
        weight = (w[0] * f[0] * k, w[1] * f[1] * k, w[2] * f[2] * k)
        if max3(weight) <= 0.0:
            return wo, zero, 0.0, 0
        return wo, weight, 0.0, label
    others, sum_pdf, _ = _eval_sum(CB, count, wi, wo, n, pick)
    fr = (w[0] * f[0] + others[0], w[1] * f[1] + others[1], w[2] * f[2] + others[2])
    mixture_pdf = (pdf * sw + sum_pdf) / total
    if not mixture_pdf > 0.0 or max3(fr) <= 0.0:
        return wo, zero, 0.0, 0
    inv = 1.0 / mixture_pdf
    return wo, (fr[0] * inv, fr[1] * inv, fr[2] * inv), mixture_pdf, label


@stage_kernel
def surface_transparency(CB, count):
    """The colour shadow rays pass through this hit: Transparent BSDF plus the Principled 1 - alpha
    part (closure_transparent_extinction); glass and refraction pass nothing."""
    r = g = b = 0.0
    for i in range(count):
        if CB.kind[i] == CLOSURE_TRANSPARENT:
            r += CB.weight[i, 0]
            g += CB.weight[i, 1]
            b += CB.weight[i, 2]
    return (r, g, b)


@stage_kernel
def surface_emission(CB):
    """Emission of the hit's Principled BSDFs (Emission Color x Strength x mix weight), attenuated
    by their alpha, sheen and coat as Cycles attenuates it; (0, 0, 0) when there is none."""
    return (CB.emission[0], CB.emission[1], CB.emission[2])


@stage_kernel
def surface_blur(CB, count, roughness):
    """Filter Glossy (Cycles surface_shader_prepare_closures / bsdf_microfacet_blur): raise every
    microfacet closure's alpha to at least `roughness` (Cycles passes 0.5 sqrt(1 - blur_pdf)); the
    energy compensation is not recomputed, as in Cycles."""
    for i in range(count):
        k = CB.kind[i]
        if k == CLOSURE_REFLECTION or k == CLOSURE_REFRACTION or k == CLOSURE_GLASS:
            CB.alpha_x[i] = max(roughness, CB.alpha_x[i])
            CB.alpha_y[i] = max(roughness, CB.alpha_y[i])


@stage_kernel
def surface_is_transmissive(CB, count):
    """Whether a sample can cross the surface (refraction, glass, translucent or transparent
    closures): the integrator's volume-stack update and shadow handling need it."""
    for i in range(count):
        k = CB.kind[i]
        if k == CLOSURE_REFRACTION or k == CLOSURE_GLASS or k == CLOSURE_TRANSLUCENT or k == CLOSURE_TRANSPARENT:
            return True
    return False


@stage_kernel
def surface_is_only_transparent(CB, count):
    """True when every closure is Transparent (a pure cut-out / pass-through surface)."""
    for i in range(count):
        if CB.kind[i] != CLOSURE_TRANSPARENT:
            return False
    return count > 0
