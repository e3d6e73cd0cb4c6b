"""Sampling a rectangle by the solid angle it subtends: Urena, Fajardo & King 2013, "An
Area-Preserving Parametrization for Spherical Rectangles", in the form Cycles uses for
rectangular area lights seen from a surface or a volume scatter point (kernel/light/area.h
area_light_rect_sample: the internal angles by asin instead of acos, which keeps small
rectangles accurate). Uniform in solid angle, the pdf is 1 / S: the cos / distance^2 of sampling
by area drops out of the estimate. Double precision here, so the planar fallback Cycles needs
for tiny solid angles in float (S < 1e-5) applies only below 1e-12.

A rectangle: centre c, edge vectors u and v (full extent, orthogonal), seen from p."""
from __future__ import annotations

import numpy as np

from .jit import stage_kernel

_TINY_SOLID_ANGLE = 1e-12


@stage_kernel
def _safe_asin(x):
    return np.arcsin(min(max(x, -1.0), 1.0))


@stage_kernel
def _frame(px, py, pz, cx, cy, cz, ux, uy, uz, vx, vy, vz):
    """The rectangle in p's frame (x along u, y along v, z away from p's side): unit axes,
    x0 < x1, y0 < y1, z0 <= 0 and the lengths of u and v."""
    len_u = np.sqrt(ux * ux + uy * uy + uz * uz)
    len_v = np.sqrt(vx * vx + vy * vy + vz * vz)
    iu, iv = 1.0 / max(len_u, 1e-300), 1.0 / max(len_v, 1e-300)
    ax, ay, az = ux * iu, uy * iu, uz * iu
    bx, by, bz = vx * iv, vy * iv, vz * iv
    zx, zy, zz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    dx, dy, dz = cx - px, cy - py, cz - pz
    z0 = dx * zx + dy * zy + dz * zz
    if z0 > 0.0:  # z points against the rectangle
        zx, zy, zz, z0 = -zx, -zy, -zz, -z0
    xc = dx * ax + dy * ay + dz * az
    yc = dx * bx + dy * by + dz * bz
    return (ax, ay, az, bx, by, bz, zx, zy, zz, xc - 0.5 * len_u, xc + 0.5 * len_u, yc - 0.5 * len_v,
            yc + 0.5 * len_v, z0, len_u, len_v, np.sqrt(dx * dx + dy * dy + dz * dz))


@stage_kernel
def _angles(x0, x1, y0, y1, z0):
    """Unit normals' components of the four sides (nz of area.h) and the internal-angle terms
    g0..g3; the solid angle is -(g0 + g1 + g2 + g3)."""
    z2 = z0 * z0
    n0 = -y0 / np.sqrt(y0 * y0 + z2)
    n1 = x1 / np.sqrt(x1 * x1 + z2)
    n2 = y1 / np.sqrt(y1 * y1 + z2)
    n3 = -x0 / np.sqrt(x0 * x0 + z2)
    return (n0, n1, n2, n3, _safe_asin(-n0 * n1), _safe_asin(-n1 * n2), _safe_asin(-n2 * n3),
            _safe_asin(-n3 * n0))


@stage_kernel
def _pdf_of(S, n0, n1, n2, n3, z0, len_u, len_v, dist):
    """1 / S, or the planar pdf at the centre where S is too small to compute (area.h)."""
    if S < _TINY_SOLID_ANGLE or min(min(n0 * n0, n1 * n1), min(n2 * n2, n3 * n3)) > 1.0 - 1e-12:
        return -dist * dist * dist / (z0 * len_u * len_v) if z0 < 0.0 else 0.0
    return 1.0 / S


@stage_kernel
def rectangle_solid_angle_pdf(px, py, pz, cx, cy, cz, ux, uy, uz, vx, vy, vz):
    """Solid-angle pdf of rectangle_sample from p: 1 / (the solid angle the rectangle subtends),
    0 for a point in its plane."""
    f = _frame(px, py, pz, cx, cy, cz, ux, uy, uz, vx, vy, vz)
    x0, x1, y0, y1, z0, len_u, len_v, dist = f[9], f[10], f[11], f[12], f[13], f[14], f[15], f[16]
    if not z0 < 0.0:
        return 0.0
    n0, n1, n2, n3, g0, g1, g2, g3 = _angles(x0, x1, y0, y1, z0)
    return _pdf_of(-(g0 + g1 + g2 + g3), n0, n1, n2, n3, z0, len_u, len_v, dist)


@stage_kernel
def rectangle_sample(px, py, pz, cx, cy, cz, ux, uy, uz, vx, vy, vz, r1, r2):
    """A point (x, y, z) on the rectangle, uniform in the solid angle it subtends from p, for
    uniforms r1, r2; and its solid-angle pdf (0, and the centre, for p in the rectangle's plane)."""
    ax, ay, az, bx, by, bz, zx, zy, zz, x0, x1, y0, y1, z0, len_u, len_v, dist = _frame(
        px, py, pz, cx, cy, cz, ux, uy, uz, vx, vy, vz)
    if not z0 < 0.0:
        return cx, cy, cz, 0.0
    n0, n1, n2, n3, g0, g1, g2, g3 = _angles(x0, x1, y0, y1, z0)
    S = -(g0 + g1 + g2 + g3)
    b0, b1 = n0, n2
    au = r1 * S + g2 + g3
    sin_au = np.sin(au)
    fu = (np.cos(au) * b0 + b1) / sin_au if sin_au != 0.0 else 0.0
    cu = min(max(np.copysign(1.0 / np.sqrt(fu * fu + b0 * b0), fu), -1.0), 1.0)
    xu = min(max(-(cu * z0) / max(np.sqrt(1.0 - cu * cu), 1e-12), x0), x1)
    d2 = xu * xu + z0 * z0
    h0 = y0 / np.sqrt(d2 + y0 * y0)
    h1 = y1 / np.sqrt(d2 + y1 * y1)
    hv = h0 + r2 * (h1 - h0)
    hv2 = hv * hv
    yv = hv * np.sqrt(d2 / (1.0 - hv2)) if hv2 < 1.0 - 1e-12 else y1
    yv = min(max(yv, y0), y1)
    return (px + xu * ax + yv * bx + z0 * zx, py + xu * ay + yv * by + z0 * zy, pz + xu * az + yv * bz + z0 * zz,
            _pdf_of(S, n0, n1, n2, n3, z0, len_u, len_v, dist))
