"""Henyey-Greenstein phase function, parameterised around the ray's travel direction:
cos_theta = dot(ray direction, scattered direction), so g > 0 scatters forward (Cycles
kernel/closure/volume_util.h; pbrt-v4 uses the opposite sign convention for wo).

hg_eval1 / hg_sample1 are what the compiled stages call; hg_eval / hg_sample loop over them for
numpy callers (tests, quadratures). Mixtures of overlapping media of different g are evaluated and
sampled by path_kernels (_phase_mixture_eval, _phase_mixture_sample) on the scene tables."""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .sampling import local_to_world1

INV_4PI = 1.0 / (4.0 * np.pi)


@kernel
def hg_eval1(g, cos_theta):
    """Phase value (= pdf of hg_sample1), per steradian."""
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_4PI * (1.0 - g * g) / (denom * np.sqrt(max(denom, 1e-30)))


@kernel
def hg_sample1(d0, d1, d2, g, u1, u2):
    """One HG direction around the travel direction d (cos_theta by inverting its CDF);
    returns (x, y, z, pdf)."""
    if abs(g) < 1e-3:
        cos_t = 1.0 - 2.0 * u1
    else:
        sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1)
        cos_t = (1.0 + g * g - sq * sq) / (2.0 * g)
    cos_t = min(max(cos_t, -1.0), 1.0)
    sin_t = np.sqrt(max(1.0 - cos_t * cos_t, 0.0))
    phi = 2.0 * np.pi * u2
    x, y, z = local_to_world1(d0, d1, d2, sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
    return x, y, z, hg_eval1(g, cos_t)


def hg_eval(g, cos_theta) -> np.ndarray:
    """hg_eval1 elementwise over broadcast g and cos_theta (any shapes)."""
    shape = np.broadcast_shapes(np.shape(g), np.shape(cos_theta))
    out = np.empty(shape)
    _hg_eval_many(np.array(np.broadcast_to(g, shape), np.float64).reshape(-1),
                  np.array(np.broadcast_to(cos_theta, shape), np.float64).reshape(-1), out.reshape(-1))
    return out


def hg_sample(directions: np.ndarray, g, u1: np.ndarray, u2: np.ndarray):
    """hg_sample1 per row of unit travel directions (N, 3); g scalar or (N,). Returns (wo, pdf)."""
    n = len(u1)
    wo, pdf = np.empty((n, 3)), np.empty(n)
    _hg_sample_many(np.ascontiguousarray(directions, np.float64),
                    np.array(np.broadcast_to(g, (n,)), np.float64),
                    np.ascontiguousarray(u1, np.float64), np.ascontiguousarray(u2, np.float64), wo, pdf)
    return wo, pdf


@kernel
def _hg_eval_many(g, cos_theta, out):
    for i in range(out.shape[0]):
        out[i] = hg_eval1(g[i], cos_theta[i])


@kernel
def _hg_sample_many(d, g, u1, u2, wo, pdf):
    for i in range(u1.shape[0]):
        wo[i, 0], wo[i, 1], wo[i, 2], pdf[i] = hg_sample1(d[i, 0], d[i, 1], d[i, 2], g[i], u1[i], u2[i])
