"""Homogeneous participating media: the volume stack, coefficients per path, free-flight
distance sampling in chromatic media and equiangular sampling.

Volume stack: one counter per *volume* (a closed mesh paired with the medium of its material);
a front-face crossing of a null boundary enters, a back-face crossing leaves (Cycles
kernel/integrator/volume_stack.h). Overlapping volumes add their coefficients; the world medium
is always at the bottom.
"""
from __future__ import annotations

import numpy as np

from .accel import Accelerator
from .jit import kernel
from .scene import Scene
from .vec import norm, sum3

_MAX_TABLE_VOLUMES = 12  # 4096 combinations: coefficient lookup tables stay small
_WALK_DIRECTION = np.array([0.5773, 0.5774, 0.5775]) / np.linalg.norm([0.5773, 0.5774, 0.5775])


class MediaTable:
    def __init__(self, scene: Scene, accel: Accelerator):
        mat_medium = np.array([m.medium for m in scene.materials], dtype=np.int64).reshape(-1)
        tri_medium = mat_medium[accel.material_ids] if len(mat_medium) else np.zeros(0, np.int64)
        pairs = np.stack([accel.mesh_ids.astype(np.int64), tri_medium], axis=1)[tri_medium >= 0]
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
        self._tables = self._build_tables()
        self._init_phase_components(media, w)
        world_t = self.world_sigma_s + self.world_sigma_a
        if np.any((self.world_emission > 0) & (world_t <= 0)):
            self.warnings.append("world medium emits but does not attenuate: its emission would be "
                                 "infinite along escaping rays and is ignored there")

    def inside_grid(self, counts: np.ndarray) -> np.ndarray:
        """Paths whose volume stack contains at least one grid volume."""
        inside = np.zeros(len(counts), dtype=bool)
        for v, _ in self.grid_volumes:
            inside |= counts[:, v] > 0
        return inside

    def empty_stack(self, n: int) -> np.ndarray:
        return np.zeros((n, max(self.n_volumes, 1)), dtype=np.int8)

    def coefficients(self, counts: np.ndarray):
        """(sigma_s, sigma_t, emission, g) per path for volume-stack counters (N, V)."""
        if self._tables is not None:
            key = self._stack_key(counts)
            return tuple(np.take(table, key, axis=0) for table in self._tables)
        return self._coefficients_direct(counts)

    def sigma_t(self, counts: np.ndarray) -> np.ndarray:
        """Only sigma_t of coefficients() (shadow rays need nothing else)."""
        if self._tables is not None:
            return np.take(self._tables[1], self._stack_key(counts), axis=0)
        return self._coefficients_direct(counts)[1]

    def _stack_key(self, counts: np.ndarray) -> np.ndarray:
        """Which volumes contain each path, as a bit set (row of the coefficient tables)."""
        if self.n_volumes == 0:
            return np.zeros(len(counts), np.intp)
        inside = counts[:, :self.n_volumes] > 0
        if self.n_volumes == 1:
            return inside[:, 0].view(np.uint8)
        key = inside[:, 0].astype(np.int32)
        for v in range(1, self.n_volumes):
            key |= inside[:, v].astype(np.int32) << v
        return key

    def _build_tables(self):
        """Coefficients of every combination of volumes when there are few volumes: a per-path
        lookup then replaces the matrix products of _coefficients_direct (it runs after every
        null-boundary crossing and for every shadow segment)."""
        if self.n_volumes > _MAX_TABLE_VOLUMES:
            return None
        combos = (np.arange(1 << self.n_volumes)[:, None] >> np.arange(self.n_volumes)[None, :]) & 1
        counts = np.zeros((len(combos), max(self.n_volumes, 1)), np.int8)
        counts[:, :self.n_volumes] = combos
        return tuple(np.ascontiguousarray(a) for a in self._coefficients_direct(counts))

    def _coefficients_direct(self, counts: np.ndarray):
        n = len(counts)
        sigma_s = np.broadcast_to(self.world_sigma_s, (n, 3)).copy()
        sigma_a = np.broadcast_to(self.world_sigma_a, (n, 3)).copy()
        emission = np.broadcast_to(self.world_emission, (n, 3)).copy()
        g_weight = np.full(n, self.world_sigma_s.mean())
        g_sum = g_weight * self.world_g
        if self.n_volumes:
            inside = (counts[:, :self.n_volumes] > 0).astype(np.float64)
            sigma_s += inside @ self.sigma_s
            sigma_a += inside @ self.sigma_a
            emission += inside @ self.emission
            ws = inside * self.sigma_s.mean(axis=1)
            g_weight += ws.sum(axis=1)
            g_sum += ws @ self.g
        # g is exact wherever one g scatters (the fast path); where media with different g
        # overlap (phase_is_mixed) the integrator uses the exact mixture of phase_components and
        # this sigma_s-weighted mean is only a placeholder.
        g = np.where(g_weight > 0, g_sum / np.where(g_weight > 0, g_weight, 1.0), 0.0)
        return sigma_s, sigma_s + sigma_a, emission, g

    # ---- phase mixtures of overlapping homogeneous media --------------------------------------
    def _init_phase_components(self, media, world_medium: int):
        """Group the scattering lobes of the homogeneous media (world included; a medium has one
        lobe unless it lists phase_lobes) by g: one mixture component per distinct g (Cycles
        merges volume closures of equal g the same way, kernel/integrator/volume_shader.h
        volume_shader_merge_closures). mixed_phase is False when at most one g scatters anywhere,
        and then the integrator never asks for components."""
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
        self._component_tables = None
        if self.mixed_phase and self.n_volumes <= _MAX_TABLE_VOLUMES:
            combos = (np.arange(1 << self.n_volumes)[:, None] >> np.arange(self.n_volumes)[None, :]) & 1
            counts = np.zeros((len(combos), max(self.n_volumes, 1)), np.int8)
            counts[:, :self.n_volumes] = combos
            components = self._components_direct(counts)
            self._component_tables = (components, (components.max(axis=2) > 0).sum(axis=1) > 1)

    def _components_direct(self, counts: np.ndarray) -> np.ndarray:
        sigma_s = np.broadcast_to(self._world_lobe_sigma, (len(counts),) + self._world_lobe_sigma.shape).copy()
        if self.n_volumes:
            inside = (counts[:, :self.n_volumes] > 0).astype(np.float64)
            sigma_s += np.einsum("nv,vkc->nkc", inside, self._volume_lobe_sigma[:self.n_volumes])
        return sigma_s

    def phase_is_mixed(self, counts: np.ndarray) -> np.ndarray:
        """Paths whose stack holds scattering homogeneous media of more than one g."""
        if not self.mixed_phase:
            return np.zeros(len(counts), dtype=bool)
        if self._component_tables is not None:
            return np.take(self._component_tables[1], self._stack_key(counts))
        return (self._components_direct(counts).max(axis=2) > 0).sum(axis=1) > 1

    def phase_components(self, counts: np.ndarray):
        """(sigma_s per component (N, K, 3), g per component (K,)) of the homogeneous media:
        the phase function there is sum_k sigma_s[:, k] HG(g_k) / sum_k sigma_s[:, k] per channel."""
        if self._component_tables is not None:
            return np.take(self._component_tables[0], self._stack_key(counts), axis=0), self.phase_g_values
        return self._components_direct(counts), self.phase_g_values

    def cross(self, counts: np.ndarray, prim: np.ndarray, front: np.ndarray) -> None:
        """Update counters in place for null-boundary crossings of triangles prim."""
        vol = self.tri_volume[prim]
        idx = np.nonzero(vol >= 0)[0]
        if not len(idx):
            return
        if not counts.flags.c_contiguous:
            step = np.where(front[idx], 1, -1).astype(np.int16)
            counts[idx, vol[idx]] = np.clip(counts[idx, vol[idx]].astype(np.int16) + step, 0, 127)
            return
        # one flat index per crossing into the (N, V) counters (2-D fancy indexing is slower)
        flat_counts = counts.reshape(-1)
        flat = idx * counts.shape[1] + vol[idx]
        new = flat_counts[flat].astype(np.int16)
        new += np.where(front[idx], 1, -1).astype(np.int16)
        np.clip(new, 0, 127, out=new)
        flat_counts[flat] = new

    def stack_at(self, points: np.ndarray, max_crossings: int = 256) -> np.ndarray:
        """Volume-stack counters for arbitrary points, by walking a ray to infinity and counting
        boundary crossings (Cycles does the same for the camera: volume_stack_init)."""
        n = len(points)
        counts = np.zeros((n, max(self.n_volumes, 1)), dtype=np.int16)
        if not self.n_volumes or n == 0:
            return counts.astype(np.int8)
        origins = points.astype(np.float64).copy()
        dirs = np.broadcast_to(_WALK_DIRECTION, (n, 3)).copy()
        active = np.arange(n)
        eps = self.accel.epsilon
        for _ in range(max_crossings):
            if len(active) == 0:
                break
            hits = self.accel.intersect(origins[active], dirs[active])
            found = hits.prim >= 0
            active, prim, t = active[found], hits.prim[found], hits.t[found]
            vol = self.tri_volume[prim]
            leaving = np.einsum("ij,ij->i", dirs[active], self.accel.normals[prim]) > 0
            m = vol >= 0
            np.add.at(counts, (active[m], vol[m]), np.where(leaving[m], 1, -1).astype(np.int16))
            origins[active] = origins[active] + dirs[active] * (t + eps)[:, None]
        return np.clip(counts, 0, 127).astype(np.int8)


