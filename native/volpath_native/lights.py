"""Light sources: selection by power, sampling from a shading point, and evaluation when a ray
hits them (for MIS). Conventions follow Cycles (scene/light.cpp, kernel/light/*.h):

- point/spot, radius 0: radiant intensity I = power / (4 pi)   (eval_fac = 1 / (pi * 4)).
- point/spot, radius r, soft falloff (is_sphere = False): a disk of radius r facing the shading
  point with radiance power / (pi * 4 pi r^2)  -> 1 / (d^2 + r^2) falloff on axis (point.h).
- point/spot, radius r, no soft falloff: a sphere with that radiance; cone-sampled (point.h).
- spot: smoothstep((cos_angle - cos(size/2)) / ((1 - cos(size/2)) * blend)) (spot.h), power not
  renormalised into the cone.
- area: one-sided, radiance power / (pi * area) (area.h: eval_fac = invarea / pi).
- sun: irradiance E on a surface facing it; angle > 0 gives radiance E / (pi sin^2(angle/2))
  over a uniformly sampled cone (light.cpp SunLight).
- emissive triangles: two-sided by default (closure/emissive.h ignores the facing).
- constant world: background colour is radiance.
Lamps do not block rays: a ray that hits one picks up its emission and continues (Cycles
integrator/shade_light.h advances the ray beyond the light).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .accel import Accelerator
from .sampling import concentric_disk, local_to_world, uniform_cone, uniform_sphere
from .scene import AreaLight, PointLight, Scene, SpotLight, SunLight
from .vec import any_positive, dot as _dot, norm

POINT, SPHERE, DISK, AREA_RECT, AREA_ELLIPSE, SUN, TRIANGLE, WORLD = range(8)
_HITTABLE = (SPHERE, DISK, AREA_RECT, AREA_ELLIPSE)


def _smoothstep(f):
    f = np.clip(f, 0.0, 1.0)
    return f * f * (3.0 - 2.0 * f)


@dataclass
class LightSample:
    wi: np.ndarray        # (N,3) unit direction from the shading point to the light
    dist: np.ndarray      # (N,) distance to the sampled point (inf for distant lights)
    value: np.ndarray     # (N,3) emitted radiance / pdf (or intensity / d^2 for delta lights)
    pdf: np.ndarray       # (N,) solid-angle pdf INCLUDING the selection probability; 0 for delta


class LightSet:
    """All emitters of a scene as flat numpy tables, one row per light (each emissive triangle is
    its own row so that selection by power handles mesh lights of any size)."""

    def __init__(self, scene: Scene, accel: Accelerator):
        lo, hi = accel.bounds
        centre = 0.5 * (lo + hi)
        for light in scene.lights:
            if hasattr(light, "position"):
                lo, hi = np.minimum(lo, light.position), np.maximum(hi, light.position)
        self.scene_radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        rows = []
        for light in scene.lights:
            rows += self._lamp_rows(light)
        self.warnings: list[str] = []
        materials = scene.materials
        emission = np.array([m.emission if m.surface != "null" else np.zeros(3) for m in materials]).reshape(-1, 3)
        two_sided = np.array([m.two_sided_emission for m in materials], dtype=bool)
        if any(m.surface == "null" and m.is_emissive for m in materials):
            self.warnings.append("emission on a volume-only (null) material is ignored, as in Cycles")
        self.n_lamps = len(rows)
        tri_emissive = np.zeros(accel.triangle_count, dtype=bool)
        if len(accel.material_ids) and len(emission):
            tri_emissive = any_positive(emission[accel.material_ids])
        self.emissive_tris = np.nonzero(tri_emissive)[0]
        self.world_radiance = scene.world.background.astype(np.float64)
        n_tri = len(self.emissive_tris)
        n = self.n_lamps + n_tri + (1 if np.any(self.world_radiance > 0) else 0)
        self.count = n
        self.kind = np.zeros(n, np.int32)
        self.position = np.zeros((n, 3))
        self.strength = np.zeros((n, 3))   # radiance (area-like kinds) or intensity (point)
        self.radius = np.zeros(n)
        self.axis_u = np.zeros((n, 3))
        self.axis_v = np.zeros((n, 3))
        self.normal = np.zeros((n, 3))      # emitting direction (area), spot axis, -sun travel
        self.area = np.ones(n)
        self.cos_half = np.ones(n)          # sun cone / spot cone
        self.spot_smooth = np.zeros(n)      # 0: not a spot
        self.two_sided = np.zeros(n, bool)
        self.triangle = np.full(n, -1, np.int64)
        self.camera_visible = np.ones(n, bool)
        power = np.zeros(n)
        for i, row in enumerate(rows):
            for key, value in row.items():
                if key == "power":
                    power[i] = value
                else:
                    getattr(self, key)[i] = value
        if n_tri:
            s = slice(self.n_lamps, self.n_lamps + n_tri)
            self.kind[s] = TRIANGLE
            self.triangle[s] = self.emissive_tris
            mats = accel.material_ids[self.emissive_tris]
            self.strength[s] = emission[mats]
            self.two_sided[s] = two_sided[mats]
            self.normal[s] = accel.normals[self.emissive_tris]
            self.area[s] = accel.areas[self.emissive_tris]
            self.position[s] = accel.corners[self.emissive_tris].mean(axis=1)
            power[s] = self.strength[s].mean(axis=1) * self.area[s] * np.pi * np.where(self.two_sided[s], 2, 1)
        if n > self.n_lamps + n_tri:
            self.kind[-1] = WORLD
            self.strength[-1] = self.world_radiance
            power[-1] = self.world_radiance.mean() * 4 * np.pi ** 2 * self.scene_radius ** 2
        self.corners = accel.corners
        # One light per row chosen proportionally to its power (Cycles' light tree refines this
        # spatially; the estimator stays unbiased either way).
        total = power.sum()
        self.select_prob = power / total if total > 0 else np.zeros(n)
        self.select_cdf = np.cumsum(self.select_prob)
        if n:
            self.select_cdf[-1] = 1.0
        # Triangle id -> light row, for MIS when a ray hits an emissive triangle.
        self.row_of_triangle = np.full(accel.triangle_count, -1, np.int64)
        self.row_of_triangle[self.emissive_tris] = np.arange(self.n_lamps, self.n_lamps + n_tri)
        self.hittable_rows = np.nonzero(np.isin(self.kind, _HITTABLE) & (self.select_prob >= 0))[0]
        self.hittable_rows = self.hittable_rows[self.hittable_rows < self.n_lamps]
        self.sun_rows = np.nonzero((self.kind == SUN) & (self.cos_half < 1.0))[0]
        self.world_row = n - 1 if n and self.kind[-1] == WORLD else -1
        self.has_spots = bool(np.any(self.spot_smooth > 0))
        kinds = np.unique(self.kind)
        self.single_kind = int(kinds[0]) if len(kinds) == 1 else None

    # -----------------------------------------------------------------------------------------
    def _lamp_rows(self, light) -> list[dict]:
        rows = self._lamp_rows_geometry(light)
        for row in rows:
            row["camera_visible"] = bool(getattr(light, "visible_camera", True))
        return rows

    def _lamp_rows_geometry(self, light) -> list[dict]:
        if isinstance(light, SunLight):
            if not np.any(light.irradiance > 0):
                return []
            half = 0.5 * light.angle
            row = dict(kind=SUN, normal=-light.direction, power=light.irradiance.mean() * np.pi * self.scene_radius ** 2)
            if half > 0:
                row.update(cos_half=np.cos(half), strength=light.irradiance / (np.pi * np.sin(half) ** 2))
            else:
                row.update(strength=light.irradiance)
            return [row]
        if not np.any(light.power > 0):
            return []
        mean_power = float(light.power.mean())
        if isinstance(light, AreaLight):
            area = light.area
            kind = AREA_ELLIPSE if light.shape in ("disk", "ellipse") else AREA_RECT
            return [dict(kind=kind, position=light.position, axis_u=light.axis_u, axis_v=light.axis_v,
                         normal=light.direction, area=area, strength=light.power / (np.pi * area),
                         power=mean_power)]
        assert isinstance(light, PointLight)
        r = light.radius
        row = dict(position=light.position, radius=r, power=mean_power)
        if r <= 0:
            row.update(kind=POINT, strength=light.power / (4.0 * np.pi))
        else:
            row.update(kind=DISK if light.soft_falloff else SPHERE,
                       strength=light.power / (np.pi * 4.0 * np.pi * r * r))
        if isinstance(light, SpotLight):
            cos_half = np.cos(0.5 * np.clip(light.spot_size, 0.0, np.pi))
            blend = max(light.spot_blend, 1e-6)
            row.update(normal=light.direction, cos_half=cos_half,
                       spot_smooth=1.0 / max((1.0 - cos_half) * blend, 1e-12))
        return [row]

    # -----------------------------------------------------------------------------------------
    def select(self, u: np.ndarray) -> np.ndarray:
        return np.minimum(np.searchsorted(self.select_cdf, u, side="right"), self.count - 1)

    def has_position(self, rows: np.ndarray) -> np.ndarray:
        """Rows whose emitters sit at a finite position (usable for equiangular sampling)."""
        k = self.kind[rows]
        return (k != SUN) & (k != WORLD)

    def _spot_mask(self, rows, light_to_point_dir):
        if not self.has_spots:
            return 1.0
        smooth = self.spot_smooth[rows]
        cos_angle = _dot(light_to_point_dir, self.normal[rows])
        mask = _smoothstep((cos_angle - self.cos_half[rows]) * smooth)
        return np.where(smooth > 0, mask, 1.0)

    def sample(self, rows: np.ndarray, p: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> LightSample:
        """Sample a point/direction on light `rows[i]` as seen from p[i]."""
        n = len(rows)
        if self.single_kind is not None:  # common case: no per-kind split and scatter
            wi, dist, value, pdf = getattr(self, _SAMPLERS[self.single_kind])(rows, p, u1, u2)
            value = np.require(value, np.float64, ["W"])  # divided in place below
        else:
            wi = np.zeros((n, 3))
            wi[:, 2] = 1.0
            dist = np.full(n, np.inf)
            value = np.zeros((n, 3))
            pdf = np.zeros(n)
            kind = self.kind[rows]
            for k in np.unique(kind):
                m = np.nonzero(kind == k)[0]
                r = rows[m]
                w, d, v, pd = getattr(self, _SAMPLERS[k])(r, p[m], u1[m], u2[m])
                wi[m], dist[m], value[m], pdf[m] = w, d, v, pd
        sel = self.select_prob[rows]
        ok = sel > 0
        if ok.all():
            value /= sel[:, None]
        else:
            value = np.where(ok[:, None], value / np.where(ok, sel, 1.0)[:, None], 0.0)
        return LightSample(wi, dist, value, pdf * sel)

    def _to_light(self, rows, p):
        to = self.position[rows] - p
        d = norm(to)
        return to / np.maximum(d, 1e-30)[:, None], d

    def _sample_point(self, rows, p, u1, u2):
        wi, d = self._to_light(rows, p)
        mask = self._spot_mask(rows, -wi)
        value = self.strength[rows] * (mask / np.maximum(d * d, 1e-30))[:, None]
        return wi, d, value, np.zeros(len(rows))

    def _sample_disk(self, rows, p, u1, u2):
        to_centre, d = self._to_light(rows, p)
        light_n = -to_centre  # disk faces the shading point (point.h)
        x, y = concentric_disk(u1, u2)
        radius = self.radius[rows]
        offset = local_to_world(light_n, x * radius, y * radius, np.zeros(len(rows)))
        y_pt = self.position[rows] + offset
        to = y_pt - p
        dist = norm(to)
        wi = to / np.maximum(dist, 1e-30)[:, None]
        cos_l = np.maximum(_dot(light_n, -wi), 0.0)
        pdf = np.where(cos_l > 0, dist * dist / np.maximum(cos_l * np.pi * radius * radius, 1e-30), 0.0)
        mask = self._spot_mask(rows, -wi)  # per sampled point (spot.h)
        value = self.strength[rows] * np.where(pdf > 0, mask / np.maximum(pdf, 1e-30), 0.0)[:, None]
        return wi, dist, value, pdf

    def _sample_sphere(self, rows, p, u1, u2):
        to_centre, d = self._to_light(rows, p)
        r = self.radius[rows]
        outside = d > r
        sin2 = np.minimum((r / np.maximum(d, 1e-30)) ** 2, 1.0)
        cos_max = np.sqrt(1.0 - sin2)
        wi_cone = uniform_cone(to_centre, cos_max, u1, u2)
        pdf_cone = 1.0 / (2.0 * np.pi * np.maximum(1.0 - cos_max, 1e-12))
        wi_in = uniform_sphere(u1, u2)
        wi = np.where(outside[:, None], wi_cone, wi_in)
        pdf = np.where(outside, pdf_cone, 1.0 / (4.0 * np.pi))
        t, _ = _ray_sphere(p, wi, self.position[rows], r)
        dist = np.where(np.isfinite(t), t, d)
        mask = np.where(outside, self._spot_mask(rows, -wi), 1.0)  # no mask inside the sphere (spot.h)
        value = self.strength[rows] * (mask / pdf)[:, None]
        return wi, dist, value, pdf

    def _sample_area(self, rows, p, u1, u2, ellipse=False):
        if ellipse:
            x, y = concentric_disk(u1, u2)
            x, y = 0.5 * x, 0.5 * y
        else:
            x, y = u1 - 0.5, u2 - 0.5
        y_pt = self.position[rows] + self.axis_u[rows] * x[:, None] + self.axis_v[rows] * y[:, None]
        return self._area_measure(rows, p, y_pt, self.normal[rows], one_sided=np.ones(len(rows), bool))

    def _sample_ellipse(self, rows, p, u1, u2):
        return self._sample_area(rows, p, u1, u2, ellipse=True)

    def _area_measure(self, rows, p, y_pt, normal, one_sided):
        to = y_pt - p
        dist = norm(to)
        wi = to / np.maximum(dist, 1e-30)[:, None]
        cos_l = _dot(normal, -wi)
        cos_eff = np.where(one_sided, np.maximum(cos_l, 0.0), np.abs(cos_l))
        pdf = np.where(cos_eff > 1e-12, dist * dist / np.maximum(cos_eff * self.area[rows], 1e-30), 0.0)
        value = self.strength[rows] * np.where(pdf > 0, 1.0 / np.maximum(pdf, 1e-30), 0.0)[:, None]
        return wi, dist, value, pdf

    def _sample_triangle(self, rows, p, u1, u2):
        su = np.sqrt(u1)
        b1, b2 = 1.0 - su, u2 * su
        c = self.corners[self.triangle[rows]]
        y_pt = c[:, 0] * (1 - b1 - b2)[:, None] + c[:, 1] * b1[:, None] + c[:, 2] * b2[:, None]
        return self._area_measure(rows, p, y_pt, self.normal[rows], one_sided=~self.two_sided[rows])

    def _sample_sun(self, rows, p, u1, u2):
        n = len(rows)
        axis = self.normal[rows]
        cos_h = self.cos_half[rows]
        cone = cos_h < 1.0
        wi = np.where(cone[:, None], uniform_cone(axis, cos_h, u1, u2), axis)
        pdf = np.where(cone, 1.0 / (2.0 * np.pi * np.maximum(1.0 - cos_h, 1e-300)), 0.0)
        value = self.strength[rows] / np.where(cone, pdf, 1.0)[:, None]
        return wi, np.full(n, np.inf), value, pdf

    def _sample_world(self, rows, p, u1, u2):
        n = len(rows)
        pdf = np.full(n, 1.0 / (4.0 * np.pi))
        return uniform_sphere(u1, u2), np.full(n, np.inf), self.strength[rows] * (4.0 * np.pi), pdf

    # -----------------------------------------------------------------------------------------
    # Evaluation of emitters hit by rays (for MIS against BSDF / phase sampling)
    # -----------------------------------------------------------------------------------------
    def triangle_emission(self, prim, origins, directions, t, front):
        """Radiance and light-sampling pdf (solid angle, incl. selection) of emissive triangles hit."""
        rows = self.row_of_triangle[prim]
        hit = rows >= 0
        radiance = np.zeros((len(prim), 3))
        pdf = np.zeros(len(prim))
        if not hit.any():
            return radiance, pdf
        r = rows[hit]
        visible = self.two_sided[r] | front[hit]
        radiance[hit] = self.strength[r] * visible[:, None]
        cos_l = np.abs(_dot(self.normal[r], directions[hit]))
        pdf[hit] = self.select_prob[r] * t[hit] ** 2 / np.maximum(cos_l * self.area[r], 1e-30)
        return radiance, pdf

    def escaped_emission(self, directions):
        """List of (radiance (N,3), light pdf (N,), camera_visible) for distant emitters seen
        along directions."""
        out = []
        if self.world_row >= 0:
            n = len(directions)
            out.append((np.broadcast_to(self.world_radiance, (n, 3)),
                        np.full(n, self.select_prob[self.world_row] / (4.0 * np.pi)), True))
        for row in self.sun_rows:
            inside = directions @ self.normal[row] >= self.cos_half[row]
            pdf = self.select_prob[row] / (2.0 * np.pi * (1.0 - self.cos_half[row]))
            out.append((inside[:, None] * self.strength[row], inside * pdf, self.camera_visible[row]))
        return out

    def intersect_lamps(self, origins, directions, tmin, tmax):
        """Emission of lamps (spheres, soft point disks, area lights) crossed by the rays within
        (tmin, tmax]: list of (t (N,), radiance (N,3), light pdf (N,), camera_visible) per lamp,
        t = inf where missed.
        origins are the previous scattering vertices (the reference point of the light pdf)."""
        out = []
        for row in self.hittable_rows:
            kind = self.kind[row]
            c = self.position[row]
            n = len(origins)
            radiance = np.zeros((n, 3))
            pdf = np.zeros(n)
            if kind == SPHERE:
                t, _ = _ray_sphere(origins, directions, c[None, :], self.radius[row])
                d2 = np.sum((origins - c) ** 2, axis=1)
                r2 = self.radius[row] ** 2
                cos_max = np.sqrt(np.maximum(1.0 - r2 / np.maximum(d2, 1e-30), 0.0))
                pdf = np.where(d2 > r2, 1.0 / (2 * np.pi * np.maximum(1 - cos_max, 1e-12)), 1 / (4 * np.pi))
                light_to_origin = origins - c
            elif kind == DISK:
                light_n = origins - c
                dist_c = norm(light_n)
                light_n = light_n / np.maximum(dist_c, 1e-30)[:, None]
                t, cos_l = _ray_plane(origins, directions, c, light_n)
                hit_pt = origins + directions * np.where(np.isfinite(t), t, 0.0)[:, None]
                inside = np.sum((hit_pt - c) ** 2, axis=1) <= self.radius[row] ** 2
                t = np.where(inside, t, np.inf)
                pdf = t ** 2 / np.maximum(np.abs(cos_l) * np.pi * self.radius[row] ** 2, 1e-30)
                light_to_origin = light_n
            else:
                normal = self.normal[row]
                t, cos_l = _ray_plane(origins, directions, c, normal)
                t = np.where(cos_l < 0, t, np.inf)  # one-sided: seen from the emitting side
                hit_pt = origins + directions * np.where(np.isfinite(t), t, 0.0)[:, None] - c
                au, av = self.axis_u[row], self.axis_v[row]
                x = hit_pt @ au / (au @ au)
                y = hit_pt @ av / (av @ av)
                if kind == AREA_ELLIPSE:
                    inside = x * x + y * y <= 0.25
                else:
                    inside = (np.abs(x) <= 0.5) & (np.abs(y) <= 0.5)
                t = np.where(inside, t, np.inf)
                pdf = t ** 2 / np.maximum(np.abs(cos_l) * self.area[row], 1e-30)
                light_to_origin = None
            t = np.where((t > tmin) & (t <= tmax), t, np.inf)
            found = np.isfinite(t)
            if not found.any():
                continue
            mask = 1.0
            if light_to_origin is not None:
                dirs = light_to_origin / np.maximum(norm(light_to_origin), 1e-30)[:, None]
                mask = self._spot_mask(np.full(n, row), dirs)
            radiance = found[:, None] * self.strength[row] * np.asarray(mask).reshape(-1, 1)
            out.append((t, radiance, np.where(found, pdf * self.select_prob[row], 0.0), self.camera_visible[row]))
        return out


_SAMPLERS = {POINT: "_sample_point", SPHERE: "_sample_sphere", DISK: "_sample_disk",
             AREA_RECT: "_sample_area", AREA_ELLIPSE: "_sample_ellipse", SUN: "_sample_sun",
             TRIANGLE: "_sample_triangle", WORLD: "_sample_world"}


def _ray_sphere(o, d, centre, radius):
    """Nearest positive intersection distance of unit rays with spheres (inf if none)."""
    oc = o - centre
    b = np.einsum("ij,ij->i", oc, d)
    c = np.einsum("ij,ij->i", oc, oc) - np.asarray(radius) ** 2
    disc = b * b - c
    sq = np.sqrt(np.maximum(disc, 0.0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > 1e-9, t0, np.where(t1 > 1e-9, t1, np.inf))
    return np.where(disc >= 0, t, np.inf), disc


def _ray_plane(o, d, point, normal):
    """Distance along unit rays to a plane and cos(ray, plane normal); inf when parallel/behind."""
    normal = np.broadcast_to(normal, o.shape)
    cos = np.einsum("ij,ij->i", d, normal)
    num = np.einsum("ij,ij->i", point - o, normal)
    safe = np.where(np.abs(cos) > 1e-12, cos, 1.0)
    t = np.where(np.abs(cos) > 1e-12, num / safe, np.inf)
    return np.where(t > 1e-9, t, np.inf), cos
