"""Light sampling and evaluation for one path at a time, compiled with numba, so the integrator's
kernels can sample and evaluate emitters per path. lights.LightSet builds the tables (LightTables)
and its numpy-facing methods are loops over these functions.

Conventions follow Cycles (scene/light.cpp, kernel/light/*.h); see lights.py for the list. Each
function takes the tables T and one row/ray as scalars and returns a tuple of floats.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .jit import inline_stage_kernel, stage_kernel
from .mis import mis_weight
from .motion_triangles import deformed_corners1, is_deforming
from .sampling import concentric_disk1, local_to_world1, uniform_cone1, uniform_sphere1
from .spherical_rectangle import rectangle_sample, rectangle_solid_angle_pdf

POINT, SPHERE, DISK, AREA_RECT, AREA_ELLIPSE, SUN, TRIANGLE, WORLD = range(8)

LightTables = namedtuple("LightTables", [
    "kind",            # (n,) int32, one of the constants above
    "position",        # (n,3) lamp centre; triangle centroid
    "strength",        # (n,3) radiance (area-like kinds, sun cone, world) or intensity (point, delta sun)
    "radius",          # (n,) sphere / soft-point radius
    "axis_u",          # (n,3) area light edge vectors (full extent)
    "axis_v",          # (n,3)
    "normal",          # (n,3) emitting direction (area, triangle), spot axis, -sun travel direction
    "area",            # (n,)
    "cos_half",        # (n,) sun cone / spot cone half-angle cosine
    "spot_smooth",     # (n,) 1 / ((1 - cos_half) * blend); 0: not a spot
    "two_sided",       # (n,) bool, emissive triangles
    "triangle",        # (n,) int64 triangle id of TRIANGLE rows, else -1
    "camera_visible",  # (n,) bool
    "select_prob",     # (n,) probability of selecting the row (by power)
    "select_cdf",      # (n,) cumulative select_prob, last entry 1
    "corners",         # (T,3,3) all triangles of the scene
    "row_of_triangle",  # (T,) int64 light row of each triangle, -1 if not emissive
    "deform_rows",     # accel's deformation tables: moving emissive triangles at a ray's time
    "deform_corners",  # (motion_triangles.py)
    "hittable_rows",   # (H,) int64 lamps a ray can hit (sphere, soft point disk, area)
    "sun_rows",        # (S,) int64 suns with a cone (angle > 0)
    "world_row",       # int, -1 without a world emitter
    "world_radiance",  # (3,)
    "count",           # int, number of rows
    "tree",            # light_tree.LightTreeTables: per-point selection (or the static one above)
])

_INF = np.inf
_FOUR_PI = 4.0 * np.pi


# ---------------------------------------------------------------------------------------------
# Ray tests and small helpers
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _ray_sphere1(ox, oy, oz, dx, dy, dz, cx, cy, cz, radius):
    """Nearest intersection distance > 1e-9 of a unit ray with a sphere (inf if none)."""
    px, py, pz = ox - cx, oy - cy, oz - cz
    b = px * dx + py * dy + pz * dz
    c = px * px + py * py + pz * pz - radius * radius
    disc = b * b - c
    if disc < 0.0:
        return _INF
    sq = np.sqrt(disc)
    if -b - sq > 1e-9:
        return -b - sq
    if -b + sq > 1e-9:
        return -b + sq
    return _INF


@stage_kernel
def _ray_plane1(ox, oy, oz, dx, dy, dz, px, py, pz, nx, ny, nz):
    """Distance > 1e-9 along a unit ray to the plane through p with normal n (inf when parallel
    or behind), and cos(ray, n)."""
    cos = dx * nx + dy * ny + dz * nz
    if abs(cos) <= 1e-12:
        return _INF, cos
    t = ((px - ox) * nx + (py - oy) * ny + (pz - oz) * nz) / cos
    return (t if t > 1e-9 else _INF), cos


@stage_kernel
def _spot_mask1(T, row, lx, ly, lz):
    """Spot cone attenuation for the unit direction l from the light to the shading point:
    smoothstep((cos_angle - cos_half) / ((1 - cos_half) * blend)) (Cycles kernel/light/spot.h
    spot_attenuation); 1 for lights that are not spots."""
    smooth = T.spot_smooth[row]
    if smooth <= 0.0:
        return 1.0
    cos_angle = lx * T.normal[row, 0] + ly * T.normal[row, 1] + lz * T.normal[row, 2]
    f = min(max((cos_angle - T.cos_half[row]) * smooth, 0.0), 1.0)
    return f * f * (3.0 - 2.0 * f)


@stage_kernel
def _unit(x, y, z):
    d = np.sqrt(x * x + y * y + z * z)
    inv = 1.0 / max(d, 1e-30)
    return x * inv, y * inv, z * inv, d


# ---------------------------------------------------------------------------------------------
# Selection
# ---------------------------------------------------------------------------------------------
@stage_kernel
def cdf_row(cdf, count, u):
    """Row with cdf[row-1] <= u < cdf[row] (searchsorted right), clamped to count - 1 (-1 when
    count is 0)."""
    lo, hi = 0, count
    while lo < hi:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid + 1
        else:
            hi = mid
    return np.int64(min(lo, count - 1))


@stage_kernel
def select_light(T, u):
    """The light chosen by power: cdf_row of the selection cdf."""
    return cdf_row(T.select_cdf, T.count, u)


@stage_kernel
def light_has_position(T, row):
    """Whether the row's emitter sits at a finite position (usable for equiangular sampling)."""
    k = T.kind[row]
    return k != SUN and k != WORLD


