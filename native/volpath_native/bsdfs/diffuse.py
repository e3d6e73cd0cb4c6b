"""Diffuse lobes (Cycles 5.0 kernel/closure/bsdf_diffuse.h and bsdf_oren_nayar.h). Each eval
returns (f |cos_o|, pdf) without the closure weight; samples are cosine-weighted about n (or -n
for Translucent) through the concentric disk (kernel/sample/mapping.h sample_cos_hemisphere) and
are rejected when they fall on the wrong side of the geometric normal ng.

Oren-Nayar: Fujii's improved model (https://mimosa-pudica.net/improved-oren-nayar.html) with the
OpenPBR energy-compensation term, as bsdf_oren_nayar.h: A = 1 / (pi + sigma (pi/2 - 2/3)),
B = sigma A, E(mu) = pi A + B G(mu), E_avg = pi A + (2 pi - 5.6) B / 3.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from ..sampling import concentric_disk1
from .vector import dot, orthonormals, saturate

INV_PI = 1.0 / np.pi


@kernel
def cosine_sample(n, u1, u2):
    """(wo, cos) cosine-distributed about the unit vector n."""
    dx, dy = concentric_disk1(u1, u2)
    z = np.sqrt(max(1.0 - dx * dx - dy * dy, 0.0))
    t, s = orthonormals(n)
    return (dx * t[0] + dy * s[0] + z * n[0], dx * t[1] + dy * s[1] + z * n[1],
            dx * t[2] + dy * s[2] + z * n[2]), z


@kernel
def lambert_eval(n, wo):
    c = max(dot(n, wo), 0.0) * INV_PI
    return c, c


@kernel
def lambert_sample(n, ng, u1, u2):
    """(wo, f |cos|, pdf, ok)."""
    wo, z = cosine_sample(n, u1, u2)
    if dot(ng, wo) > 0.0 and z > 0.0:
        return wo, z * INV_PI, z * INV_PI, True
    return wo, 0.0, 0.0, False


@kernel
def translucent_eval(n, wo):
    c = max(-dot(n, wo), 0.0) * INV_PI
    return c, c


@kernel
def translucent_sample(n, ng, u1, u2):
    wo, z = cosine_sample((-n[0], -n[1], -n[2]), u1, u2)
    if dot(ng, wo) < 0.0 and z > 0.0:
        return wo, z * INV_PI, z * INV_PI, True
    return wo, 0.0, 0.0, False


@kernel
def _oren_nayar_G(cos_t):
    if cos_t < 1e-6:  # the tan term misbehaves; Taylor expansion
        return (0.5 * np.pi - 2.0 / 3.0) - cos_t
    sin_t = np.sqrt(max(1.0 - cos_t * cos_t, 0.0))
    theta = np.arccos(min(cos_t, 1.0))
    return sin_t * (theta - 2.0 / 3.0 - sin_t * cos_t) + 2.0 / 3.0 * (sin_t / cos_t) * (1.0 - sin_t * sin_t * sin_t)


@kernel
def oren_nayar_setup(roughness, color, n, wi):
    """(A, B, multiscatter colour) for roughness sigma and albedo colour (saturated here)."""
    sigma = saturate(roughness)
    a = 1.0 / (np.pi + sigma * (0.5 * np.pi - 2.0 / 3.0))
    b = sigma * a
    e_avg = a * np.pi + ((2.0 * np.pi - 5.6) / 3.0) * b
    nv = max(dot(n, wi), 0.0)
    e_v = a * np.pi + b * _oren_nayar_G(nv)
    c0, c1, c2 = saturate(color[0]), saturate(color[1]), saturate(color[2])
    k = INV_PI * (e_avg / (1.0 - e_avg)) * (1.0 - e_v)
    return a, b, (k * c0 * c0 / (1.0 - c0 * (1.0 - e_avg)), k * c1 * c1 / (1.0 - c1 * (1.0 - e_avg)),
                  k * c2 * c2 / (1.0 - c2 * (1.0 - e_avg)))


@kernel
def _oren_nayar_value(a, b, ms, n, wi, wo):
    nl = max(dot(n, wo), 0.0)
    if b <= 0.0:
        v = nl * INV_PI
        return (v, v, v)
    nv = max(dot(n, wi), 0.0)
    t = dot(wo, wi) - nl * nv
    if t > 0.0:
        t /= max(nl, nv) + 1e-38
    single = a + b * t
    e_l = a * np.pi + b * _oren_nayar_G(nl)
    return (nl * (single + ms[0] * (1.0 - e_l)), nl * (single + ms[1] * (1.0 - e_l)),
            nl * (single + ms[2] * (1.0 - e_l)))


@kernel
def oren_nayar_eval(a, b, ms, n, wi, wo):
    """(f |cos_o| per channel, pdf)."""
    c = dot(n, wo)
    if c > 0.0:
        return _oren_nayar_value(a, b, ms, n, wi, wo), c * INV_PI
    return (0.0, 0.0, 0.0), 0.0


@kernel
def oren_nayar_sample(a, b, ms, n, ng, wi, u1, u2):
    """(wo, f |cos| per channel, pdf, ok)."""
    wo, z = cosine_sample(n, u1, u2)
    if dot(ng, wo) > 0.0 and z > 0.0:
        return wo, _oren_nayar_value(a, b, ms, n, wi, wo), z * INV_PI, True
    return wo, (0.0, 0.0, 0.0), 0.0, False