# ---------------------------------------------------------------------------------------------
# Free-flight sampling (chromatic): the channel is chosen per path and the pdf averaged over
# channels -- the one-sample spectral MIS of pbrt-v4 (media.h SampleT_maj + "r_u" rescaling) and
# Cycles (kernel/integrator/volume_shader/shade_volume.h, volume_sample_channel).
# ---------------------------------------------------------------------------------------------
def channel_probabilities(beta: np.ndarray, sigma_s: np.ndarray, sigma_t: np.ndarray,
                          valid: np.ndarray | None = None) -> np.ndarray:
    """Per-path channel probabilities proportional to |throughput * albedo| (Cycles), with a
    uniform share so every channel that carries energy can be sampled."""
    w = np.divide(sigma_s, sigma_t, out=np.zeros_like(sigma_s), where=sigma_t > 0)  # albedo
    w *= np.abs(beta)
    s = sum3(w)
    positive = s > 0
    if positive.all():
        w /= s[:, None]
    else:
        w = np.where(positive[:, None], w / np.where(positive, s, 1.0)[:, None], 1.0 / 3.0)
    w *= 0.9
    w += 0.1 / 3.0
    p = w
    if valid is not None:
        p = p * valid
        s = sum3(p)[:, None]
        p = np.where(s > 0, p / np.where(s > 0, s, 1.0), 0.0)
    return p


