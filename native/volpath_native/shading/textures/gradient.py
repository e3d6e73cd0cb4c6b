"""Gradient Texture node (Cycles src/kernel/svm/gradient.h `svm_gradient`, `svm_node_tex_gradient`)."""
from __future__ import annotations

import math

import numpy as np

from ...jit import stage_kernel

#: Cycles svm/types.h NodeGradientType
(GRADIENT_LINEAR, GRADIENT_QUADRATIC, GRADIENT_EASING, GRADIENT_DIAGONAL, GRADIENT_RADIAL,
 GRADIENT_QUADRATIC_SPHERE, GRADIENT_SPHERICAL) = range(7)
GRADIENT_TYPES = {"LINEAR": GRADIENT_LINEAR, "QUADRATIC": GRADIENT_QUADRATIC, "EASING": GRADIENT_EASING,
                  "DIAGONAL": GRADIENT_DIAGONAL, "RADIAL": GRADIENT_RADIAL,
                  "QUADRATIC_SPHERE": GRADIENT_QUADRATIC_SPHERE, "SPHERICAL": GRADIENT_SPHERICAL}
#: gradient.h: 0.999999f - |p| so that a unit vector gives exactly 0
SPHERE_BIAS = float(np.float32(0.999999))


@stage_kernel
def gradient_texture(gradient_type, x, y, z):
    """gradient.h `svm_gradient`, saturated as `svm_node_tex_gradient` (Fac; Color is (f, f, f))."""
    if gradient_type == GRADIENT_LINEAR:
        f = x
    elif gradient_type == GRADIENT_QUADRATIC:
        r = max(x, 0.0)
        f = r * r
    elif gradient_type == GRADIENT_EASING:
        r = min(max(x, 0.0), 1.0)
        t = r * r
        f = 3.0 * t - 2.0 * t * r
    elif gradient_type == GRADIENT_DIAGONAL:
        f = (x + y) * 0.5
    elif gradient_type == GRADIENT_RADIAL:
        f = math.atan2(y, x) / (2.0 * math.pi) + 0.5
    else:
        r = max(SPHERE_BIAS - math.sqrt(x * x + y * y + z * z), 0.0)
        f = r * r if gradient_type == GRADIENT_QUADRATIC_SPHERE else r
    if not f >= 0.0:  # saturatef; NaN -> 0 as fminf/fmaxf do
        return 0.0
    return min(f, 1.0)