@stage_kernel
def light_position(T, row):
    return T.position[row, 0], T.position[row, 1], T.position[row, 2]


@stage_kernel
def equiangular_centre(T, row, u1, u2, time):
    """The point equiangular sampling of a medium segment aims at, drawn with the (u1, u2) the next
    event then samples light `row` with: on area lamps and emissive triangles a point uniform by
    area, as Cycles aims at the light sample it draws for the whole segment
    (kernel/integrator/shade_volume.h integrate_volume_sample_direct_light: equiangular_coeffs->P
    = ls->P, area lights sampled by area in a volume segment) and samples the light again from
    the vertex with the same numbers; a large lamp then spreads the distances over the segment
    where its parts are close. Unbiased: given (u1, u2) the distance has the equiangular pdf
    about this point, and for each distance the light sample keeps its own pdf (for emitters
    sampled by area it is this very point; a rectangle is then sampled by solid angle). Other
    lights: their centre."""
    k = T.kind[row]
    if k == AREA_RECT or k == AREA_ELLIPSE:
        return _area_point(T, row, u1, u2, k == AREA_ELLIPSE)
    if k == TRIANGLE:
        yx, yy, yz, _, _, _, _ = _triangle_point(T, row, u1, u2, time)
        return yx, yy, yz
    return T.position[row, 0], T.position[row, 1], T.position[row, 2]


# ---------------------------------------------------------------------------------------------
# Sampling: (wx, wy, wz, dist, value r, g, b, pdf) before the selection probability
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _sample_point(T, row, px, py, pz):
    """Delta point/spot light: intensity / d^2 (Cycles kernel/light/point.h, radius 0)."""
    wx, wy, wz, d = _unit(T.position[row, 0] - px, T.position[row, 1] - py, T.position[row, 2] - pz)
    s = _spot_mask1(T, row, -wx, -wy, -wz) / max(d * d, 1e-30)
    return wx, wy, wz, d, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, 0.0


@stage_kernel
def _sample_disk(T, row, px, py, pz, u1, u2):
    """Soft-falloff point light: a disk of the lamp's radius facing the shading point, sampled by
    area (Cycles kernel/light/point.h, !is_sphere); spot mask per sampled point (spot.h)."""
    cx, cy, cz = T.position[row, 0], T.position[row, 1], T.position[row, 2]
    nx, ny, nz, _ = _unit(px - cx, py - cy, pz - cz)  # disk normal points at the shading point
    x, y = concentric_disk1(u1, u2)
    radius = T.radius[row]
    ox, oy, oz = local_to_world1(nx, ny, nz, x * radius, y * radius, 0.0)
    wx, wy, wz, dist = _unit(cx + ox - px, cy + oy - py, cz + oz - pz)
    cos_l = max(-(nx * wx + ny * wy + nz * wz), 0.0)
    pdf = dist * dist / max(cos_l * np.pi * radius * radius, 1e-30) if cos_l > 0.0 else 0.0
    s = _spot_mask1(T, row, -wx, -wy, -wz) / max(pdf, 1e-30) if pdf > 0.0 else 0.0
    return wx, wy, wz, dist, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, pdf


