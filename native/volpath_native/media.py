"""Homogeneous participating media: the per-volume tables of the volume stack, and the scalar
estimators the compiled stages call per path (transmittance, free-flight distance sampling in
chromatic media, emission, equiangular sampling).

Volume stack: one counter per *volume* (a closed mesh paired with the medium of its material);
a front-face crossing of a null boundary enters, a back-face crossing leaves (Cycles
kernel/integrator/volume_stack.h). Overlapping volumes add their coefficients; the world medium
is always at the bottom. path_kernels keeps the counters per path and sums the coefficients of
the volumes a path is in (stack_coefficients, _component_sigma) from the tables built here.
"""
from __future__ import annotations

import numpy as np

from .accel import Accelerator
from .jit import kernel
from .scene import Scene

_WALK_DIRECTION = np.array([0.5773, 0.5774, 0.5775]) / np.linalg.norm([0.5773, 0.5774, 0.5775])


class MediaTable:
    def __init__(self, scene: Scene, accel: Accelerator):
        mat_medium = np.array([m.medium for m in scene.materials], dtype=np.int64).reshape(-1)
        if np.any(mat_medium >= 0):
            tri_medium = mat_medium[accel.material_ids]
            pairs = np.stack([accel.mesh_ids.astype(np.int64), tri_medium], axis=1)[tri_medium >= 0]
        else:  # no volume boundaries: no per-triangle temporaries
            pairs = np.zeros((0, 2), np.int64)
        uniq = np.unique(pairs, axis=0) if len(pairs) else np.zeros((0, 2), np.int64)
        self.volume_medium = uniq[:, 1]
        self.n_volumes = len(uniq)
        self.tri_volume = np.full(accel.triangle_count, -1, np.int32)
        for v, (mesh, medium) in enumerate(uniq):
            sel = (accel.mesh_ids == mesh) & (tri_medium == medium)
            self.tri_volume[sel] = v
        media = scene.media
        # Heterogeneous (grid) media are tracked by their own objects; their rows in the
        # homogeneous tables stay zero.
        self.volume_is_grid = np.array([not getattr(media[m], "is_homogeneous", True) for m in self.volume_medium],
                                       dtype=bool)
        self.grid_volumes = [(int(v), media[m]) for v, m in enumerate(self.volume_medium) if self.volume_is_grid[v]]
        self.has_grids = bool(self.grid_volumes)

        def table(attr):
            rows = [np.zeros(3) if self.volume_is_grid[v] else getattr(media[m], attr)
                    for v, m in enumerate(self.volume_medium)]
            return np.array(rows, dtype=np.float64).reshape(-1, 3)

        self.sigma_s = table("sigma_s")
        self.sigma_a = table("sigma_a")
        self.emission = table("emission")
        self.g = np.array([0.0 if self.volume_is_grid[v] else media[m].g for v, m in enumerate(self.volume_medium)],
                          dtype=np.float64)
        w = scene.world.medium
        zero = np.zeros(3)
        self.world_sigma_s = media[w].sigma_s if w >= 0 else zero
        self.world_sigma_a = media[w].sigma_a if w >= 0 else zero
        self.world_emission = media[w].emission if w >= 0 else zero
        self.world_g = media[w].g if w >= 0 else 0.0
        self.any_medium = bool(self.n_volumes) or bool(np.any(self.world_sigma_s + self.world_sigma_a > 0)
                                                       or np.any(self.world_emission > 0))
        self.accel = accel
        self.warnings: list[str] = []
        self._init_phase_components(media, w)
        world_t = self.world_sigma_s + self.world_sigma_a
        if np.any((self.world_emission > 0) & (world_t <= 0)):
            self.warnings.append("world medium emits but does not attenuate: its emission would be "
                                 "infinite along escaping rays and is ignored there")

    def empty_stack(self, n: int) -> np.ndarray:
        """Counters (n, V) of paths inside no volume."""
        return np.zeros((n, max(self.n_volumes, 1)), dtype=np.int8)

    # ---- phase mixtures of overlapping homogeneous media --------------------------------------
    def _init_phase_components(self, media, world_medium: int):
        """Group the scattering lobes of the homogeneous media (world included; a medium has one
        lobe unless it lists phase_lobes) by g: one mixture component per distinct g (Cycles
        merges volume closures of equal g the same way, kernel/integrator/volume_shader.h
        volume_shader_merge_closures). mixed_phase is False when at most one g scatters anywhere,
        and then the stages never evaluate mixtures."""
        def lobes(medium):
            return [(s, float(g)) for s, g in medium.lobes() if np.any(s > 0)]
        volume_lobes = {v: lobes(media[m]) for v, m in enumerate(self.volume_medium) if not self.volume_is_grid[v]}
        world_lobes = lobes(media[world_medium]) if world_medium >= 0 else []
        values = {g for ls in volume_lobes.values() for _, g in ls} | {g for _, g in world_lobes}
        self.phase_g_values = np.array(sorted(values), dtype=np.float64)
        self.mixed_phase = len(self.phase_g_values) > 1
        k = len(self.phase_g_values)
        self._volume_lobe_sigma = np.zeros((max(self.n_volumes, 1), k, 3))
        for v, ls in volume_lobes.items():
            for sigma_s, g in ls:
                self._volume_lobe_sigma[v, int(np.searchsorted(self.phase_g_values, g))] += sigma_s
        self._world_lobe_sigma = np.zeros((k, 3))
        for sigma_s, g in world_lobes:
            self._world_lobe_sigma[int(np.searchsorted(self.phase_g_values, g))] += sigma_s

    @property
    def boundaries_move(self) -> bool:
        """Whether some volume boundary moves during the shutter (a deforming or moving mesh)."""
        accel = self.accel
        return bool(accel.has_deformation and np.any(accel.deform_rows[self.tri_volume >= 0, 0] >= 0))

    def boundary_meets_box(self, lo: np.ndarray, hi: np.ndarray) -> bool:
        """Whether the bounding box of some volume boundary triangle (over the shutter, for moving
        ones) overlaps the box [lo, hi] (conservative: False means no boundary passes through the
        box)."""
        boundary = np.nonzero(self.tri_volume >= 0)[0]
        corners = self.accel.triangle_corners(boundary)
        if len(corners) == 0:
            return False
        low, high = corners.min(axis=1), corners.max(axis=1)
        if self.boundaries_move:
            low, high = self.accel.swept_bounds(boundary, low, high)
        pad = self.accel.epsilon
        overlap = (low <= hi + pad) & (high >= lo - pad)
        return bool(np.any(overlap.all(axis=1)))

    def stack_at(self, points: np.ndarray, times=None, max_crossings: int = 256) -> np.ndarray:
        """Volume-stack counters for arbitrary points, by walking a ray to infinity and counting
        boundary crossings (Cycles does the same for the camera: volume_stack_init), at the
        points' shutter times (None: the frame) when boundaries move (Cycles'
        integrator_volume_stack_init walks with the camera ray's time)."""
        n = len(points)
        counts = np.zeros((n, max(self.n_volumes, 1)), dtype=np.int16)
        if not self.n_volumes or n == 0:
            return counts.astype(np.int8)
        origins = points.astype(np.float64).copy()
        dirs = np.broadcast_to(_WALK_DIRECTION, (n, 3)).copy()
        active = np.arange(n)
        eps = self.accel.epsilon
        moving = self.boundaries_move
        if moving:
            times = np.full(n, 0.5, np.float32) if times is None else np.asarray(times, np.float32).reshape(n)
        for _ in range(max_crossings):
            if len(active) == 0:
                break
            if moving:
                hits = self.accel.intersect_at(origins[active], dirs[active], times[active])
            else:
                hits = self.accel.intersect(origins[active], dirs[active])
            found = hits.prim >= 0
            active, prim, t = active[found], hits.prim[found], hits.t[found]
            vol = self.tri_volume[prim]
            normals = self.accel.normals_at(prim, times[active]) if moving else self.accel.normals[prim]
            leaving = np.einsum("ij,ij->i", dirs[active], normals) > 0
            m = vol >= 0
            np.add.at(counts, (active[m], vol[m]), np.where(leaving[m], 1, -1).astype(np.int16))
            origins[active] = origins[active] + dirs[active] * (t + eps)[:, None]
        return np.clip(counts, 0, 127).astype(np.int8)