def pick_channel(p: np.ndarray, u: np.ndarray) -> np.ndarray:
    c = (u >= p[:, 0]).astype(np.int64) + (u >= p[:, 0] + p[:, 1])
    return np.minimum(c, 2)


def sample_distance(sigma_t, p, u_channel, u):
    """Untruncated exponential free flight with the chosen channel; inf where sigma = 0."""
    c = pick_channel(p, u_channel)
    s = sigma_t[np.arange(len(c)), c]
    return np.where(s > 0, -np.log1p(-u) / np.where(s > 0, s, 1.0), np.inf)


def distance_pdf(sigma_t, p, t):
    """Channel-averaged free-flight density at t and survival probability beyond t."""
    if np.isfinite(t).all():  # usual case: one exp, no masks
        tr = transmittance(sigma_t, t)
        weighted = p * tr
        return sum3(weighted * sigma_t), sum3(weighted), tr
    tt = np.where(np.isfinite(t), t, 0.0)[:, None]
    tr = np.where(np.isfinite(t)[:, None], np.exp(-sigma_t * tt), (sigma_t <= 0).astype(np.float64))
    return sum3(p * sigma_t * tr), sum3(p * tr), tr


def sample_distance_truncated(sigma_t, p, u_channel, u, t_end):
    """Exponential restricted to [0, t_end] (t_end may be inf where that channel attenuates)."""
    c = pick_channel(p, u_channel)
    s = sigma_t[np.arange(len(c)), c]
    finite = np.isfinite(t_end)
    te = np.where(finite, t_end, 0.0)
    mass = np.where(finite, -np.expm1(-s * te), 1.0)
    t_exp = -np.log1p(-u * mass) / np.where(s > 0, s, 1.0)
    return np.where(s > 1e-12, t_exp, u * te)