@stage_kernel
def _sample_sphere(T, row, px, py, pz, u1, u2):
    """Sphere light: uniform cone of the sphere's solid angle from outside, uniform sphere from
    inside (Cycles kernel/light/point.h, is_sphere); spot mask only from outside (spot.h)."""
    cx, cy, cz = T.position[row, 0], T.position[row, 1], T.position[row, 2]
    ax, ay, az, d = _unit(cx - px, cy - py, cz - pz)
    r = T.radius[row]
    if d > r:
        sin2 = min((r / max(d, 1e-30)) ** 2, 1.0)
        cos_max = np.sqrt(1.0 - sin2)
        wx, wy, wz = uniform_cone1(ax, ay, az, cos_max, u1, u2)
        pdf = 1.0 / (2.0 * np.pi * max(1.0 - cos_max, 1e-12))
        mask = _spot_mask1(T, row, -wx, -wy, -wz)
    else:
        wx, wy, wz = uniform_sphere1(u1, u2)
        pdf = 1.0 / _FOUR_PI
        mask = 1.0
    t = _ray_sphere1(px, py, pz, wx, wy, wz, cx, cy, cz, r)
    dist = t if t < _INF else d
    s = mask / pdf
    return wx, wy, wz, dist, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, pdf


@stage_kernel
def _sample_surface_point(T, row, px, py, pz, yx, yy, yz, one_sided, nx, ny, nz, area):
    """Point y sampled uniformly by area on a flat emitter (unit normal n, area): area pdf
    converted to solid angle, dist^2 / (cos_light * area) (Cycles kernel/light/area.h, triangle.h)."""
    wx, wy, wz, dist = _unit(yx - px, yy - py, yz - pz)
    cos_l = -(nx * wx + ny * wy + nz * wz)
    cos_eff = max(cos_l, 0.0) if one_sided else abs(cos_l)
    pdf = dist * dist / max(cos_eff * area, 1e-30) if cos_eff > 1e-12 else 0.0
    s = 1.0 / max(pdf, 1e-30) if pdf > 0.0 else 0.0
    return wx, wy, wz, dist, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, pdf


@stage_kernel
def _area_point(T, row, u1, u2, ellipse):
    """The point of a rectangle / ellipse lamp that (u1, u2) select, uniform by area."""
    if ellipse:
        x, y = concentric_disk1(u1, u2)
        x, y = 0.5 * x, 0.5 * y
    else:
        x, y = u1 - 0.5, u2 - 0.5
    return (T.position[row, 0] + T.axis_u[row, 0] * x + T.axis_v[row, 0] * y,
            T.position[row, 1] + T.axis_u[row, 1] * x + T.axis_v[row, 1] * y,
            T.position[row, 2] + T.axis_u[row, 2] * x + T.axis_v[row, 2] * y)


@stage_kernel
def _sample_area(T, row, px, py, pz, u1, u2, ellipse):
    """Area light, one-sided (Cycles kernel/light/area.h): a rectangle uniform in the solid angle
    it subtends (area_light_rect_sample), an ellipse uniform by area."""
    if not ellipse:
        return _sample_rectangle(T, row, px, py, pz, u1, u2)
    yx, yy, yz = _area_point(T, row, u1, u2, True)
    return _sample_surface_point(T, row, px, py, pz, yx, yy, yz, True, T.normal[row, 0], T.normal[row, 1],
                                 T.normal[row, 2], T.area[row])


@stage_kernel
def _sample_rectangle(T, row, px, py, pz, u1, u2):
    """Rectangle light by solid angle (spherical_rectangle.py); nothing from behind it (area.h
    area_light_sample)."""
    cx, cy, cz = T.position[row, 0], T.position[row, 1], T.position[row, 2]
    nx, ny, nz = T.normal[row, 0], T.normal[row, 1], T.normal[row, 2]
    if (cx - px) * nx + (cy - py) * ny + (cz - pz) * nz >= 0.0:
        return 0.0, 0.0, 1.0, _INF, 0.0, 0.0, 0.0, 0.0
    yx, yy, yz, pdf = rectangle_sample(px, py, pz, cx, cy, cz, T.axis_u[row, 0], T.axis_u[row, 1], T.axis_u[row, 2],
                                       T.axis_v[row, 0], T.axis_v[row, 1], T.axis_v[row, 2], u1, u2)
    wx, wy, wz, dist = _unit(yx - px, yy - py, yz - pz)
    s = 1.0 / pdf if pdf > 0.0 else 0.0
    return wx, wy, wz, dist, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, pdf


