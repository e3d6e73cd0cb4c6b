"""Light sources: selection by power, sampling from a shading point, and evaluation when a ray
hits them (for MIS). Conventions follow Cycles (scene/light.cpp, kernel/light/*.h):

- point/spot, radius 0: radiant intensity I = power / (4 pi)   (eval_fac = 1 / (pi * 4)).
- point/spot, radius r, soft falloff (is_sphere = False): a disk of radius r facing the shading
  point with radiance power / (pi * 4 pi r^2)  -> 1 / (d^2 + r^2) falloff on axis (point.h).
- point/spot, radius r, no soft falloff: a sphere with that radiance; cone-sampled (point.h).
- spot: smoothstep((cos_angle - cos(size/2)) / ((1 - cos(size/2)) * blend)) (spot.h), power not
  renormalised into the cone.
- area: one-sided, radiance power / (pi * area) (area.h: eval_fac = invarea / pi); a rectangle
  is sampled uniformly in the solid angle it subtends (spherical_rectangle.py), an ellipse by area.
- sun: irradiance E on a surface facing it; angle > 0 gives radiance E / (pi sin^2(angle/2))
  over a uniformly sampled cone (light.cpp SunLight).
- emissive triangles: two-sided by default (closure/emissive.h ignores the facing).
- constant world: background colour is radiance.
Lamps do not block rays: a ray that hits one picks up its emission and continues (Cycles
integrator/shade_light.h advances the ray beyond the light).

LightSet builds flat tables (LightSet.tables, a light_kernels.LightTables); sampling and
evaluation are the compiled per-path functions of light_kernels, and the array methods below are
loops over them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .accel import Accelerator
from .light_tree import build_light_tree, tree_pdf_many, tree_select_many
from .light_kernels import (AREA_ELLIPSE, AREA_RECT, DISK, POINT, SPHERE, SUN, TRIANGLE, WORLD, LightTables,
                            distant_emission_many, has_position_many, lamp_crossing_many, sample_many,
                            select_many, triangle_emission_many)
from .scene import AreaLight, PointLight, Scene, SpotLight, SunLight

_HITTABLE = (SPHERE, DISK, AREA_RECT, AREA_ELLIPSE)


def any_positive(a: np.ndarray) -> np.ndarray:
    """Rows of an (N, 3) array with a positive component."""
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2]) > 0


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
        # the light tree's energy of each row (scene/light_tree.cpp LightTreeEmitter: intensity of
        # point lights, power / pi of area lights, irradiance of suns, area x emission of triangles)
        self.tree_energy = np.zeros(n)
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
            # a material whose emission is a surface program: unit strength here, the program's
            # radiance is multiplied in where the light is hit or sampled (surface_programs.py);
            # its constant emission is an estimate that only weighs the light's selection
            textured = np.array([_has_program_emission(m) for m in materials], dtype=bool)
            if textured.any():
                self.strength[s] = np.where(textured[mats][:, None], 1.0, self.strength[s])
            self.two_sided[s] = two_sided[mats]
            self.normal[s] = accel.normals[self.emissive_tris]
            self.area[s] = accel.areas[self.emissive_tris]
            self.position[s] = accel.triangle_corners(self.emissive_tris).mean(axis=1)
            power[s] = emission[mats].mean(axis=1) * self.area[s] * np.pi * np.where(self.two_sided[s], 2, 1)
            self.tree_energy[s] = emission[mats].mean(axis=1) * self.area[s]
        if n > self.n_lamps + n_tri:
            self.kind[-1] = WORLD
            self.strength[-1] = self.world_radiance
            # Weighed against suns as Cycles' light tree weighs distant lights: the background's
            # energy pi x average radiance (irradiance of an upward surface) against the sun's
            # irradiance (scene/light_tree.cpp, LightTreeEmitter: LIGHT_BACKGROUND strength x pi,
            # LIGHT_DISTANT strength), both over the scene's cross-section pi R^2. (The world's
            # power through the whole bounding sphere, 4 pi^2 R^2 L, picked it 4x as often: on the
            # noise cloud's floor, lit by the sun, that was most of the error.)
            power[-1] = self.world_radiance.mean() * np.pi ** 2 * self.scene_radius ** 2
            self.tree_energy[-1] = self.world_radiance.mean() * np.pi  # LIGHT_BACKGROUND: x pi
        # corners of every triangle, indexed by triangle id: only mesh lights read them
        self.corners = accel.corners if n_tri else np.zeros((0, 3, 3))
        if n > self.n_lamps + n_tri and np.any(power[:-1] > 0):
            # Cycles disables the background light of a world shader that does not vary over
            # directions (scene/light.cpp, LightManager::test_enabled_lights: "Background MIS has
            # been disabled"): next events never pick it and escaped rays take its full radiance
            # (its selection pdf is 0, so their MIS weight is 1). VolPath's world is one colour.
            # Picking it anyway cost the noise cloud's floor most of its error: the sky's
            # full-sphere cone made the distant branch's lower importance bound 0, so the tree
            # over-picked the point light against the sun (README, Benchmarks). As the scene's only
            # emitter it stays selectable (a next event where Cycles samples none: unbiased either way).
            power[-1] = 0.0
            self.tree_energy[-1] = 0.0
        # One light per row chosen proportionally to its power (Cycles' light tree refines this
        # spatially; the estimator stays unbiased either way).
        total = power.sum()
        self.select_prob = power / total if total > 0 else np.zeros(n)
        self.select_cdf = np.cumsum(self.select_prob)
        if n:
            # rows of probability 0 at the end (the world above) are never reached by rounding
            selectable = np.nonzero(self.select_prob > 0)[0]
            self.select_cdf[selectable[-1] if len(selectable) else n - 1:] = 1.0
        # Triangle id -> light row, for MIS when a ray hits an emissive triangle.
        self.row_of_triangle = np.full(accel.triangle_count, -1, np.int64)
        self.row_of_triangle[self.emissive_tris] = np.arange(self.n_lamps, self.n_lamps + n_tri)
        self.hittable_rows = np.nonzero(np.isin(self.kind, _HITTABLE) & (self.select_prob >= 0))[0]
        self.hittable_rows = self.hittable_rows[self.hittable_rows < self.n_lamps]
        self.sun_rows = np.nonzero((self.kind == SUN) & (self.cos_half < 1.0))[0]
        self.world_row = n - 1 if n and self.kind[-1] == WORLD else -1
        # moving emissive triangles are sampled at a ray's time from accel's deformation tables
        moving = n_tri and accel.has_deformation and bool(np.any(accel.deform_rows[self.emissive_tris, 0] >= 0))
        self._deform_rows = accel.deform_rows if moving else np.full((1, 4), -1, np.int64)
        self._deform_corners = accel.deform_corners if moving else np.zeros((1, 3, 3), np.float32)
        # per-point selection (Cycles' light tree; RenderSettings.light_tree, Cycles' use_light_tree)
        self.use_tree = bool(getattr(scene.settings, "light_tree", True))
        # With a single emitter the tree can only pick it or nothing: the static selection gives the
        # same image without the tree's cost per next event (measured: 1.5-1.8x the render time of
        # a one-point-light fog box).
        self.tree = build_light_tree(self, enabled=self.use_tree and int(np.count_nonzero(self.tree_energy > 0)) > 1)
        self.tables = self._tables()

    def _tables(self) -> LightTables:
        """The tables in the fixed dtypes/layouts the compiled kernels are specialised for (one
        compilation serves every scene)."""
        def f64(a):
            return np.ascontiguousarray(a, dtype=np.float64)

        def i64(a):
            return np.ascontiguousarray(a, dtype=np.int64)

        def flag(a):
            return np.ascontiguousarray(a, dtype=np.bool_)

        return LightTables(
            kind=np.ascontiguousarray(self.kind, dtype=np.int32), position=f64(self.position),
            strength=f64(self.strength), radius=f64(self.radius), axis_u=f64(self.axis_u),
            axis_v=f64(self.axis_v), normal=f64(self.normal), area=f64(self.area), cos_half=f64(self.cos_half),
            spot_smooth=f64(self.spot_smooth), two_sided=flag(self.two_sided), triangle=i64(self.triangle),
            camera_visible=flag(self.camera_visible), select_prob=f64(self.select_prob),
            select_cdf=f64(self.select_cdf), corners=f64(self.corners).reshape(-1, 3, 3),
            row_of_triangle=i64(self.row_of_triangle), deform_rows=self._deform_rows,
            deform_corners=self._deform_corners, hittable_rows=i64(self.hittable_rows),
            sun_rows=i64(self.sun_rows), world_row=int(self.world_row),
            world_radiance=f64(self.world_radiance).reshape(3), count=int(self.count), tree=self.tree)

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
            row = dict(kind=SUN, normal=-light.direction, power=light.irradiance.mean() * np.pi * self.scene_radius ** 2,
                       tree_energy=light.irradiance.mean())
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
                         power=mean_power, tree_energy=mean_power / np.pi)]
        assert isinstance(light, PointLight)
        r = light.radius
        row = dict(position=light.position, radius=r, power=mean_power, tree_energy=mean_power / (4.0 * np.pi))
        if r <= 0:
            row.update(kind=POINT, strength=light.power / (4.0 * np.pi))
        else:
            row.update(kind=DISK if light.soft_falloff else SPHERE,
                       strength=light.power / (np.pi * 4.0 * np.pi * r * r))
        if isinstance(light, SpotLight):
            cos_half = np.cos(0.5 * np.clip(light.spot_size, 0.0, np.pi))
            blend = max(light.spot_blend, 1e-6)
            # Selection power: what the spot emits into its cone (intensity power / 4 pi times the
            # cone's solid angle), not the power of the full sphere: a narrow spot was otherwise
            # picked for most next-event samples that its cone then masks to 0 (Cycles' light tree
            # bounds a spot's emission by its cone: scene/light_tree.cpp, LightTreeEmitter,
            # bcone.theta_e = spot_angle / 2; measured: 4x the error of a sun + spot height fog).
            row.update(normal=light.direction, cos_half=cos_half, power=mean_power * 0.5 * (1.0 - cos_half),
                       spot_smooth=1.0 / max((1.0 - cos_half) * blend, 1e-12))
        return [row]

    # -----------------------------------------------------------------------------------------
    # numpy-facing API: loops over the scalar kernels of light_kernels (one implementation)
    # -----------------------------------------------------------------------------------------
    def tree_select(self, u, points, normals, t, mode):
        """light_tree.tree_select per point: (rows, probabilities)."""
        n = len(u)
        rows, pdf = np.empty(n, np.int64), np.empty(n)
        tree_select_many(self.tables.tree, _f64(u), _f64(points).reshape(n, 3), _f64(normals).reshape(n, 3),
                         _f64(np.broadcast_to(t, (n,))), int(mode), rows, pdf)
        return rows, pdf

    def tree_pdf(self, rows, points, normals, t, mode):
        """light_tree.tree_pdf per point."""
        rows = _i64(rows)
        n = len(rows)
        pdf = np.empty(n)
        tree_pdf_many(self.tables.tree, rows, _f64(points).reshape(n, 3), _f64(normals).reshape(n, 3),
                      _f64(np.broadcast_to(t, (n,))), int(mode), pdf)
        return pdf

    def select(self, u: np.ndarray) -> np.ndarray:
        u = _f64(u)
        out = np.empty(len(u), np.int64)
        select_many(self.tables, u, out)
        return out

    def has_position(self, rows: np.ndarray) -> np.ndarray:
        """Rows whose emitters sit at a finite position (usable for equiangular sampling)."""
        rows = _i64(rows)
        out = np.empty(len(rows), bool)
        has_position_many(self.tables, rows, out)
        return out

    def sample(self, rows: np.ndarray, p: np.ndarray, u1: np.ndarray, u2: np.ndarray, times=0.5) -> LightSample:
        """Sample a point/direction on light `rows[i]` as seen from p[i] at shutter time times[i]
        (light_kernels.sample_light)."""
        rows = _i64(rows)
        n = len(rows)
        wi, dist, value, pdf = np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty(n)
        sample_many(self.tables, rows, _f64(p).reshape(n, 3), _f64(u1), _f64(u2), _f64(np.broadcast_to(times, (n,))),
                    wi, dist, value, pdf)
        return LightSample(wi, dist, value, pdf)

    def triangle_emission(self, prim, origins, directions, t, front, times=0.5):
        """Radiance and light-sampling pdf (solid angle, incl. selection) of emissive triangles hit
        (at shutter times `times`)."""
        prim = _i64(prim)
        n = len(prim)
        radiance, pdf = np.empty((n, 3)), np.empty(n)
        triangle_emission_many(self.tables, prim, _f64(origins).reshape(n, 3), _f64(directions).reshape(n, 3),
                               _f64(t), np.ascontiguousarray(front, dtype=bool), _f64(np.broadcast_to(times, (n,))),
                               radiance, pdf)
        return radiance, pdf

    def escaped_emission(self, directions):
        """List of (radiance (N,3), light pdf (N,), camera_visible) for distant emitters seen
        along directions (the world is always visible to the camera)."""
        d = _f64(directions).reshape(-1, 3)
        out = []
        rows = ([self.world_row] if self.world_row >= 0 else []) + list(self.sun_rows)
        for row in rows:
            radiance, pdf = np.empty((len(d), 3)), np.empty(len(d))
            distant_emission_many(self.tables, int(row), d, radiance, pdf)
            out.append((radiance, pdf, True if row == self.world_row else bool(self.camera_visible[row])))
        return out

    def intersect_lamps(self, origins, directions, tmin, tmax):
        """Emission of lamps (spheres, soft point disks, area lights) crossed by the rays within
        (tmin, tmax]: list of (t (N,), radiance (N,3), light pdf (N,), camera_visible) per lamp
        crossed by at least one ray, t = inf where missed.
        origins are the previous scattering vertices (the reference point of the light pdf)."""
        o = _f64(origins).reshape(-1, 3)
        n = len(o)
        d = _f64(directions).reshape(n, 3)
        tmin = _f64(np.broadcast_to(tmin, (n,)))
        tmax = _f64(np.broadcast_to(tmax, (n,)))
        out = []
        for k, row in enumerate(self.hittable_rows):
            t, radiance, pdf = np.empty(n), np.empty((n, 3)), np.empty(n)
            if lamp_crossing_many(self.tables, k, o, d, tmin, tmax, t, radiance, pdf):
                out.append((t, radiance, pdf, bool(self.camera_visible[row])))
        return out


def _has_program_emission(material) -> bool:
    program = getattr(material, "surface_program", None)
    return program is not None and int(getattr(program, "emission", -1)) >= 0


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _i64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)
