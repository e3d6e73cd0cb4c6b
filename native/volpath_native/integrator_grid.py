"""The numpy wavefront volumetric path tracer, kept for scenes with grid (heterogeneous) media
until their tracking is compiled too; integrator.py is the compiled one.

Paths live in numpy structure-of-arrays; each iteration runs the stages of pbrt-v4's wavefront
integrator (src/pbrt/wavefront/integrator.cpp) over whole queues of paths at once: closest hit
(Embree, bulk) -> medium segment (emission, next-event estimation, free-flight sampling) ->
lamps crossed -> escaped rays -> surface hits (null boundaries, emission, NEE, BSDF sampling) ->
Russian roulette. Shadow rays are traced in bulk per stage.

Estimators and their references:
- free flight in chromatic media: one-sample spectral MIS, channel pdf averaged (pbrt-v4
  media.h / Cycles shade_volume.h); see media.py.
- direct light in media: a separate NEE vertex per segment whose distance is drawn from
  equiangular (toward the chosen light) or distance sampling, combined by one-sample MIS with the
  mixture (balance) pdf (Kulla & Fajardo 2012; Cycles kernel/integrator/shade_volume.h,
  volume_equiangular_sample / volume_equiangular_pdf, which weights with the power heuristic
  instead); light vs phase sampling combined with the power heuristic.
- light vs BSDF/phase sampling for hittable emitters: power heuristic (Veach 1997; Cycles
  kernel/sample/mis.h power_heuristic). Both NEE vertices use weights that depend only on the
  (vertex, direction) pair, so the two estimators sum to the direct light exactly.
- bounce limits: Cycles' path_state.h: after a scatter the counters grow; exceeding a limit sets
  "terminate after transparent" (the path still crosses null boundaries and collects emission
  with MIS, then ends). Russian roulette: survive with min(sqrt(max beta), 1).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import media as md
from .accel import Accelerator
from .bsdf import lambert_eval, lambert_sample
from .camera import CameraModel, crop_window
from .film import PixelFilter
from .lights import LightSet
from .phase import hg_eval, hg_mixture_sample, hg_sample
from .sampling import CAMERA_DIMS, DIMS_PER_EVENT, path_keys, uniform, uniform_block
from .scene import Scene
from .vec import any_positive, dot as _dot, max3, sum3

# Random dimensions within one iteration (see sampling.event_dimension).
D_CHANNEL, D_DISTANCE, D_MED_SELECT, D_MED_TECH, D_MED_T, D_MED_CHANNEL, D_MED_LU, D_MED_LV, \
    D_PHASE_U, D_PHASE_V, D_RR, D_SURF_SELECT, D_SURF_LU, D_SURF_LV, D_BSDF_U, D_BSDF_V = range(16)

MAX_VOLUME_BOUNDS = 1024  # Cycles' VOLUME_BOUNDS_MAX: null crossings are not transparent bounces


from .integrator import Cancelled  # noqa: E402  (one exception type for both integrators)


def _power_heuristic(a, b):
    a2, b2 = a * a, b * b
    return np.where(a2 + b2 > 0, a2 / np.where(a2 + b2 > 0, a2 + b2, 1.0), 0.0)


@dataclass
class _BatchContext:
    """Per-batch mutable state shared by the stages (one per render_paths call, so threads never
    share it)."""
    stats: dict
    rng: Optional[np.random.Generator]  # for grid-medium tracking (numpy Generator API)


class PathState:
    """Structure of arrays for the paths still alive."""

    FIELDS = ("pid", "key", "o", "d", "tmax", "beta", "counts", "bounce", "diffuse", "volume",
              "bounds", "tat", "prev_pdf", "prev_pos", "travelled", "lead",
              "m_ss", "m_st", "m_em", "m_g")  # m_*: homogeneous coefficients of the current stack

    def __init__(self, **arrays):
        for k in self.FIELDS:
            setattr(self, k, arrays[k])
        # wavefront iteration: all paths of a batch start together and advance in lockstep, so
        # one counter serves every path (it selects the random dimensions of the iteration)
        self.iteration = 0

    def __len__(self):
        return len(self.pid)

    def keep(self, mask):
        idx = np.nonzero(mask)[0]  # integer gathers are ~3x faster than boolean masks
        if len(idx) == len(self.pid):
            return
        for k in self.FIELDS:
            value = getattr(self, k)
            if value is not None:
                setattr(self, k, value[idx])


class Integrator:
    """Everything prepared once per scene; render_paths() may run in several threads."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.settings = scene.settings
        self.accel = Accelerator(scene.meshes)
        self.lights = LightSet(scene, self.accel)
        self.media = md.MediaTable(scene, self.accel)
        self.camera = CameraModel(scene.camera, scene.film)
        self.filter = PixelFilter(scene.film)
        self.crop = crop_window(scene.film)
        mats = scene.materials
        self.mat_null = np.array([m.surface == "null" for m in mats], dtype=bool)
        self.mat_albedo = np.array([m.base_color for m in mats], dtype=np.float64).reshape(-1, 3)
        self.mat_emissive = np.array([m.is_emissive and m.surface != "null" for m in mats], dtype=bool)
        ids = self.accel.material_ids
        self.tri_null = self.mat_null[ids] if len(mats) else np.zeros(0, bool)
        self.tri_emissive = self.mat_emissive[ids] if len(mats) else np.zeros(0, bool)
        self.has_null = bool(self.tri_null.any())
        self.warnings = self.lights.warnings + self.media.warnings
        self._camera_stack = None
        if self.media.n_volumes and scene.camera.projection == "perspective":
            self._camera_stack = self.media.stack_at(self.camera.position[None, :])[0]

    # -----------------------------------------------------------------------------------------
    def render_paths(self, pixel: np.ndarray, sample: np.ndarray, cancel=None):
        """Radiance estimates (N,3) for paths (crop-region pixel index, sample index) and stats."""
        st = self.settings
        n = len(pixel)
        rng = None
        if self.media.has_grids:
            # grid tracking draws from a numpy Generator seeded by the batch's first path: still
            # deterministic for a given batch layout, but not independent of the batch size
            rng = np.random.default_rng([st.seed & 0xFFFFFFFF, int(pixel[0]), int(sample[0]), n])
        ctx = _BatchContext(dict(rays=0, shadow_rays=0, vertices=0, paths=n), rng)
        x0, y0, cw, _ = self.crop
        px, py = x0 + pixel % cw, y0 + pixel // cw
        # keyed by the full-frame pixel, so a crop renders exactly the pixels of the full frame
        keys = path_keys(st.seed, py * self.scene.film.width + px, sample)
        fx = px + 0.5 + self.filter.sample(uniform(keys, 0))
        fy = py + 0.5 + self.filter.sample(uniform(keys, 1))
        o, d, tmax = self.camera.generate_rays(fx, fy)
        if self._camera_stack is not None:
            counts = np.repeat(self._camera_stack[None, :], n, axis=0)
        elif self.media.n_volumes:
            counts = self.media.stack_at(o)
        else:
            counts = self.media.empty_stack(n)
        zeros_i = np.zeros(n, np.int32)
        S = PathState(pid=np.arange(n), key=keys, o=o, d=d, tmax=tmax, beta=np.ones((n, 3)),
                      counts=counts, bounce=zeros_i.copy(), diffuse=zeros_i.copy(),
                      volume=zeros_i.copy(), bounds=zeros_i.copy(), tat=np.zeros(n, bool),
                      prev_pdf=np.zeros(n), prev_pos=o.copy(), travelled=np.zeros(n),
                      lead=np.zeros(n), m_ss=None, m_st=None, m_em=None, m_g=None)
        if self.media.any_medium:
            S.m_ss, S.m_st, S.m_em, S.m_g = self.media.coefficients(counts)
        L = np.zeros((n, 3))
        self._cancel = cancel
        while len(S):
            self._poll_cancel()
            S = self._iteration(S, L, ctx)
        return L, ctx.stats

    def _poll_cancel(self):
        cancel = getattr(self, "_cancel", None)
        if cancel is not None and cancel():
            raise Cancelled()

    def _u(self, S, offset, idx=None):
        dimension = CAMERA_DIMS + S.iteration * DIMS_PER_EVENT + offset
        return uniform(S.key if idx is None else S.key[idx], dimension)

    def _us(self, S, offsets, idx):
        """Several dimensions for the same paths in one pass (rows identical to _u's)."""
        base = CAMERA_DIMS + S.iteration * DIMS_PER_EVENT
        return uniform_block(S.key[idx], [base + k for k in offsets])

    # -----------------------------------------------------------------------------------------
    def _iteration(self, S: PathState, L: np.ndarray, ctx: "_BatchContext") -> PathState:
        st = self.settings
        n = len(S)
        hits = self.accel.intersect(S.o, S.d, S.tmax)
        ctx.stats["rays"] += n
        geo = (hits.prim >= 0) & (hits.t <= S.tmax)
        t_seg = np.where(geo, hits.t, S.tmax)

        # ---- medium segment --------------------------------------------------------------
        scatter = np.zeros(n, bool)
        t_scatter = np.full(n, np.inf)
        survive_p = None
        if self.media.any_medium:
            sig_s, sig_t, emis, g = S.m_ss, S.m_st, S.m_em, S.m_g
            in_med = (max3(sig_t) > 0) | (max3(emis) > 0)
        else:
            in_med = np.zeros(n, bool)
        in_grid = self.media.inside_grid(S.counts) if self.media.has_grids else np.zeros(n, bool)
        in_med |= in_grid
        phase_g = g.copy() if self.media.any_medium else None
        # which scattering events a grid caused (their phase is the grid's own HG)
        grid_scattered = np.zeros(n, bool) if self.media.has_grids else None
        if in_med.any() and np.any(S.lead > 0):
            # the origin sits `lead` past the boundary it just crossed: attenuate that gap exactly
            j = np.nonzero(in_med & (S.lead > 0))[0]
            S.beta[j] = S.beta[j] * md.transmittance(sig_t[j], S.lead[j])
        S.lead[:] = 0.0
        lamps = len(self.lights.hittable_rows) > 0
        # throughput at the segment start: only lamp hits and grid emission look back at it
        beta_in = S.beta.copy() if lamps or self.media.has_grids else None
        if in_med.any():
            i = np.nonzero(in_med & (max3(emis) > 0))[0]
            if len(i):
                L[S.pid[i]] += S.beta[i] * md.emission_integral(emis[i], sig_t[i], t_seg[i])
            # homogeneous scattering segments: next-event estimation, then free-flight sampling
            samp = np.nonzero(in_med & ~S.tat & (max3(sig_s) > 0) & ~in_grid)[0]
            if len(samp) and self.lights.count:
                self._medium_nee(S, samp, L, sig_s[samp], sig_t[samp], g[samp], t_seg[samp], ctx)
            i = np.nonzero(in_grid & ~S.tat)[0]
            if len(i) and self.lights.count:
                self._grid_nee(S, i, L, sig_s[i], sig_t[i], g[i], t_seg[i], ctx)
            # continuation: free-flight sampling, or plain attenuation when scattering is over
            survive_p = np.zeros((n, 3)) if lamps else None
            if len(samp):
                p = md.channel_probabilities(S.beta[samp], sig_s[samp], sig_t[samp])
                if survive_p is not None:
                    survive_p[samp] = p
                ts = md.sample_distance(sig_t[samp], p, *self._us(S, (D_CHANNEL, D_DISTANCE), samp))
                sc = ts < t_seg[samp]
                t_scatter[samp[sc]] = ts[sc]
                scatter[samp[sc]] = True
                pdf, _, tr = md.distance_pdf(sig_t[samp[sc]], p[sc], ts[sc])
                j = samp[sc]
                S.beta[j] = S.beta[j] * sig_s[j] * tr / np.maximum(pdf, 1e-300)[:, None]
                k = samp[~sc]
                _, surv, tr = md.distance_pdf(sig_t[k], p[~sc], t_seg[k])
                S.beta[k] = np.where(surv[:, None] > 0, S.beta[k] * tr / np.where(surv > 0, surv, 1.0)[:, None], 0.0)
            sampled_mask = np.zeros(n, bool)
            sampled_mask[samp] = True
            att = np.nonzero(in_med & ~sampled_mask & ~in_grid)[0]
            if len(att):
                S.beta[att] = S.beta[att] * md.transmittance(sig_t[att], t_seg[att])
            G = np.nonzero(in_grid)[0]
            if len(G):
                self._grid_segment(S, G, L, beta_in, sig_s[G], sig_t[G], t_seg[G], scatter, t_scatter, phase_g,
                                   grid_scattered, ctx)

        self._poll_cancel()
        # ---- lamps crossed before the end of the segment (they do not block) -------------
        if len(self.lights.hittable_rows):
            # grid paths use an independent ratio-tracking estimate of the transmittance to the
            # lamp (unbiased, whatever their own collision), so they reach every lamp on the segment
            reach = np.where(in_grid, t_seg, np.minimum(t_scatter, t_seg))
            for t_l, radiance, lpdf, camera_visible in self.lights.intersect_lamps(
                    S.prev_pos, S.d, S.travelled, S.travelled + reach):
                found = np.isfinite(t_l)
                if not camera_visible:
                    found &= S.bounce > 0  # camera rays do not see this lamp
                hit = np.nonzero(found)[0]
                if not len(hit):
                    continue
                w = np.where(S.prev_pdf[hit] > 0, _power_heuristic(S.prev_pdf[hit], lpdf[hit]), 1.0)
                local_t = t_l[hit] - S.travelled[hit]
                weight = beta_in[hit]
                if self.media.any_medium:
                    tr = md.transmittance(sig_t[hit], local_t)
                    p = survive_p[hit] if survive_p is not None else np.zeros((len(hit), 3))
                    sampled = sum3(p) > 0
                    _, surv, _ = md.distance_pdf(sig_t[hit], np.where(sampled[:, None], p, 1.0), local_t)
                    scale = np.where(sampled[:, None] & ~in_grid[hit][:, None], tr / np.maximum(surv, 1e-300)[:, None], tr)
                    weight = weight * scale
                    gh = np.nonzero(in_grid[hit])[0]
                    if len(gh):
                        weight[gh] *= self._grid_transmittance(S.o[hit[gh]], S.d[hit[gh]], local_t[gh],
                                                               S.counts[hit[gh]], ctx)
                L[S.pid[hit]] += weight * radiance[hit] * w[:, None]

        # ---- escaped rays ------------------------------------------------------------------
        escaped = ~geo & ~scatter
        e = np.nonzero(escaped)[0]
        if len(e):
            for radiance, lpdf, camera_visible in self.lights.escaped_emission(S.d[e]):
                w = np.where(S.prev_pdf[e] > 0, _power_heuristic(S.prev_pdf[e], lpdf), 1.0)
                if not camera_visible:
                    w = w * (S.bounce[e] > 0)
                L[S.pid[e]] += S.beta[e] * radiance * w[:, None]

        alive = ~escaped
        # ---- volume scattering vertices ------------------------------------------------------
        v = np.nonzero(scatter)[0]
        if len(v):
            ctx.stats["vertices"] += len(v)
            x = S.o[v] + S.d[v] * t_scatter[v][:, None]
            u_phase, v_phase = self._us(S, (D_PHASE_U, D_PHASE_V), v)
            wo, pdf = hg_sample(S.d[v], phase_g[v], u_phase, v_phase)
            # beta *= phase / pdf == 1 for exactly sampled HG; overlapping media of different g
            # need the mixture's value / pdf
            if self.media.mixed_phase:
                hom_event = np.ones(len(v), bool) if grid_scattered is None else ~grid_scattered[v]
                mv = np.nonzero(hom_event & self.media.phase_is_mixed(S.counts[v]))[0]
                if len(mv):
                    wo[mv], pdf[mv] = self._sample_phase_mixture(S, v[mv], sig_s[v[mv]], u_phase[mv], v_phase[mv])
            gv = np.nonzero(in_grid[v])[0]
            if len(gv):
                # MIS needs the pdf of the whole phase mixture at x (same function as grid NEE)
                comps = self._scattering_components(x[gv], S.counts[v[gv]], sig_s[v[gv]], g[v[gv]])
                _, pdf[gv] = _phase_mixture(comps, _dot(S.d[v[gv]], wo[gv]))
            S.o[v], S.d[v], S.prev_pos[v], S.prev_pdf[v] = x, wo, x, pdf
            S.travelled[v] = 0.0
            S.tmax[v] = np.inf
            S.volume[v] += 1
            S.bounce[v] += 1
            S.tat[v] |= (S.volume[v] > st.volume_bounces) | (S.bounce[v] > st.max_bounces)
            alive[v] &= self._russian_roulette(S, v)

        self._poll_cancel()
        # ---- surface hits ------------------------------------------------------------------
        s = np.nonzero(geo & ~scatter)[0]
        if len(s):
            alive[s] &= self._surfaces(S, s, hits, L, ctx)

        S.iteration += 1
        S.keep(alive & any_positive(S.beta))
        return S

    # -----------------------------------------------------------------------------------------
    def _russian_roulette(self, S, idx):
        survive = np.ones(len(idx), bool)
        j = np.nonzero(S.bounce[idx] > self.settings.russian_roulette_min_bounces)[0]
        if not len(j):  # early bounces: nothing to decide, no random numbers needed
            return survive
        r = idx[j]
        q = np.minimum(np.sqrt(max3(np.abs(S.beta[r]))), 1.0)
        survive[j] = self._u(S, D_RR, r) < q
        # survivors are scaled by 1/q; the others end here, their throughput no longer matters
        S.beta[r] *= np.where(survive[j], 1.0 / np.maximum(q, 1e-30), 1.0)[:, None]
        return survive

    def _surfaces(self, S, s, hits, L, ctx):
        """Shade surface hits s; returns which of them continue."""
        accel = self.accel
        st = self.settings
        prim = hits.prim[s]
        t = hits.t[s]
        d_s = S.d[s]
        ng = accel.normals[prim]
        front = _dot(d_s, ng) < 0
        cont = np.ones(len(s), bool)
        eps = accel.epsilon

        # null boundary: cross it, update the volume stack, keep the direction
        null = self.tri_null[prim]
        k = np.nonzero(null)[0]
        if len(k):
            a = s[k]
            sub = S.counts[a]
            self.media.cross(sub, prim[k], front[k])
            S.counts[a] = sub
            if self.media.any_medium:
                S.m_ss[a], S.m_st[a], S.m_em[a], S.m_g[a] = self.media.coefficients(sub)
            step = t[k] + eps
            S.o[a] += d_s[k] * step[:, None]
            S.lead[a] = eps
            S.travelled[a] += step
            S.tmax[a] -= step
            S.bounds[a] += 1
            cont[k] = S.bounds[a] <= MAX_VOLUME_BOUNDS
        if len(k) == len(s):
            return cont
        opaque = np.nonzero(~null)[0]  # integer gathers are faster than boolean masks
        b = s[opaque]
        primb, ngb, frontb = prim[opaque], ng[opaque], front[opaque]
        pb = S.o[b] + d_s[opaque] * t[opaque][:, None]
        ctx.stats["vertices"] += len(b)

        # emission (two-sided by default), MIS against the light-sampling pdf
        em = self.tri_emissive[primb]
        if em.any():
            e = b[em]
            dist = S.travelled[e] + t[opaque][em]
            radiance, lpdf = self.lights.triangle_emission(primb[em], S.prev_pos[e], S.d[e], dist, frontb[em])
            w = np.where(S.prev_pdf[e] > 0, _power_heuristic(S.prev_pdf[e], lpdf), 1.0)
            L[S.pid[e]] += S.beta[e] * radiance * w[:, None]

        # terminate-after-transparent paths end here; black surfaces absorb everything
        albedo_b = self.mat_albedo[self.accel.material_ids[primb]]
        i = np.nonzero(~S.tat[b] & any_positive(albedo_b))[0]
        bi = b[i]
        albedo = albedo_b[i]
        n_face = ngb[i] * np.where(frontb[i], 1.0, -1.0)[:, None]
        origin = pb[i] + n_face * eps
        ns = accel.shading_normals(primb[i], hits.u[bi], hits.v[bi]) if accel.has_smooth else ngb[i]
        if accel.has_smooth:
            ns = ns * np.where(_dot(ns, n_face) < 0, -1.0, 1.0)[:, None]
        else:
            ns = n_face
        if len(i) and self.lights.count:
            u_select, u_light1, u_light2 = self._us(S, (D_SURF_SELECT, D_SURF_LU, D_SURF_LV), bi)
            rows = self.lights.select(u_select)
            ls = self.lights.sample(rows, origin, u_light1, u_light2)
            f, bsdf_pdf = lambert_eval(albedo, ns, ls.wi)
            above = _dot(ls.wi, n_face) > 0
            w = np.where(ls.pdf > 0, _power_heuristic(ls.pdf, bsdf_pdf), 1.0)
            contrib = S.beta[bi] * f * ls.value * (w * above)[:, None]
            nz = np.nonzero(any_positive(contrib))[0]
            if len(nz):
                tr = self._shadow(origin[nz], ls.wi[nz], ls.dist[nz], S.counts[bi[nz]], ctx,
                                  S.m_st[bi[nz]] if S.m_st is not None else None)
                L[S.pid[bi[nz]]] += contrib[nz] * tr
        # continue with a cosine-sampled direction
        wi, weight, pdf = lambert_sample(albedo, ns, *self._us(S, (D_BSDF_U, D_BSDF_V), bi))
        ok = _dot(wi, n_face) > 0  # smooth normals may point below the geometric surface
        S.o[bi], S.d[bi] = origin, wi
        S.beta[bi] = S.beta[bi] * weight * ok[:, None]
        S.prev_pos[bi], S.prev_pdf[bi] = origin, pdf
        S.travelled[bi] = 0.0
        S.tmax[bi] = np.inf
        S.bounce[bi] += 1
        S.diffuse[bi] += 1
        S.tat[bi] |= (S.diffuse[bi] > st.diffuse_bounces) | (S.bounce[bi] > st.max_bounces)
        survive = np.zeros(len(b), bool)
        survive[i] = self._russian_roulette(S, bi)
        cont[opaque] = survive
        return cont

    # -----------------------------------------------------------------------------------------
    def _medium_nee(self, S, i, L, sig_s, sig_t, g, t_end, ctx):
        """One next-event vertex per medium segment (see module docstring)."""
        lights = self.lights
        mode = self.settings.volume_sampling
        o, d, beta = S.o[i], S.d[i], S.beta[i]
        u_select, u_t, u_channel, u_tech, u_light1, u_light2 = self._us(
            S, (D_MED_SELECT, D_MED_T, D_MED_CHANNEL, D_MED_TECH, D_MED_LU, D_MED_LV), i)
        rows = lights.select(u_select)
        positional = lights.has_position(rows)
        valid = (sig_t > 0) | np.isfinite(t_end)[:, None]
        p = md.channel_probabilities(beta, sig_s, sig_t, valid)
        can_distance = sum3(p) > 0
        can_equi = positional & (mode != "distance")
        if mode == "equiangular":
            prob_eq = np.where(can_equi, 1.0, 0.0)
        else:
            prob_eq = np.where(can_equi & can_distance, 0.5, np.where(can_equi, 1.0, 0.0))
        prob_eq = np.where(~can_equi & ~can_distance, 0.0, prob_eq)
        usable = can_equi | can_distance
        setup = md.equiangular_setup(o, d, t_end, lights.position[rows])
        t_eq, _ = md.equiangular_sample(setup, u_t)
        t_di = md.sample_distance_truncated(sig_t, p, u_channel, u_t, t_end)
        use_eq = u_tech < prob_eq
        t = np.where(use_eq, t_eq, t_di)
        t = np.where(np.isfinite(t), t, 0.0)
        pdf_t = prob_eq * md.equiangular_pdf(setup, t) + \
            (1.0 - prob_eq) * np.where(can_distance, md.truncated_distance_pdf(sig_t, p, t, t_end), 0.0)
        good = usable & (pdf_t > 0) & np.isfinite(pdf_t)
        x = o + d * t[:, None]
        ls = lights.sample(rows, x, u_light1, u_light2)
        cos_theta = _dot(d, ls.wi)
        phase = hg_eval(g, cos_theta)  # the phase pdf (MIS) ...
        scattering = sig_s * phase[:, None]  # ... and sigma_s x phase, per channel
        if self.media.mixed_phase:
            m = np.nonzero(self.media.phase_is_mixed(S.counts[i]))[0]
            if len(m):
                sigma_k, g_k = self.media.phase_components(S.counts[i[m]])
                scattering[m], phase[m] = _phase_mixture(
                    [(sigma_k[:, k], np.full(len(m), g_k[k])) for k in range(len(g_k))], cos_theta[m])
        w = np.where(ls.pdf > 0, _power_heuristic(ls.pdf, phase), 1.0)
        scale = np.where(good, w / np.where(good, pdf_t, 1.0), 0.0)
        contrib = beta * md.transmittance(sig_t, t) * scattering * scale[:, None] * ls.value
        nz = np.nonzero(any_positive(contrib))[0]
        if len(nz):
            tr = self._shadow(x[nz], ls.wi[nz], ls.dist[nz], S.counts[i[nz]], ctx, sig_t[nz])
            L[S.pid[i[nz]]] += contrib[nz] * tr

    def _shadow(self, origin, wi, dist, counts, ctx, sig_t=None):
        """Transmittance (N,3) from origin toward wi over dist, through null boundaries and media."""
        n = len(origin)
        eps = self.accel.epsilon
        margin = 2.0 * eps  # stop short of the light's own surface; attenuated like the rest
        remaining = np.where(np.isfinite(dist), np.maximum(dist - margin, 0.0), np.inf)
        T = np.ones((n, 3))
        if not self.has_null:
            ctx.stats["shadow_rays"] += n
            blocked = self.accel.occluded(origin, wi, remaining)
            if self.media.any_medium:
                if sig_t is None:
                    sig_t = self.media.sigma_t(counts)
                T *= md.transmittance(sig_t, remaining + margin)
            T[blocked] = 0.0
            return T
        counts = counts.copy()
        origin = origin.copy()
        alive = np.arange(n)
        lead = np.zeros(n)
        seg_sig_t = sig_t  # coefficients of the first segment, if the caller has them
        for _ in range(MAX_VOLUME_BOUNDS):
            if not len(alive):
                break
            hits = self.accel.intersect(origin[alive], wi[alive], remaining[alive])
            ctx.stats["shadow_rays"] += len(alive)
            hit = hits.prim >= 0
            seg = np.where(hit, hits.t, remaining[alive])
            if self.media.any_medium:
                if seg_sig_t is None:
                    seg_sig_t = self.media.sigma_t(counts[alive])
                T[alive] *= md.transmittance(seg_sig_t, seg + lead[alive] + np.where(hit, 0.0, margin))
                if self.media.has_grids:
                    T[alive] *= self._grid_transmittance(origin[alive], wi[alive], seg, counts[alive], ctx)
            null = hit & self.tri_null[np.maximum(hits.prim, 0)]
            T[alive[hit & ~null]] = 0.0
            a = alive[null]
            prim = hits.prim[null]
            ng = self.accel.normals[prim]
            front = _dot(wi[a], ng) < 0
            sub = counts[a]
            self.media.cross(sub, prim, front)
            counts[a] = sub
            origin[a] = origin[a] + wi[a] * (seg[null] + eps)[:, None]
            remaining[a] = remaining[a] - seg[null] - eps
            lead[a] = eps
            alive = a[remaining[a] > 0]
            seg_sig_t = None
        T[alive] = 0.0
        return T

    # -----------------------------------------------------------------------------------------
    # Heterogeneous (grid) media: delta tracking and ratio tracking from grid_medium.GridMedium.
    # A homogeneous medium overlapping a grid is sampled first and the grid tracked only up to its
    # event (the earlier of two independent collision processes is the first event of their sum).
    # -----------------------------------------------------------------------------------------
    def _grid_transmittance(self, origins, dirs, dist, counts, ctx):
        """Product of ratio-tracking estimates over the grid volumes each ray is inside."""
        T = np.ones((len(origins), 3))
        for v, grid in self.media.grid_volumes:
            sub = np.nonzero(counts[:, v] > 0)[0]
            if len(sub):
                T[sub] *= grid.transmittance(origins[sub], dirs[sub], dist[sub], ctx.rng)
        return T

    def _sample_phase_mixture(self, S, j, sig_s, u1, u2):
        """Scattered directions at homogeneous events of paths j whose stack mixes media of
        different g: component k picked with probability ~ mean sigma_s,k (as Cycles'
        volume_shader_phase_pick, kernel/integrator/volume_shader.h), HG(g_k) sampled, and
        beta *= f / (sigma_s pdf) with f_c = sum_k sigma_s,k,c HG_k and pdf = sum_k p_k HG_k (the
        collision weight already holds sigma_s). Returns (wo, mixture pdf) for MIS."""
        sigma_k, g_k = self.media.phase_components(S.counts[j])
        weights = sigma_k.mean(axis=2)
        total = weights.sum(axis=1)
        probabilities = weights / np.where(total > 0, total, 1.0)[:, None]
        wo, pdf, _ = hg_mixture_sample(S.d[j], probabilities, g_k, u1, u2)
        hg = hg_eval(g_k[None, :], _dot(S.d[j], wo)[:, None])
        f = np.einsum("mkc,mk->mc", sigma_k, hg)
        ok = (sig_s > 0) & (pdf > 0)[:, None]
        S.beta[j] *= np.where(ok, f / np.where(ok, sig_s * pdf[:, None], 1.0), 0.0)
        return wo, pdf

    def _scattering_components(self, x, counts, sig_s_hom, g_hom):
        """[(sigma_s (M,3), g (M,))] of every medium scattering at points x."""
        if self.media.mixed_phase:
            sigma_k, g_k = self.media.phase_components(counts)
            comps = [(sigma_k[:, k], np.full(len(x), g_k[k])) for k in range(len(g_k))]
        else:
            comps = [(sig_s_hom, g_hom)]
        for v, grid in self.media.grid_volumes:
            inside = counts[:, v] > 0
            if inside.any():
                ss = np.zeros((len(x), 3))
                ss[inside], _, _ = grid.coefficients(x[inside])
                comps.append((ss, np.full(len(x), grid.g)))
        return comps

    def _grid_segment(self, S, G, L, beta_in, sig_s, sig_t, t_seg, scatter, t_scatter, phase_g, grid_scattered,
                      ctx):
        """Free flight for paths G inside grid volumes (coefficient arrays are already [G])."""
        beta = S.beta[G]
        m = len(G)
        weight = np.ones((m, 3))
        tat = S.tat[G]
        a = np.nonzero(tat)[0]
        if len(a):  # attenuation only
            weight[a] = md.transmittance(sig_t[a], t_seg[a]) * self._grid_transmittance(
                S.o[G[a]], S.d[G[a]], t_seg[a], S.counts[G[a]], ctx)
        live = np.nonzero(~tat)[0]
        if len(live):
            gl = G[live]
            hom = max3(sig_s[live]) > 0
            p = np.zeros((len(live), 3))
            ts = np.full(len(live), np.inf)
            h = np.nonzero(hom)[0]
            if len(h):
                p[h] = md.channel_probabilities(beta[live[h]], sig_s[live[h]], sig_t[live[h]])
                ts[h] = md.sample_distance(sig_t[live[h]], p[h], self._u(S, D_CHANNEL, gl[h]),
                                           self._u(S, D_DISTANCE, gl[h]))
            t_end = np.minimum(ts, t_seg[live])
            w = np.ones((len(live), 3))
            grid_event = np.zeros(len(live), bool)
            g_event = phase_g[gl].copy()
            for v, grid in self.media.grid_volumes:
                sub = np.nonzero(S.counts[gl, v] > 0)[0]
                if not len(sub):
                    continue
                f = grid.sample_free_flight(S.o[gl[sub]], S.d[gl[sub]], t_end[sub], ctx.rng,
                                            throughput=beta[live[sub]] * w[sub])
                L[S.pid[gl[sub]]] += beta_in[gl[sub]] * w[sub] * f.emission
                w[sub] *= f.weight
                sc = np.nonzero(f.scattered)[0]
                t_end[sub[sc]] = f.t[sc]
                grid_event[sub[sc]] = True
                g_event[sub[sc]] = grid.g
            hom_event = hom & ~grid_event & (ts < t_seg[live])
            t_eval = np.where(grid_event | hom_event, t_end, t_seg[live])
            factor = md.transmittance(sig_t[live], t_eval)  # absorbing-only homogeneous part
            if len(h):
                pdf, surv, tr = md.distance_pdf(sig_t[live[h]], p[h], t_eval[h])
                collide = hom_event[h]
                pass_w = np.where(surv[:, None] > 0, tr / np.where(surv > 0, surv, 1.0)[:, None], 0.0)
                coll_w = sig_s[live[h]] * tr / np.maximum(pdf, 1e-300)[:, None]
                factor[h] = np.where(collide[:, None], coll_w, pass_w)
            weight[live] = w * factor
            event = grid_event | hom_event
            scatter[gl[event]] = True
            t_scatter[gl[event]] = t_eval[event]
            phase_g[gl] = g_event
            grid_scattered[gl[grid_event]] = True
        S.beta[G] = beta * weight

    def _grid_nee(self, S, i, L, sig_s, sig_t, g, t_end, ctx):
        """Next-event vertex per segment for paths inside grid volumes: the distance is drawn by
        equiangular sampling (positional lights) or uniformly on the bounded segment, one-sample
        MIS of the two; sigma_s and transmittance come from the grids (ratio tracking)."""
        lights = self.lights
        mode = self.settings.volume_sampling
        o, d, beta = S.o[i], S.d[i], S.beta[i]
        rows = lights.select(self._u(S, D_MED_SELECT, i))
        finite = np.isfinite(t_end) & (t_end > 0)
        can_equi = lights.has_position(rows) & (mode != "distance" or ~finite)
        if mode == "equiangular":
            prob_eq = np.where(can_equi, 1.0, 0.0)
        else:
            prob_eq = np.where(can_equi, np.where(finite, 0.5, 1.0), 0.0)
        usable = can_equi | finite
        setup = md.equiangular_setup(o, d, t_end, lights.position[rows])
        u_t = self._u(S, D_MED_T, i)
        t_eq, _ = md.equiangular_sample(setup, u_t)
        te = np.where(finite, t_end, 0.0)
        use_eq = self._u(S, D_MED_TECH, i) < prob_eq
        t = np.where(use_eq, t_eq, u_t * te)
        t = np.where(np.isfinite(t), t, 0.0)
        pdf_t = prob_eq * md.equiangular_pdf(setup, t) + (1.0 - prob_eq) * np.where(finite, 1.0 / np.where(finite, te, 1.0), 0.0)
        good = usable & (pdf_t > 0) & np.isfinite(pdf_t)
        x = o + d * t[:, None]
        ls = lights.sample(rows, x, self._u(S, D_MED_LU, i), self._u(S, D_MED_LV, i))
        comps = self._scattering_components(x, S.counts[i], sig_s, g)
        f_rgb, phase_pdf = _phase_mixture(comps, _dot(d, ls.wi))
        w = np.where(ls.pdf > 0, _power_heuristic(ls.pdf, phase_pdf), 1.0)
        scale = np.where(good, w / np.where(good, pdf_t, 1.0), 0.0)
        contrib = beta * md.transmittance(sig_t, t) * f_rgb * scale[:, None] * ls.value
        nz = np.nonzero(any_positive(contrib))[0]
        if len(nz):
            contrib = contrib[nz] * self._grid_transmittance(o[nz], d[nz], t[nz], S.counts[i[nz]], ctx)
            tr = self._shadow(x[nz], ls.wi[nz], ls.dist[nz], S.counts[i[nz]], ctx)
            L[S.pid[i[nz]]] += contrib * tr


def _phase_mixture(components, cos_theta):
    """Sum of sigma_s * HG over components (RGB) and the mixture's pdf (weights: mean sigma_s)."""
    # Cycles: kernel/integrator/volume_shader.h _volume_shader_phase_eval_mis (value = sum of the
    # closures' weighted evals, pdf = sample-weighted mean of their pdfs)
    f = np.zeros((len(cos_theta), 3))
    num = np.zeros(len(cos_theta))
    den = np.zeros(len(cos_theta))
    for sigma_s, g in components:
        ph = hg_eval(g, cos_theta)
        f += sigma_s * ph[:, None]
        weight = sum3(sigma_s) / 3.0
        num += weight * ph
        den += weight
    return f, np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