@stage_kernel
def triangle_sample_barycentrics(u1, u2):
    """Barycentrics (b1, b2) of corners 1 and 2 of the point _sample_triangle draws from (u1, u2)
    (uniform by area); a textured emitter is evaluated there (path_kernels)."""
    su = np.sqrt(u1)
    return 1.0 - su, u2 * su


@stage_kernel
def _triangle_point(T, row, u1, u2, time):
    """The point of an emissive triangle that (u1, u2) select, uniform by area, where the
    triangle is at shutter time `time`, with its unit normal and area then."""
    b1, b2 = triangle_sample_barycentrics(u1, u2)
    b0 = 1.0 - b1 - b2
    prim = T.triangle[row]
    if is_deforming(T.deform_rows, prim):
        c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z = deformed_corners1(T.deform_rows, T.deform_corners, prim, time)
        nx, ny, nz, area = _triangle_normal_area(c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z)
    else:
        c = T.corners[prim]
        c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z = (c[0, 0], c[0, 1], c[0, 2], c[1, 0], c[1, 1], c[1, 2],
                                                       c[2, 0], c[2, 1], c[2, 2])
        nx, ny, nz, area = T.normal[row, 0], T.normal[row, 1], T.normal[row, 2], T.area[row]
    return (c0x * b0 + c1x * b1 + c2x * b2, c0y * b0 + c1y * b1 + c2y * b2, c0z * b0 + c1z * b1 + c2z * b2,
            nx, ny, nz, area)


@stage_kernel
def _sample_triangle(T, row, px, py, pz, u1, u2, time):
    """Emissive triangle, uniform by area (Cycles kernel/light/triangle.h area sampling); a moving
    one where it is at the ray's shutter time, with its normal and area then (Cycles
    triangle_light_sample: triangle_world_space_vertices at the time; the selection stays by the
    frame's area, as Cycles' distribution_area at a fixed time)."""
    yx, yy, yz, nx, ny, nz, area = _triangle_point(T, row, u1, u2, time)
    return _sample_surface_point(T, row, px, py, pz, yx, yy, yz, not T.two_sided[row], nx, ny, nz, area)


@stage_kernel
def _triangle_normal_area(c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z):
    """Unit normal (counter-clockwise corners: outward) and area of a triangle."""
    e1x, e1y, e1z = c1x - c0x, c1y - c0y, c1z - c0z
    e2x, e2y, e2z = c2x - c0x, c2y - c0y, c2z - c0z
    x, y, z = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    length = np.sqrt(x * x + y * y + z * z)
    inverse = 1.0 / max(length, 1e-30)
    return x * inverse, y * inverse, z * inverse, 0.5 * length


@stage_kernel
def moving_triangle_normal_area(T, prim, time):
    """(unit normal, area) of emissive triangle prim at shutter time `time` (its frame's when it
    does not move)."""
    if is_deforming(T.deform_rows, prim):
        c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z = deformed_corners1(T.deform_rows, T.deform_corners, prim, time)
        return _triangle_normal_area(c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z)
    row = T.row_of_triangle[prim]
    return T.normal[row, 0], T.normal[row, 1], T.normal[row, 2], T.area[row]


@stage_kernel
def _sample_sun(T, row, u1, u2):
    """Sun: uniform over its cone when it has an angle, else a delta direction with irradiance as
    value (Cycles kernel/light/distant.h)."""
    ax, ay, az = T.normal[row, 0], T.normal[row, 1], T.normal[row, 2]
    cos_h = T.cos_half[row]
    if cos_h < 1.0:
        wx, wy, wz = uniform_cone1(ax, ay, az, cos_h, u1, u2)
        pdf = 1.0 / (2.0 * np.pi * max(1.0 - cos_h, 1e-300))
        s = 1.0 / pdf
    else:
        wx, wy, wz = ax, ay, az
        pdf = 0.0
        s = 1.0
    return wx, wy, wz, _INF, T.strength[row, 0] * s, T.strength[row, 1] * s, T.strength[row, 2] * s, pdf


