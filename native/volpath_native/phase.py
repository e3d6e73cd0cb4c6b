"""Henyey-Greenstein phase function, parameterised around the ray's travel direction:
cos_theta = dot(ray direction, scattered direction), so g > 0 scatters forward (Cycles
kernel/closure/volume_util.h; pbrt-v4 uses the opposite sign convention for wo)."""
from __future__ import annotations

import numpy as np

from .sampling import local_to_world

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
