"""Surface scattering, one path at a time for the compiled stages. Only Lambertian exists so far;
'null' surfaces are handled by the integrator as pure boundaries (no BSDF). A new BSDF kind adds an
eval/sample pair here and a branch in path_kernels._surface."""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .sampling import cosine_hemisphere1


@kernel
def lambert_eval1(albedo, n, wi):
    """(f |cos| per channel, cosine-sampling pdf) toward unit wi; n is the shading normal facing
    the incoming ray."""
    cos = max(n[0] * wi[0] + n[1] * wi[1] + n[2] * wi[2], 0.0)
    pdf = cos / np.pi
    return (albedo[0] * pdf, albedo[1] * pdf, albedo[2] * pdf), pdf


@kernel
def lambert_sample1(n, u1, u2):
    """Cosine-weighted direction around n: (wi, pdf); the weight f cos / pdf is the albedo."""
    x, y, z, cos = cosine_hemisphere1(n[0], n[1], n[2], u1, u2)
    return (x, y, z), cos / np.pi