@stage_kernel
def _sample_world(T, row, u1, u2):
    """Constant background, uniform sphere (Cycles kernel/light/background.h without an
    importance map)."""
    wx, wy, wz = uniform_sphere1(u1, u2)
    return (wx, wy, wz, _INF, T.strength[row, 0] * _FOUR_PI, T.strength[row, 1] * _FOUR_PI,
            T.strength[row, 2] * _FOUR_PI, 1.0 / _FOUR_PI)


@inline_stage_kernel
def sample_light(T, row, px, py, pz, u1, u2, time):
    """Sample light `row` as seen from p at shutter time `time` (moving emissive triangles move;
    lamps do not, as in Cycles): (wx, wy, wz, dist, vr, vg, vb, pdf) with w the unit
    direction to the light, dist the distance to the sampled point (inf for distant lights),
    v = emitted radiance / pdf (intensity / d^2 for delta lights) divided by the selection
    probability, pdf = solid-angle pdf times the selection probability (0 for delta lights);
    the static selection by power (sample_light_selected takes any)."""
    return sample_light_selected(T, row, T.select_prob[row], px, py, pz, u1, u2, time)


@inline_stage_kernel
def sample_light_selected(T, row, sel, px, py, pz, u1, u2, time):
    """sample_light for a row chosen with probability sel (light_tree.tree_select)."""
    k = T.kind[row]
    if k == POINT:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_point(T, row, px, py, pz)
    elif k == DISK:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_disk(T, row, px, py, pz, u1, u2)
    elif k == SPHERE:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_sphere(T, row, px, py, pz, u1, u2)
    elif k == AREA_RECT or k == AREA_ELLIPSE:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_area(T, row, px, py, pz, u1, u2, k == AREA_ELLIPSE)
    elif k == TRIANGLE:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_triangle(T, row, px, py, pz, u1, u2, time)
    elif k == SUN:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_sun(T, row, u1, u2)
    elif k == WORLD:
        wx, wy, wz, dist, vr, vg, vb, pdf = _sample_world(T, row, u1, u2)
    else:
        wx, wy, wz, dist, vr, vg, vb, pdf = 0.0, 0.0, 1.0, _INF, 0.0, 0.0, 0.0, 0.0
    if sel > 0.0:
        inv = 1.0 / sel
        vr, vg, vb = vr * inv, vg * inv, vb * inv
    else:
        vr, vg, vb = 0.0, 0.0, 0.0
    return wx, wy, wz, dist, vr, vg, vb, pdf * sel


# ---------------------------------------------------------------------------------------------
# Evaluation of emitters found by BSDF / phase sampling (for MIS against light sampling)
# ---------------------------------------------------------------------------------------------
@stage_kernel
def triangle_emission(T, prim, ox, oy, oz, dx, dy, dz, t, front, time):
    """Radiance and light-sampling pdf (solid angle, incl. the static selection) of triangle
    `prim` hit at distance t along the unit ray o + t d from the previous vertex o at shutter time
    `time` (a moving triangle's normal and area then: Cycles triangle_light_pdf); zeros if prim
    does not emit. Two-sided unless the material says otherwise (Cycles closure/emissive.h)."""
    r, g, b, pdf, row = triangle_emission_unselected(T, prim, dx, dy, dz, t, front, time)
    return r, g, b, (pdf * T.select_prob[row] if row >= 0 else 0.0)


@stage_kernel
def triangle_emission_unselected(T, prim, dx, dy, dz, t, front, time):
    """triangle_emission without the selection probability: (r, g, b, solid-angle pdf, row)."""
    if prim < 0 or prim >= T.row_of_triangle.shape[0]:
        return 0.0, 0.0, 0.0, 0.0, np.int64(-1)
    row = T.row_of_triangle[prim]
    if row < 0:
        return 0.0, 0.0, 0.0, 0.0, np.int64(-1)
    visible = 1.0 if (T.two_sided[row] or front) else 0.0
    nx, ny, nz, area = moving_triangle_normal_area(T, prim, time)
    cos_l = abs(nx * dx + ny * dy + nz * dz)
    pdf = t * t / max(cos_l * area, 1e-30)
    return T.strength[row, 0] * visible, T.strength[row, 1] * visible, T.strength[row, 2] * visible, pdf, row