# ---------------------------------------------------------------------------------------------
# Estimators, one path per call; RGB quantities are 3-tuples.
#
# Free-flight sampling (chromatic): the channel is chosen per path and the pdf averaged over
# channels -- the one-sample spectral MIS of pbrt-v4 (media.h SampleT_maj + "r_u" rescaling) and
# Cycles (kernel/integrator/volume_shader/shade_volume.h, volume_sample_channel).
# ---------------------------------------------------------------------------------------------
@kernel
def transmittance1(sigma, distance):
    """exp(-sigma d) for one channel, with exp(-0 * inf) = 1."""
    if sigma <= 0.0:
        return 1.0
    return np.exp(-sigma * distance)


@kernel
def transmittance3(sigma_t, distance):
    t0 = transmittance1(sigma_t[0], distance)
    if sigma_t[1] == sigma_t[0] and sigma_t[2] == sigma_t[0]:  # grey medium: one exp
        return t0, t0, t0
    return t0, transmittance1(sigma_t[1], distance), transmittance1(sigma_t[2], distance)


@kernel
def channel_probabilities1(beta, sigma_s, sigma_t, v0, v1, v2):
    """Channel pdf ~ |throughput * albedo| plus a uniform share (Cycles volume_sample_channel),
    restricted to the valid channels v0..v2 (renormalised; all zero if none is valid). In a grey
    medium every channel samples the same distances, so the choice does not matter."""
    if sigma_t[1] == sigma_t[0] and sigma_t[2] == sigma_t[0] and v1 == v0 and v2 == v0:
        return v0 / 3.0, v0 / 3.0, v0 / 3.0
    w0 = abs(beta[0]) * (sigma_s[0] / sigma_t[0] if sigma_t[0] > 0.0 else 0.0)
    w1 = abs(beta[1]) * (sigma_s[1] / sigma_t[1] if sigma_t[1] > 0.0 else 0.0)
    w2 = abs(beta[2]) * (sigma_s[2] / sigma_t[2] if sigma_t[2] > 0.0 else 0.0)
    s = w0 + w1 + w2
    if s > 0.0:
        w0, w1, w2 = w0 / s, w1 / s, w2 / s
    else:
        w0 = w1 = w2 = 1.0 / 3.0
    p0 = (0.9 * w0 + 0.1 / 3.0) * v0
    p1 = (0.9 * w1 + 0.1 / 3.0) * v1
    p2 = (0.9 * w2 + 0.1 / 3.0) * v2
    s = p0 + p1 + p2
    if s <= 0.0:
        return 0.0, 0.0, 0.0
    return p0 / s, p1 / s, p2 / s


