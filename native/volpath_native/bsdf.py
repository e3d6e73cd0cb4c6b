"""Surface scattering. Only Lambertian exists so far; 'null' surfaces are handled by the
integrator as pure boundaries (no BSDF). New BSDF kinds add eval/sample pairs here."""
from __future__ import annotations

import numpy as np

from .sampling import cosine_hemisphere


def lambert_eval(albedo: np.ndarray, normal: np.ndarray, wi: np.ndarray):
    """f * |cos| and the cosine-sampling pdf for directions wi; normal faces the viewer."""
    cos = np.einsum("ij,ij->i", normal, wi)
    pos = np.maximum(cos, 0.0)
    return albedo * (pos / np.pi)[:, None], pos / np.pi


def lambert_sample(albedo: np.ndarray, normal: np.ndarray, u1: np.ndarray, u2: np.ndarray):
    """Cosine-weighted direction; returns (wi, weight = f*cos/pdf = albedo, pdf)."""
    wi, cos = cosine_hemisphere(normal, u1, u2)
    return wi, albedo, cos / np.pi