@stage_kernel
def distant_emission(T, row, dx, dy, dz):
    """Radiance and light pdf (incl. the static selection) of the world or a sun cone seen along
    unit d (Cycles kernel/light/background.h, distant.h distant_light_intersect)."""
    r, g, b, pdf = distant_emission_unselected(T, row, dx, dy, dz)
    return r, g, b, pdf * T.select_prob[row]


@stage_kernel
def distant_emission_unselected(T, row, dx, dy, dz):
    """distant_emission without the selection probability."""
    if T.kind[row] == WORLD:
        return T.world_radiance[0], T.world_radiance[1], T.world_radiance[2], 1.0 / _FOUR_PI
    cos_h = T.cos_half[row]
    if cos_h >= 1.0 or dx * T.normal[row, 0] + dy * T.normal[row, 1] + dz * T.normal[row, 2] < cos_h:
        return 0.0, 0.0, 0.0, 0.0
    return T.strength[row, 0], T.strength[row, 1], T.strength[row, 2], 1.0 / (2.0 * np.pi * (1.0 - cos_h))


@stage_kernel
def escaped_emission_mis(T, dx, dy, dz, prev_pdf, camera_ray):
    """MIS-weighted radiance of every distant emitter (world, sun cones) seen along unit d by a
    ray sampled with pdf prev_pdf (0: camera ray or delta scattering, full weight). Emitters
    hidden from the camera give nothing to camera rays."""
    r, g, b = 0.0, 0.0, 0.0
    if T.world_row >= 0:
        er, eg, eb, pdf = distant_emission(T, T.world_row, dx, dy, dz)
        w = mis_weight(prev_pdf, pdf)
        r, g, b = r + er * w, g + eg * w, b + eb * w
    for i in range(T.sun_rows.shape[0]):
        row = T.sun_rows[i]
        if camera_ray and not T.camera_visible[row]:
            continue
        er, eg, eb, pdf = distant_emission(T, row, dx, dy, dz)
        if pdf > 0.0:
            w = mis_weight(prev_pdf, pdf)
            r, g, b = r + er * w, g + eg * w, b + eb * w
    return r, g, b


