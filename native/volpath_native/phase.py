"""Henyey-Greenstein phase function, parameterised around the ray's travel direction:
cos_theta = dot(ray direction, scattered direction), so g > 0 scatters forward (Cycles
kernel/closure/volume_util.h; pbrt-v4 uses the opposite sign convention for wo)."""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .sampling import local_to_world, local_to_world1

INV_4PI = 1.0 / (4.0 * np.pi)


def hg_eval(g: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """Phase value (= pdf of hg_sample), per steradian."""
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_4PI * (1.0 - g * g) / (denom * np.sqrt(np.maximum(denom, 1e-30)))


def hg_sample(directions: np.ndarray, g: np.ndarray, u1: np.ndarray, u2: np.ndarray):
    """Sample scattered directions around the travel directions; returns (wo, pdf)."""
    g = np.broadcast_to(np.asarray(g, dtype=np.float64), u1.shape)
    isotropic = np.abs(g) < 1e-3
    safe_g = np.where(isotropic, 1.0, g)
    sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1)
    cos_t = np.where(isotropic, 1.0 - 2.0 * u1, (1.0 + g * g - sq * sq) / (2.0 * safe_g))
    cos_t = np.clip(cos_t, -1.0, 1.0)
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    phi = 2.0 * np.pi * u2
    wo = local_to_world(directions, sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t)
    return wo, hg_eval(g, cos_t)


# Mixtures: where media with different g overlap, the phase function is
# sum_k sigma_s,k HG(g_k) / sigma_s (per channel). Cycles evaluates every volume closure weighted
# by its sample weight (kernel/integrator/volume_shader.h _volume_shader_phase_eval_mis) and picks
# one closure by sample weight to sample a direction (volume_shader_phase_pick, which rescales
# the random number so it can be reused); closures with equal g are merged first
# (volume_shader_merge_closures).

def hg_mixture_pdf(probabilities: np.ndarray, g: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
    """sum_k p_k HG(g_k, cos) for component probabilities (N, K) summing to 1 and g (K,)."""
    return np.einsum("nk,nk->n", probabilities, hg_eval(g[None, :], cos_theta[:, None]))


def hg_mixture_sample(directions: np.ndarray, probabilities: np.ndarray, g: np.ndarray,
                      u1: np.ndarray, u2: np.ndarray):
    """Pick component k with probability p_k (u1 decides, then is rescaled into the chosen
    interval and reused, as Cycles' volume_shader_phase_pick) and sample HG(g_k).
    Returns (wo, mixture pdf of wo, chosen component)."""
    cdf = np.cumsum(probabilities, axis=1)
    cdf[:, -1] = np.maximum(cdf[:, -1], 1.0)  # rounding must never leave u1 past the last bin
    k = np.minimum((u1[:, None] >= cdf).sum(axis=1), probabilities.shape[1] - 1)
    rows = np.arange(len(k))
    lower = np.where(k > 0, cdf[rows, np.maximum(k - 1, 0)], 0.0)
    p_k = probabilities[rows, k]
    u_within = np.clip((u1 - lower) / np.where(p_k > 0, p_k, 1.0), 0.0, 1.0 - 1e-12)
    wo, _ = hg_sample(directions, g[k], u_within, u2)
    return wo, hg_mixture_pdf(probabilities, g, _cosine(directions, wo)), k


def _cosine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


# ---------------------------------------------------------------------------------------------
# Scalar forms for the compiled kernels
# ---------------------------------------------------------------------------------------------
@kernel
def hg_eval1(g, cos_theta):
    denom = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_4PI * (1.0 - g * g) / (denom * np.sqrt(max(denom, 1e-30)))


@kernel
def hg_sample1(d0, d1, d2, g, u1, u2):
    """One HG direction around the travel direction d; returns (x, y, z, pdf)."""
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