def truncated_distance_pdf(sigma_t, p, t, t_end):
    if np.isfinite(t_end).all():  # usual case (segments end on a surface): fewer masks
        te = t_end[:, None]
        optical = sigma_t * te
        mass = np.expm1(-optical)
        np.negative(mass, out=mass)
        dens = transmittance(sigma_t, t)
        dens *= sigma_t
        dens /= np.where(mass > 0, mass, 1.0)
        small = optical < 1e-9
        if small.any():
            dens = np.where(small, 1.0 / np.where(te > 0, te, np.inf), dens)
        dens *= p
        return sum3(dens)
    finite = np.isfinite(t_end)[:, None]
    te = np.where(finite, t_end[:, None], 0.0)
    mass = np.where(finite, -np.expm1(-sigma_t * te), 1.0)
    small = sigma_t * np.where(finite, te, np.inf) < 1e-9
    dens = np.where(small, 1.0 / np.where(finite & (te > 0), te, np.inf),
                    sigma_t * np.exp(-sigma_t * t[:, None]) / np.where(mass > 0, mass, 1.0))
    return sum3(p * dens)


def transmittance(sigma_t, distance):
    """exp(-sigma_t d), with exp(-0 * inf) = 1."""
    if np.isfinite(distance).all():  # usual case: exp(-0 * d) = 1 needs no mask
        out = sigma_t * distance[:, None]
        np.negative(out, out=out)
        return np.exp(out, out=out)
    d = distance[:, None]
    return np.where(sigma_t > 0, np.exp(-sigma_t * np.where(np.isfinite(d), d, 1e300)), 1.0)


def emission_integral(emission, sigma_t, distance):
    """Integral of emission * T(t) over [0, distance] in a homogeneous medium (analytic, as
    Cycles' homogeneous volume emission); infinite paths without attenuation contribute 0."""
    d = np.where(np.isfinite(distance), distance, np.inf)[:, None]
    with np.errstate(invalid="ignore", over="ignore"):
        attenuating = emission * -np.expm1(-sigma_t * d) / np.where(sigma_t > 0, sigma_t, 1.0)
        flat = emission * np.where(np.isfinite(d), d, 0.0)
    return np.where(sigma_t > 0, attenuating, flat)


# ---------------------------------------------------------------------------------------------
# Equiangular sampling toward a point (Kulla & Fajardo 2012, "Importance Sampling Techniques for
# Path Tracing in Participating Media", section 4.1; Cycles kernel/integrator/shade_volume.h).
# ---------------------------------------------------------------------------------------------
def equiangular_setup(origins, directions, t_end, light_pos):
    delta = np.einsum("ij,ij->i", light_pos - origins, directions)
    closest = origins + directions * delta[:, None]
    D = np.maximum(norm(light_pos - closest), 1e-7)
    theta_a = np.arctan2(-delta, D)
    theta_b = np.where(np.isfinite(t_end), np.arctan2(np.where(np.isfinite(t_end), t_end, 0.0) - delta, D),
                       0.5 * np.pi)
    return delta, D, theta_a, theta_b


def equiangular_sample(setup, u):
    delta, D, ta, tb = setup
    t = delta + D * np.tan(ta + u * (tb - ta))
    return t, equiangular_pdf(setup, t)


def equiangular_pdf(setup, t):
    delta, D, ta, tb = setup
    span = np.maximum(tb - ta, 1e-12)
    return D / (span * (D * D + (t - delta) ** 2))


# ---------------------------------------------------------------------------------------------
# Scalar forms for the compiled kernels: RGB quantities are 3-tuples, one path per call; the
# estimators are those of the array functions above (same references).
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
    restricted to the valid channels v0..v2 (renormalised; all zero if none is valid)."""
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
    return -np.log1p(-u) / s if s > 0.0 else np.inf


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


@kernel
def equiangular_setup1(o, d, t_end, light):
    """(delta, D, theta_a, theta_b) of Kulla & Fajardo's equiangular sampling toward `light`."""
    delta = (light[0] - o[0]) * d[0] + (light[1] - o[1]) * d[1] + (light[2] - o[2]) * d[2]
    cx = light[0] - (o[0] + d[0] * delta)
    cy = light[1] - (o[1] + d[1] * delta)
    cz = light[2] - (o[2] + d[2] * delta)
    D = max(np.sqrt(cx * cx + cy * cy + cz * cz), 1e-7)
    theta_a = np.arctan2(-delta, D)
    theta_b = np.arctan2(t_end - delta, D) if np.isfinite(t_end) else 0.5 * np.pi
    return delta, D, theta_a, theta_b


@kernel
def equiangular_sample1(setup, u):
    delta, D, ta, tb = setup
    return delta + D * np.tan(ta + u * (tb - ta))


@kernel
def equiangular_pdf1(setup, t):
    delta, D, ta, tb = setup
    span = max(tb - ta, 1e-12)
    return D / (span * (D * D + (t - delta) ** 2))