@stage_kernel
def lamp_crossing(T, k, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """Lamp T.hittable_rows[k] crossed by the unit ray o + t d within (tmin, tmax]: (t, r, g, b,
    pdf), t = inf if missed; pdf is the light-sampling pdf from o (the previous scattering vertex)
    incl. the static selection. Lamps do not block rays (Cycles integrator/shade_light.h). The
    caller checks T.camera_visible itself."""
    t, r, g, b, pdf = lamp_crossing_unselected(T, k, ox, oy, oz, dx, dy, dz, tmin, tmax)
    return t, r, g, b, pdf * T.select_prob[T.hittable_rows[k]]


@stage_kernel
def lamp_crossing_unselected(T, k, ox, oy, oz, dx, dy, dz, tmin, tmax):
    """lamp_crossing without the selection probability."""
    row = T.hittable_rows[k]
    kind = T.kind[row]
    cx, cy, cz = T.position[row, 0], T.position[row, 1], T.position[row, 2]
    mask = 1.0
    if kind == SPHERE:
        # pdf of the cone sampling in _sample_sphere (Cycles point.h point_light_pdf)
        r = T.radius[row]
        t = _ray_sphere1(ox, oy, oz, dx, dy, dz, cx, cy, cz, r)
        lx, ly, lz, dc = _unit(ox - cx, oy - cy, oz - cz)
        d2, r2 = dc * dc, r * r
        if d2 > r2:
            cos_max = np.sqrt(max(1.0 - r2 / max(d2, 1e-30), 0.0))
            pdf = 1.0 / (2.0 * np.pi * max(1.0 - cos_max, 1e-12))
        else:
            pdf = 1.0 / _FOUR_PI
        mask = _spot_mask1(T, row, lx, ly, lz)
    elif kind == DISK:
        # the disk faces the previous vertex, as when it was sampled from there (point.h)
        nx, ny, nz, _ = _unit(ox - cx, oy - cy, oz - cz)
        t, cos_l = _ray_plane1(ox, oy, oz, dx, dy, dz, cx, cy, cz, nx, ny, nz)
        if t < _INF:
            hx, hy, hz = ox + dx * t - cx, oy + dy * t - cy, oz + dz * t - cz
            if hx * hx + hy * hy + hz * hz > T.radius[row] ** 2:
                t = _INF
        pdf = t * t / max(abs(cos_l) * np.pi * T.radius[row] ** 2, 1e-30)
        mask = _spot_mask1(T, row, nx, ny, nz)
    else:
        # rectangle / ellipse, one-sided: seen from the emitting side only (area.h)
        nx, ny, nz = T.normal[row, 0], T.normal[row, 1], T.normal[row, 2]
        t, cos_l = _ray_plane1(ox, oy, oz, dx, dy, dz, cx, cy, cz, nx, ny, nz)
        if cos_l >= 0.0:
            t = _INF
        if t < _INF:
            hx, hy, hz = ox + dx * t - cx, oy + dy * t - cy, oz + dz * t - cz
            ux, uy, uz = T.axis_u[row, 0], T.axis_u[row, 1], T.axis_u[row, 2]
            vx, vy, vz = T.axis_v[row, 0], T.axis_v[row, 1], T.axis_v[row, 2]
            x = (hx * ux + hy * uy + hz * uz) / (ux * ux + uy * uy + uz * uz)
            y = (hx * vx + hy * vy + hz * vz) / (vx * vx + vy * vy + vz * vz)
            if kind == AREA_ELLIPSE:
                inside = x * x + y * y <= 0.25
            else:
                inside = abs(x) <= 0.5 and abs(y) <= 0.5
            if not inside:
                t = _INF
        if kind == AREA_ELLIPSE:
            pdf = t * t / max(abs(cos_l) * T.area[row], 1e-30)
        elif t > tmin and t <= tmax and t < _INF:  # the solid-angle pdf of _sample_rectangle from o
            pdf = rectangle_solid_angle_pdf(ox, oy, oz, cx, cy, cz, T.axis_u[row, 0], T.axis_u[row, 1],
                                            T.axis_u[row, 2], T.axis_v[row, 0], T.axis_v[row, 1], T.axis_v[row, 2])
        else:
            pdf = 0.0  # missed: not computed
    if not (t > tmin and t <= tmax) or t == _INF:
        return _INF, 0.0, 0.0, 0.0, 0.0
    return t, T.strength[row, 0] * mask, T.strength[row, 1] * mask, T.strength[row, 2] * mask, pdf


# ---------------------------------------------------------------------------------------------
# Loops behind LightSet's numpy-facing methods
# ---------------------------------------------------------------------------------------------
@stage_kernel
def select_many(T, u, out):
    for i in range(u.shape[0]):
        out[i] = select_light(T, u[i])


@stage_kernel
def has_position_many(T, rows, out):
    for i in range(rows.shape[0]):
        out[i] = light_has_position(T, rows[i])


@stage_kernel
def sample_many(T, rows, p, u1, u2, times, wi, dist, value, pdf):
    for i in range(rows.shape[0]):
        (wi[i, 0], wi[i, 1], wi[i, 2], dist[i], value[i, 0], value[i, 1], value[i, 2],
         pdf[i]) = sample_light(T, rows[i], p[i, 0], p[i, 1], p[i, 2], u1[i], u2[i], times[i])


@stage_kernel
def triangle_emission_many(T, prim, o, d, t, front, times, radiance, pdf):
    for i in range(prim.shape[0]):
        radiance[i, 0], radiance[i, 1], radiance[i, 2], pdf[i] = triangle_emission(
            T, prim[i], o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], t[i], front[i], times[i])


@stage_kernel
def distant_emission_many(T, row, d, radiance, pdf):
    for i in range(d.shape[0]):
        radiance[i, 0], radiance[i, 1], radiance[i, 2], pdf[i] = distant_emission(T, row, d[i, 0], d[i, 1], d[i, 2])


@stage_kernel
def lamp_crossing_many(T, k, o, d, tmin, tmax, t, radiance, pdf):
    """lamp_crossing for every ray; returns how many rays cross the lamp."""
    found = 0
    for i in range(o.shape[0]):
        t[i], radiance[i, 0], radiance[i, 1], radiance[i, 2], pdf[i] = lamp_crossing(
            T, k, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2], tmin[i], tmax[i])
        if t[i] < _INF:
            found += 1
    return found