@kernel
def pick_channel1(p, u):
    if u < p[0]:
        return 0
    if u < p[0] + p[1]:
        return 1
    return 2


@kernel
def sample_distance1(sigma_t, p, u_channel, u):
    """Untruncated exponential free flight with the chosen channel; inf where sigma = 0."""
    s = sigma_t[pick_channel1(p, u_channel)]
    return -np.log(1.0 - u) / s if s > 0.0 else np.inf  # 1 - u is exact for u = k 2^-53


@kernel
def distance_pdf1(sigma_t, p, t):
    """(channel-averaged density at t, survival beyond t, transmittance (3-tuple) at t)."""
    tr = transmittance3(sigma_t, t)
    density = p[0] * sigma_t[0] * tr[0] + p[1] * sigma_t[1] * tr[1] + p[2] * sigma_t[2] * tr[2]
    return density, p[0] * tr[0] + p[1] * tr[1] + p[2] * tr[2], tr


@kernel
def sample_distance_truncated1(sigma_t, p, u_channel, u, t_end):
    """Exponential restricted to [0, t_end] (t_end may be inf where that channel attenuates)."""
    s = sigma_t[pick_channel1(p, u_channel)]
    finite = np.isfinite(t_end)
    te = t_end if finite else 0.0
    if s <= 1e-12:
        return u * te
    mass = -np.expm1(-s * te) if finite else 1.0
    return -np.log1p(-u * mass) / s


