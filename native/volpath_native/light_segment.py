"""The part of a ray segment a light can reach, for next-event estimation in media: a spot lights
only the inside of its cone, a one-sided area light only the half-space in front of it. Medium
NEE samples its scattering distance (equiangular) on this part only and skips segments that lie
wholly outside it, as Cycles does (kernel/integrator/shade_volume.h
volume_valid_direct_ray_segment; kernel/light/spot.h spot_light_valid_ray_segment,
kernel/light/area.h area_light_valid_ray_segment, util/math_intersect.h ray_cone_intersect /
ray_plane_intersect). Other lights reach the whole segment.

The clipped part must contain every point the light reaches (else the estimate loses light), so
it is conservative: a spot with a radius is bounded by the cone of its half-angle whose apex is
moved back along the axis until the cone holds the lamp's sphere (Cycles scene/light.cpp,
ray_segment_dp = radius / sin(half angle)); the blend region lies inside the cone (the
smoothstep is 0 at its edge, light_kernels._spot_mask1).
"""
from __future__ import annotations

import numpy as np

from .jit import stage_kernel
from .light_kernels import AREA_ELLIPSE, AREA_RECT, DISK, POINT, SPHERE

# relative widening of the clipped interval against rounding at the cone's edge (attenuation 0 there)
_PAD = 1e-6


@stage_kernel
def _half_line(h0, h1, lo, hi):
    """[lo, hi] intersected with {t : h0 + t h1 >= 0}."""
    if h1 > 0.0:
        return max(lo, -h0 / h1), hi
    if h1 < 0.0:
        return lo, min(hi, -h0 / h1)
    return (lo, hi) if h0 >= 0.0 else (1.0, 0.0)


@stage_kernel
def cone_segment(ax, ay, az, px, py, pz, dx, dy, dz, cos_half, lo, hi):
    """[lo, hi] intersected with the t where p + t d (p relative to the apex, d unit) lies in the
    cone of unit axis a and half-angle acos(cos_half) (its forward nappe): (t0, t1), empty when
    t1 < t0. Along the ray n.x(t)^2 - cos^2 |x(t)|^2 is the quadratic A t^2 + B t + C; the cone is
    where it is >= 0 and a.x(t) > 0."""
    hd = ax * dx + ay * dy + az * dz
    hp = ax * px + ay * py + az * pz
    # forward half-space a.x(t) >= 0 (alone when the cone is almost a plane, as Cycles)
    lo, hi = _half_line(hp, hd, lo, hi)
    c2 = cos_half * cos_half
    if c2 < 1e-4 or not lo <= hi:
        return lo, hi
    dp = dx * px + dy * py + dz * pz
    pp = px * px + py * py + pz * pz
    A = hd * hd - c2
    B = 2.0 * (hd * hp - c2 * dp)
    C = hp * hp - c2 * pp
    disc = B * B - 4.0 * A * C
    scale = np.sqrt(pp) + 1.0
    if abs(A) < 1e-9:
        return lo, hi  # ray parallel to the cone's surface: keep the half-space (conservative)
    if disc < 0.0:
        # A < 0: the line never enters the double cone; A > 0 cannot happen but for rounding
        return (1.0, 0.0) if A < 0.0 else (lo, hi)
    # numerically stable roots
    q = -0.5 * (B + np.copysign(np.sqrt(disc), B))
    r1 = q / A
    r2 = C / q if q != 0.0 else r1
    if r1 > r2:
        r1, r2 = r2, r1
    pad = _PAD * (scale + abs(r1) + abs(r2))
    if A < 0.0:
        # direction outside the cone's angle: inside between the roots (one nappe; the half-space
        # above picked the forward one unless the chord is in the backward one)
        if hp + 0.5 * (r1 + r2) * hd < 0.0:
            return 1.0, 0.0
        return max(lo, r1 - pad), min(hi, r2 + pad)
    # direction inside the cone's angle: the forward nappe is the far side along +d when the
    # ray points along the axis, the near side otherwise
    if hd > 0.0:
        return max(lo, r2 - pad), hi
    return lo, min(hi, r1 + pad)


@stage_kernel
def light_segment(T, row, o, d, t_end):
    """(t0, t1): the part of the segment o + t d, t in [0, t_end] (d unit, t_end may be inf) that
    light `row` can reach; empty when t1 < t0 (t1 == t0 is a point: kept)."""
    k = T.kind[row]
    nx, ny, nz = T.normal[row, 0], T.normal[row, 1], T.normal[row, 2]
    cx, cy, cz = T.position[row, 0], T.position[row, 1], T.position[row, 2]
    if k == AREA_RECT or k == AREA_ELLIPSE:
        # one-sided: light leaves towards +normal only (Cycles area.h, spread pi: the plane)
        h0 = nx * (o[0] - cx) + ny * (o[1] - cy) + nz * (o[2] - cz)
        return _half_line(h0, nx * d[0] + ny * d[1] + nz * d[2], 0.0, t_end)
    if (k == POINT or k == DISK or k == SPHERE) and T.spot_smooth[row] > 0.0:
        cos_half = T.cos_half[row]
        sin_half = np.sqrt(max(1.0 - cos_half * cos_half, 0.0))
        if sin_half < 1e-7:
            return 0.0, t_end  # zero-angle spot: degenerate, left unclipped
        back = T.radius[row] / sin_half  # apex behind the lamp so the cone holds its sphere
        ax, ay, az = cx - nx * back, cy - ny * back, cz - nz * back
        return cone_segment(nx, ny, nz, o[0] - ax, o[1] - ay, o[2] - az, d[0], d[1], d[2], cos_half, 0.0, t_end)
    return 0.0, t_end
