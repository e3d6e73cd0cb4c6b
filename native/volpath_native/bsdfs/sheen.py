"""Sheen lobe: Zeltner, Burley & Chiang 2022, "Practical Multiple-Scattering Sheen Using Linearly
Transformed Cosines", as Cycles 5.0 kernel/closure/bsdf_sheen.h uses it.

The lobe is a clamped cosine warped by M^-1 = [[a, 0, b], [0, a, 0], [0, 0, 1]] in the frame
(t, s, n) whose t axis is wi projected on the tangent plane: D(wo) = cos'/pi |M^-1| / |M^-1 wo|^3
= z (a / |M^-1 wo|^2)^2 / pi. Sampling draws a cosine direction and maps it through M. It
integrates to 1 over the sphere; the part below the horizon is lost (eval clamps z >= 0), and the
closure weight carries the fitted albedo R. (a, b, R) come from tables.sheen_ltc indexed by
(mu = dot(n, wi), roughness), see sheen_fit.py for how our table is made.
"""
from __future__ import annotations

import numpy as np

from ..jit import kernel
from ..sampling import concentric_disk1
from .vector import dot, normalize, to_local, to_world

INV_PI = 1.0 / np.pi


@kernel
def sheen_eval(a, b, t, s, n, wo):
    """(f |cos_o|, pdf) of the normalised lobe (the albedo is in the closure weight)."""
    o = to_local(wo, t, s, n)
    x = a * o[0] + b * o[2]
    y = a * o[1]
    len_sq = x * x + y * y + o[2] * o[2]
    if not len_sq > 0.0:
        return 0.0, 0.0
    r = a / len_sq
    v = INV_PI * max(o[2], 0.0) * r * r
    return v, v


@kernel
def sheen_sample(a, b, t, s, n, ng, u1, u2):
    """(wo, f |cos|, pdf, ok)."""
    dx, dy = concentric_disk1(u1, u2)
    dz = np.sqrt(max(1.0 - dx * dx - dy * dy, 0.0))
    o = normalize((dx - dz * b, dy, dz * a))
    wo = to_world(o, t, s, n)
    if dot(ng, wo) <= 0.0 or o[2] <= 0.0:
        return wo, 0.0, 0.0, False
    x = a * o[0] + b * o[2]
    y = a * o[1]
    len_sq = x * x + y * y + o[2] * o[2]
    r = a / len_sq
    v = INV_PI * o[2] * r * r
    return wo, v, v, True