@kernel
def truncated_distance_pdf1(sigma_t, p, tr, t_end):
    """Channel-averaged density of sample_distance_truncated1 at the distance where the
    transmittance is tr (= transmittance3(sigma_t, t), which the caller needs anyway)."""
    finite = np.isfinite(t_end)
    grey = sigma_t[1] == sigma_t[0] and sigma_t[2] == sigma_t[0]
    total = 0.0
    mass = 1.0
    for c in range(3):
        s = sigma_t[c]
        if finite:
            optical = s * t_end
            if optical < 1e-9:
                density = 1.0 / t_end if t_end > 0.0 else 0.0
            else:
                if c == 0 or not grey:
                    mass = -np.expm1(-optical)
                density = s * tr[c] / mass
        else:
            density = s * tr[c]
        total += p[c] * density
    return total


@kernel
def emission_integral1(emission, sigma_t, distance):
    """Integral of emission T(t) over [0, distance] per channel (analytic); unattenuated infinite
    paths contribute 0 (the world-medium warning covers them)."""
    out0 = out1 = out2 = 0.0
    for c in range(3):
        s = sigma_t[c]
        if s > 0.0:
            v = emission[c] * -np.expm1(-s * distance) / s
        elif np.isfinite(distance):
            v = emission[c] * distance
        else:
            v = 0.0
        if c == 0:
            out0 = v
        elif c == 1:
            out1 = v
        else:
            out2 = v
    return out0, out1, out2


# Equiangular sampling toward a point (Kulla & Fajardo 2012, "Importance Sampling Techniques for
# Path Tracing in Participating Media", section 4.1; Cycles kernel/integrator/shade_volume.h).
# The angles are theta = atan((t - delta) / D) at t_start and t_end. Only their difference (the
# span) is needed: tan(b - a) = (tan b - tan a) / (1 + tan a tan b) gives it with one atan2, and
# the sample's tan(theta_a + u span) expands the same way -- Cycles evaluates two atan2. The
# segment [t_start, t_end] is the part a light reaches (light_segment.py; Cycles samples over
# volume_valid_direct_ray_segment's t_range): the pdf is 0 outside it.
@kernel
def equiangular_setup1(o, d, t_start, t_end, light):
    """(delta, D, span, t_start, t_end) of equiangular sampling toward `light` along the unit ray
    o + t d, t in [t_start, t_end] (t_end may be inf): delta is the distance along the ray to the
    point nearest the light, D the light's distance from the ray, span the angle the segment
    subtends."""
    delta = (light[0] - o[0]) * d[0] + (light[1] - o[1]) * d[1] + (light[2] - o[2]) * d[2]
    cx = light[0] - (o[0] + d[0] * delta)
    cy = light[1] - (o[1] + d[1] * delta)
    cz = light[2] - (o[2] + d[2] * delta)
    D = max(np.sqrt(cx * cx + cy * cy + cz * cz), 1e-7)
    a = t_start - delta
    if np.isfinite(t_end):
        span = np.arctan2((t_end - t_start) * D, D * D + a * (t_end - delta))
    else:
        span = np.arctan2(D, a)
    return delta, D, span, t_start, t_end


@kernel
def equiangular_sample1(setup, u):
    """t = delta + D tan(theta_a + u span) with tan(theta_a) = (t_start - delta) / D."""
    delta, D, span, t_start, t_end = setup
    a = t_start - delta
    b = np.tan(u * span)
    return min(max(delta + D * (a + D * b) / (D - a * b), t_start), t_end)


@kernel
def equiangular_pdf1(setup, t):
    delta, D, span, t_start, t_end = setup
    if not t_start <= t <= t_end:
        return 0.0
    return D / (max(span, 1e-12) * (D * D + (t - delta) ** 2))
