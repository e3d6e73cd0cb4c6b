"""3-tuple vector arithmetic for the scalar BSDF kernels (no arrays: the stages call them per path
with allocation disabled)."""
from __future__ import annotations

import numpy as np

from ..jit import kernel


@kernel
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel
def mul(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@kernel
def mix(a, b, t):
    """a (1 - t) + b t per component; t is a scalar."""
    return (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t)


@kernel
def average(a):
    return (a[0] + a[1] + a[2]) * (1.0 / 3.0)


@kernel
def max3(a):
    return max(a[0], max(a[1], a[2]))


@kernel
def is_zero(a):
    return a[0] == 0.0 and a[1] == 0.0 and a[2] == 0.0


@kernel
def length(a):
    return np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@kernel
def normalize(a):
    """a / |a|, or a unchanged if |a| is zero."""
    n = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if n > 0.0:
        return (a[0] / n, a[1] / n, a[2] / n)
    return a


@kernel
def saturate(x):
    return min(max(x, 0.0), 1.0)


@kernel
def saturate3(a):
    return (min(max(a[0], 0.0), 1.0), min(max(a[1], 0.0), 1.0), min(max(a[2], 0.0), 1.0))


@kernel
def orthonormals(n):
    """Two unit tangents (t, s) with (t, s, n) right-handed: Duff et al. 2017, "Building an
    Orthonormal Basis, Revisited" (the frame of sampling.local_to_world1)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]), (b, sign + n[1] * n[1] * a, -n[1])


@kernel
def orthonormals_tangent(n, t):
    """(x, y) with y = normalize(n x t), x = y x n (Cycles kernel/sample/mapping.h
    make_orthonormals_safe_tangent): falls back to orthonormals(n) when t is parallel to n."""
    c = cross(n, t)
    cl = length(c)
    if not cl > 1e-12:
        return orthonormals(n)
    y = scale(c, 1.0 / cl)
    return cross(y, n), y


@kernel
def to_local(v, x, y, n):
    return (dot(v, x), dot(v, y), dot(v, n))


@kernel
def to_world(v, x, y, n):
    return (v[0] * x[0] + v[1] * y[0] + v[2] * n[0],
            v[0] * x[1] + v[1] * y[1] + v[2] * n[1],
            v[0] * x[2] + v[1] * y[2] + v[2] * n[2])


@kernel
def reflect(wi, h):
    """Mirror of wi about the unit normal h (both pointing away from the surface)."""
    c = 2.0 * dot(wi, h)
    return (c * h[0] - wi[0], c * h[1] - wi[1], c * h[2] - wi[2])
