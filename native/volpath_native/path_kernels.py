"""Compiled wavefront stages: one loop over the live paths per stage, between the bulk Embree
queries that integrator.py issues (pbrt-v4 src/pbrt/wavefront/integrator.cpp runs the same stages
as ParallelFor loops over its queues).

Path state is a structure of arrays packed for locality: `F` (n, NF) float64 fields, `I` (n, NI)
int64 fields, `K` (n,) uint64 random keys, `C` (n, V) int8 volume-stack counters, and the next ray
of each path in Embree's float32 layout. Shadow rays produced by a stage go to a queue
(ShadowQueue, the same layout) and are traced in bulk afterwards.

Estimators and their references (each block below says which it implements):
- free flight in chromatic media: one-sample spectral MIS, channel pdf averaged (pbrt-v4
  media.h SampleT_maj; Cycles kernel/integrator/shade_volume.h volume_sample_channel).
- direct light in media: a separate NEE vertex per segment whose distance is drawn from
  equiangular (toward the chosen light) or distance sampling, one-sample MIS with the mixture
  (balance) pdf (Kulla & Fajardo 2012; Cycles shade_volume.h volume_equiangular_sample /
  volume_equiangular_pdf, which weights with the power heuristic instead); light vs phase
  sampling combined with the power heuristic.
- light vs BSDF/phase sampling for hittable emitters: power heuristic (Veach 1997; Cycles
  kernel/sample/mis.h). Both NEE vertices use weights that depend only on the (vertex, direction)
  pair, so the two estimators sum to the direct light exactly.
- bounce limits: Cycles' path_state.h: after a scatter the counters grow; exceeding a limit sets
  "terminate after transparent" (the path still crosses null boundaries and collects emission
  with MIS, then ends). Russian roulette: survive with min(sqrt(max beta), 1).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from .bsdfs.closures import (LABEL_DIFFUSE, LABEL_TRANSMIT, LABEL_TRANSPARENT, setup_surface_tangent,
                             surface_eval, surface_is_transmissive, surface_sample, surface_transparency)
from .camera import camera_ray1, ray_time1
from .emissive_media import bounce_share, sample_emissive_point
from .film import filter_offset1
from .grid_kernels import STREAM_DIMENSIONS
from .grid_slots import (slot_attenuation, slot_cell_max_extinction, slot_control_occupancy, slot_emission,
                         slot_free_flight, slot_g, slot_nee_distance_pdf_given, slot_nee_distance_sample_pdf_given,
                         slot_scattering, slot_transmittance)
from .glow_guide import (GLOW_SHARE, glow_pdf, glow_sample, guided_label, medium_glow_pdf, medium_glow_sample,
                         medium_glow_share, mixture_pdf, surface_has_delta)
from .jit import inline_stage_kernel, stage_kernel
from .light_kernels import (TRIANGLE, equiangular_centre, lamp_crossing_unselected, light_has_position,
                            sample_light_selected, triangle_emission_unselected, triangle_sample_barycentrics)
from .light_tree import (MODE_SURFACE, MODE_SURFACE_TRANSMIT, MODE_VOLUME, escaped_emission_mis_at, tree_pdf,
                         tree_select)
from .light_segment import light_segment
from .media import (channel_probabilities1, distance_pdf1, emission_integral1, equiangular_pdf1,
                    equiangular_sample1, equiangular_setup1, sample_distance1, sample_distance_truncated1,
                    transmittance1, transmittance3, truncated_distance_pdf1)
from .mis import mis_weight, power_heuristic
from .phase import hg_eval1, hg_sample1
from .sample_pattern import path_key1, sample1, sample2
from .sampling import CAMERA_DIMS, DIMS_PER_EVENT, LENS_U_DIM, LENS_V_DIM, SHUTTER_TIME_DIM
from .instance_motion import normal_map1
from .motion_triangles import deform_step, deformed_corners1, is_deforming
from .surface_programs import (frame_at_time, has_program_emission, program_emission, program_shading_normal,
                               shade_surface_program)
from .table_ref import table_ref

# F columns
O, D, BETA, PREV = 0, 3, 6, 9
TMAX, PREV_PDF, TRAVELLED, LEAD = 12, 13, 14, 15
SS, ST, EM, G = 16, 19, 22, 25
TIME = 26  # the path's shutter time in [0, 1]: its camera ray's, inherited by every later ray
# Where the last scattering vertex chose its light (light_tree: a surface point and normal, or the
# volume segment's start, direction and length): lamps, emitters and escaped rays it finds weigh
# their MIS against the selection probability from there.
MIS_P, MIS_N, MIS_T = 27, 30, 33
NF = 34
# I columns: path id, bounce counters (Cycles' path_state: total, diffuse, volume, glossy,
# transmission, transparent), null-boundary crossings, "terminate after transparent"
PID, BOUNCE, DIFFUSE, VOLUME, BOUNDS, TAT, GLOSSY, TRANSMISSION, TRANSPARENT, MIS_MODE = range(10)
NI = 10
# shadow queue SF columns; SI columns: path id, purpose (which NEE queued it); SK: path key
S_O, S_D, S_REMAINING, S_CONTRIB, S_ST, S_LEAD, S_TIME = 0, 3, 6, 7, 10, 13, 14
NSF = 15
SI_PID, SI_PURPOSE = 0, 1
NSI = 2
# Grid tracking draws from its own streams of dimensions (grid_kernels): one per iteration,
# purpose, shadow step and grid, far above the per-iteration dimensions of the path.
P_FREE_FLIGHT, P_NEE_SEGMENT, P_LAMP, P_SHADOW_MEDIUM, P_SHADOW_SURFACE, P_SHADOW_EMISSION, P_EMISSION_DIRECT = range(7)
N_PURPOSES = 7
_STREAM_BASE = 1 << 40
_MAX_STEPS, _MAX_GRIDS = 64, 16

# Random dimensions within one iteration (see sampling.CAMERA_DIMS).
D_CHANNEL, D_DISTANCE, D_MED_SELECT, D_MED_TECH, D_MED_T, D_MED_CHANNEL, D_MED_LU, D_MED_LV, \
    D_PHASE_U, D_PHASE_V, D_RR, D_SURF_SELECT, D_SURF_LU, D_SURF_LV, D_BSDF_U, D_BSDF_V, D_SURF_PICK = range(17)
D_MED_ROULETTE = 18  # its own Sobol' pair (18, 19)
D_EMIT_CELL, D_EMIT_U, D_EMIT_V, D_EMIT_W = 17, 20, 21, 22  # a surface vertex's emissive-media sample
assert D_EMIT_W < DIMS_PER_EVENT
# pairs drawn together by _u2 (even offset, partner next)
assert all(a % 2 == 0 and b == a + 1 for a, b in ((D_CHANNEL, D_DISTANCE), (D_MED_T, D_MED_CHANNEL),
                                                  (D_MED_LU, D_MED_LV), (D_PHASE_U, D_PHASE_V),
                                                  (D_SURF_LU, D_SURF_LV), (D_BSDF_U, D_BSDF_V), (D_EMIT_U, D_EMIT_V)))
#: survival probability of a grid next-event vertex in a majorant cell that looked empty (see
#: _empty_cell_survival)
EMPTY_CELL_SURVIVAL = 0.125
#: how often a grid segment's next event toward a positional light draws its distance
#: equiangularly rather than from the control extinction, where the medium fills the segment evenly
#: (Cycles' fixed 1/2, shade_volume.h volume_integrate_state_init); _grid_nee scales it by the
#: segment's occupancy (grid_kernels.grid_control_occupancy): equiangular distances ignore the
#: density, and in a sparse medium most land where nothing scatters. Measured, error per sample
#: against the fixed 1/2 (paired seeds): noise cloud (a point lamp outside a sparse cloud) 0.93 --
#: a fixed 0 gave 0.89-0.96 there but 1.41 on the height fog (a spot inside smooth fog), where the
#: occupancy keeps 1.02 (SceneTables.grid_equiangular_share: tunable without a recompile).
GRID_EQUIANGULAR_SHARE = 0.5

MAX_VOLUME_BOUNDS = 1024  # Cycles' VOLUME_BOUNDS_MAX: null crossings are not transparent bounces
VOLUME_SAMPLING = {"mis": 0, "distance": 1, "equiangular": 2}

ShadowQueue = namedtuple("ShadowQueue", ["F", "I", "K", "C", "o32", "d32", "t32"])

# Everything the stages read about the scene (built once per scene by integrator.py).
SceneTables = namedtuple("SceneTables", [
    "tri_null", "tri_emissive", "tri_material", "tri_transparent", "normals", "corner_normals", "has_smooth", "tri_volume",
    "inst_normal", "inst_frame_base", "inst_steps", "inst_motion", "has_motion",
    "has_deformation", "deform_rows", "deform_corners", "deform_normals",
    "vol_sigma_s", "vol_sigma_a", "vol_emission", "vol_g", "vol_is_grid",
    "world_sigma_s", "world_sigma_a", "world_emission", "world_g",
    "phase_g", "vol_lobe_sigma", "world_lobe_sigma", "mixed_phase",
    "vol_grid", "has_grids",
    "epsilon", "any_medium", "max_bounces", "diffuse_bounces", "volume_bounces", "glossy_bounces",
    "transmission_bounces", "transparent_bounces", "rr_min_bounces",
    "volume_sampling", "grid_equiangular_share", "glow",  # glow: glow_guide.GlowTable
    "emitters"])  # emissive_media.EmissiveMedia


@stage_kernel
def _u(K, p, iteration, offset):
    return sample1(K[p], CAMERA_DIMS + iteration * DIMS_PER_EVENT + offset)


@stage_kernel
def _u2(K, p, iteration, offset):
    """(_u at offset, _u at offset + 1) for an even offset: the two numbers of one Sobol' pair
    (sample2; CAMERA_DIMS and DIMS_PER_EVENT are even)."""
    return sample2(K[p], CAMERA_DIMS + iteration * DIMS_PER_EVENT + offset)


@stage_kernel
def _get3(A, p, col):
    return A[p, col], A[p, col + 1], A[p, col + 2]


@stage_kernel
def _set3(A, p, col, v):
    A[p, col] = v[0]
    A[p, col + 1] = v[1]
    A[p, col + 2] = v[2]


@stage_kernel
def _max3(v):
    return max(v[0], max(v[1], v[2]))


@stage_kernel
def _mul3(a, b):
    return a[0] * b[0], a[1] * b[1], a[2] * b[2]


@stage_kernel
def _scale3(a, s):
    return a[0] * s, a[1] * s, a[2] * s


@stage_kernel
def _dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


# Largest float32: a contribution component beyond it would be inf in a float32 film.
FLOAT32_MAX = float(np.finfo(np.float32).max)


@stage_kernel
def _add_radiance(L, pid, v):
    """L[pid, :3] += v; components that are not finite or beyond float32's range are zeroed and
    the contribution counted in L[pid, 3] (Cycles zeroes non-finite components of every
    contribution: kernel/film/light_passes.h film_clamp_light, util/math_float3.h ensure_finite)."""
    r, g, b = v[0], v[1], v[2]
    ok_r, ok_g, ok_b = abs(r) <= FLOAT32_MAX, abs(g) <= FLOAT32_MAX, abs(b) <= FLOAT32_MAX
    L[pid, 0] += r if ok_r else 0.0
    L[pid, 1] += g if ok_g else 0.0
    L[pid, 2] += b if ok_b else 0.0
    if not (ok_r and ok_g and ok_b):
        L[pid, 3] += 1.0


@stage_kernel
def grid_stream(iteration, purpose, step, grid):
    """First dimension of the stream of grid `grid` for this iteration/purpose/shadow step."""
    index = ((iteration * N_PURPOSES + purpose) * _MAX_STEPS + min(step, _MAX_STEPS - 1)) * _MAX_GRIDS + grid
    return np.uint64(_STREAM_BASE) + np.uint64(index) * np.uint64(STREAM_DIMENSIONS)


@inline_stage_kernel
def inside_grid(S, C, p):
    if not S.has_grids:
        return False
    for v in range(S.vol_grid.shape[0]):
        if C[p, v] > 0 and S.vol_grid[v] >= 0:
            return True
    return False


@inline_stage_kernel
def grids_transmittance(S, GR, C, p, o, d, dist, key, stream_of, time):
    """Product of ratio-tracking estimates (RGB) over the grid volumes path p's stack is inside,
    each placed at shutter time `time`; stream_of: the first dimension of grid 0's stream (see
    grid_stream). Inlined, with grid_slots' constant-index calls: a call taking GR costs more than
    the tracking (grid_slots.py)."""
    t0 = t1 = t2 = 1.0
    for v in range(S.vol_grid.shape[0]):
        gi = S.vol_grid[v]
        if C[p, v] > 0 and gi >= 0:
            r = slot_transmittance(GR, gi, time, o, d, dist, key,
                                   stream_of + np.uint64(gi) * np.uint64(STREAM_DIMENSIONS))
            t0, t1, t2 = t0 * r[0], t1 * r[1], t2 * r[2]
    return t0, t1, t2


# ---------------------------------------------------------------------------------------------
# Volume stack (Cycles kernel/integrator/volume_stack.h): counters per volume, coefficients add
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def stack_coefficients(S, C, p, F):
    """Homogeneous sigma_s, sigma_t, emission and g of path p's stack, written to F. g is the
    sigma_s-weighted mean: exact where one g scatters; mixed stacks use phase components."""
    ss0, ss1, ss2 = S.world_sigma_s[0], S.world_sigma_s[1], S.world_sigma_s[2]
    sa0, sa1, sa2 = S.world_sigma_a[0], S.world_sigma_a[1], S.world_sigma_a[2]
    em0, em1, em2 = S.world_emission[0], S.world_emission[1], S.world_emission[2]
    g_weight = (ss0 + ss1 + ss2) / 3.0
    g_sum = g_weight * S.world_g
    for v in range(S.vol_g.shape[0]):
        if C[p, v] > 0 and not S.vol_is_grid[v]:
            ss0 += S.vol_sigma_s[v, 0]
            ss1 += S.vol_sigma_s[v, 1]
            ss2 += S.vol_sigma_s[v, 2]
            sa0 += S.vol_sigma_a[v, 0]
            sa1 += S.vol_sigma_a[v, 1]
            sa2 += S.vol_sigma_a[v, 2]
            em0 += S.vol_emission[v, 0]
            em1 += S.vol_emission[v, 1]
            em2 += S.vol_emission[v, 2]
            w = (S.vol_sigma_s[v, 0] + S.vol_sigma_s[v, 1] + S.vol_sigma_s[v, 2]) / 3.0
            g_weight += w
            g_sum += w * S.vol_g[v]
    F[p, SS], F[p, SS + 1], F[p, SS + 2] = ss0, ss1, ss2
    F[p, ST], F[p, ST + 1], F[p, ST + 2] = ss0 + sa0, ss1 + sa1, ss2 + sa2
    F[p, EM], F[p, EM + 1], F[p, EM + 2] = em0, em1, em2
    F[p, G] = g_sum / g_weight if g_weight > 0.0 else 0.0


@stage_kernel
def initial_coefficients(S, C, F, n):
    for p in range(n):
        stack_coefficients(S, C, p, F)


@stage_kernel
def start_paths(S, cam, filter_inverse, seed_key, crop, full_width, pixel, sample, stack, F, I, K, C, o32, d32, t32,
                alive):
    """Camera rays and initial state of paths (crop-region pixel index, sample index). crop:
    (x0, y0, width) of the crop region in the full frame; keys use the full-frame pixel, so a crop
    renders exactly the pixels of the full frame. Every path starts in the volume stack `stack`
    (the camera's). alive[p] is False where the camera has no ray (outside a fisheye's circle);
    returns how many such paths there are."""
    x0, y0, crop_width = crop
    unseen = 0
    for p in range(pixel.shape[0]):
        px = x0 + pixel[p] % crop_width
        py = y0 + pixel[p] // crop_width
        key = path_key1(seed_key, py * full_width + px, sample[p])
        lens_u = sample1(key, LENS_U_DIM) if cam.aperture_size > 0.0 else 0.5
        lens_v = sample1(key, LENS_V_DIM) if cam.aperture_size > 0.0 else 0.5
        time = ray_time1(cam, py, sample1(key, SHUTTER_TIME_DIM))
        # Cycles' raster y grows upwards, VolPath's rows downwards: its filter table is not quite
        # symmetric (film.py), so the y offset is mirrored to land where Cycles' lands
        filter_u, filter_v = sample2(key, 0)
        origin, direction, tmax, seen = camera_ray1(
            cam, px + 0.5 + filter_offset1(filter_inverse, filter_u),
            py + 0.5 - filter_offset1(filter_inverse, filter_v), lens_u, lens_v, time)
        alive[p] = seen
        if not seen:
            unseen += 1
        for j in range(F.shape[1]):
            F[p, j] = 0.0
        _set3(F, p, O, origin)
        _set3(F, p, D, direction)
        _set3(F, p, BETA, (1.0, 1.0, 1.0))
        _set3(F, p, PREV, origin)
        F[p, TMAX] = tmax
        F[p, TIME] = time
        for j in range(I.shape[1]):
            I[p, j] = 0
        I[p, PID] = p
        K[p] = key
        for v in range(C.shape[1]):
            C[p, v] = stack[v]
        if p == 0:
            stack_coefficients(S, C, p, F)
        else:  # the same stack: the same coefficients
            for j in range(SS, G + 1):
                F[p, j] = F[0, j]
        _write_ray(F, p, O, D, TMAX, o32, d32, t32, p)
    return unseen


@inline_stage_kernel
def stack_sigma_t(S, C, p):
    s0 = S.world_sigma_s[0] + S.world_sigma_a[0]
    s1 = S.world_sigma_s[1] + S.world_sigma_a[1]
    s2 = S.world_sigma_s[2] + S.world_sigma_a[2]
    for v in range(S.vol_g.shape[0]):
        if C[p, v] > 0 and not S.vol_is_grid[v]:
            s0 += S.vol_sigma_s[v, 0] + S.vol_sigma_a[v, 0]
            s1 += S.vol_sigma_s[v, 1] + S.vol_sigma_a[v, 1]
            s2 += S.vol_sigma_s[v, 2] + S.vol_sigma_a[v, 2]
    return s0, s1, s2


@inline_stage_kernel
def cross_boundary(S, C, p, prim, front):
    """Enter (front face) or leave (back face) the volume bounded by triangle prim."""
    v = S.tri_volume[prim]
    if v >= 0:
        c = np.int16(C[p, v]) + (1 if front else -1)
        C[p, v] = np.int8(min(max(c, 0), 127))


@stage_kernel
def _component_sigma(S, C, p, k):
    """sigma_s (RGB) of phase component k (media of one g) in path p's stack."""
    s0, s1, s2 = S.world_lobe_sigma[k, 0], S.world_lobe_sigma[k, 1], S.world_lobe_sigma[k, 2]
    for v in range(S.vol_g.shape[0]):
        if C[p, v] > 0 and not S.vol_is_grid[v]:
            s0 += S.vol_lobe_sigma[v, k, 0]
            s1 += S.vol_lobe_sigma[v, k, 1]
            s2 += S.vol_lobe_sigma[v, k, 2]
    return s0, s1, s2


@stage_kernel
def _phase_is_mixed(S, C, p):
    if not S.mixed_phase:
        return False
    scattering = 0
    for k in range(S.phase_g.shape[0]):
        if _max3(_component_sigma(S, C, p, k)) > 0.0:
            scattering += 1
    return scattering > 1


@stage_kernel
def _phase_mixture_eval(S, C, p, cos_theta):
    """(sum_k sigma_s,k HG(g_k) per channel, mixture pdf with weights mean sigma_s,k); Cycles
    kernel/integrator/volume_shader.h _volume_shader_phase_eval_mis."""
    f0 = f1 = f2 = 0.0
    num = den = 0.0
    for k in range(S.phase_g.shape[0]):
        sk = _component_sigma(S, C, p, k)
        ph = hg_eval1(S.phase_g[k], cos_theta)
        f0 += sk[0] * ph
        f1 += sk[1] * ph
        f2 += sk[2] * ph
        w = (sk[0] + sk[1] + sk[2]) / 3.0
        num += w * ph
        den += w
    return (f0, f1, f2), (num / den if den > 0.0 else 0.0)


@stage_kernel
def _phase_mixture_sample(S, C, p, d, u1, u2):
    """Pick component k with probability ~ mean sigma_s,k (u1 rescaled and reused, as Cycles'
    volume_shader_phase_pick) and sample HG(g_k); returns (wo, f (RGB), mixture pdf)."""
    total = 0.0
    for k in range(S.phase_g.shape[0]):
        sk = _component_sigma(S, C, p, k)
        total += (sk[0] + sk[1] + sk[2]) / 3.0
    chosen = S.phase_g.shape[0] - 1
    lower = 0.0
    p_k = 0.0
    for k in range(S.phase_g.shape[0]):
        sk = _component_sigma(S, C, p, k)
        p_k = (sk[0] + sk[1] + sk[2]) / 3.0 / total if total > 0.0 else 0.0
        if u1 < lower + p_k or k == S.phase_g.shape[0] - 1:
            chosen = k
            break
        lower += p_k
    u_within = min(max((u1 - lower) / p_k if p_k > 0.0 else 0.0, 0.0), 1.0 - 1e-12)
    x, y, z, _ = hg_sample1(d[0], d[1], d[2], S.phase_g[chosen], u_within, u2)
    wo = (x, y, z)
    f, pdf = _phase_mixture_eval(S, C, p, _dot3(d, wo))
    return wo, f, pdf


@stage_kernel
def _write_ray(A, row, origin, direction, length, o32, d32, t32, out):
    """Row `out` of Embree's float32 ray buffers from a packed state row (paths: O, D, TMAX;
    shadow queue: S_O, S_D, S_REMAINING)."""
    for c in range(3):
        o32[out, c] = A[row, origin + c]
        d32[out, c] = A[row, direction + c]
    t32[out] = min(A[row, length], 1e30)


@inline_stage_kernel
def _push_shadow(Q, C, K, p, n_shadow, origin, wi, dist, contrib, sigma_t, margin, pid, purpose, time):
    q = n_shadow
    Q.F[q, S_TIME] = time
    Q.K[q] = K[p]
    Q.I[q, SI_PURPOSE] = purpose
    _set3(Q.F, q, S_O, origin)
    _set3(Q.F, q, S_D, wi)
    Q.F[q, S_REMAINING] = max(dist - margin, 0.0) if np.isfinite(dist) else np.inf
    _set3(Q.F, q, S_CONTRIB, contrib)
    _set3(Q.F, q, S_ST, sigma_t)
    Q.F[q, S_LEAD] = 0.0
    Q.I[q, SI_PID] = pid
    for v in range(C.shape[1]):
        Q.C[q, v] = C[p, v]
    _write_ray(Q.F, q, S_O, S_D, S_REMAINING, Q.o32, Q.d32, Q.t32, q)
    return q + 1


@inline_stage_kernel
def _scatter_to(S, F, I, p, x, wo, pdf, kind, kind_limit):
    """Start path p's next segment at scattering vertex x toward wo (sampled with pdf). The bounce
    counters grow as in Cycles' path_state_next; past a limit the path is "terminate after
    transparent". kind: the I column counting this kind of bounce (VOLUME, DIFFUSE, GLOSSY or
    TRANSMISSION)."""
    _set3(F, p, O, x)
    _set3(F, p, D, wo)
    _set3(F, p, PREV, x)
    F[p, PREV_PDF] = pdf
    F[p, TRAVELLED] = 0.0
    F[p, TMAX] = np.inf
    I[p, kind] += 1
    I[p, BOUNCE] += 1
    if I[p, kind] > kind_limit or I[p, BOUNCE] > S.max_bounces:
        I[p, TAT] = 1


@stage_kernel
def _russian_roulette(S, F, I, K, p, iteration):
    """True if path p survives; survivors are scaled by 1/q."""
    if I[p, BOUNCE] <= S.rr_min_bounces:
        return True
    q = min(np.sqrt(max(abs(F[p, BETA]), max(abs(F[p, BETA + 1]), abs(F[p, BETA + 2])))), 1.0)
    if _u(K, p, iteration, D_RR) < q:
        s = 1.0 / max(q, 1e-30)
        F[p, BETA] *= s
        F[p, BETA + 1] *= s
        F[p, BETA + 2] *= s
        return True
    return False


# ---------------------------------------------------------------------------------------------
# The path stage: everything between a closest-hit query and the next one
# ---------------------------------------------------------------------------------------------
@stage_kernel
def shade(S, T, GR, SN, BT, CB, SP, SPS, n, iteration, F, I, K, C, hit_t, hit_prim, hit_inst, hit_u, hit_v, L, alive,
          Q, stats, o32, d32, t32):
    """Advance paths 0..n-1 by one segment: medium (emission, NEE, free flight), lamps crossed,
    escape, volume scattering or surface interaction (SN: the materials' BSDF nodes, BT: BSDF
    lookup tables, CB: this thread's closure scratch, SP / SPS: surface programs and this thread's
    scratch for them, surface_programs.py). hit_inst: the instance of each hit (-1: a world
    triangle; accel.Accelerator). Shadow rays go to the queue Q; returns its
    length. The next rays of live paths are written to o32, d32, t32. stats: [vertices]
    accumulated."""
    # callees take the tables by reference, not ~4 KB of flattened arrays per call (table_ref.py)
    S, T, GR, SN, BT, CB, SP, SPS, Q = (table_ref(S), table_ref(T), table_ref(GR), table_ref(SN), table_ref(BT),
                                        table_ref(CB), table_ref(SP), table_ref(SPS), table_ref(Q))
    eps = S.epsilon
    margin = 2.0 * eps  # shadow rays stop short of the light's own surface
    n_shadow = 0
    n_lights = T.count
    n_lamps = T.hittable_rows.shape[0]
    for p in range(n):
        pid = I[p, PID]
        prim = hit_prim[p]
        geo = prim >= 0 and hit_t[p] <= F[p, TMAX]
        t_seg = hit_t[p] if geo else F[p, TMAX]
        o = _get3(F, p, O)
        d = _get3(F, p, D)
        ss = _get3(F, p, SS)
        st = _get3(F, p, ST)
        em = _get3(F, p, EM)
        g = F[p, G]
        tat = I[p, TAT] != 0
        in_grid = S.has_grids and inside_grid(S, C, p)
        in_med = in_grid or (S.any_medium and (_max3(st) > 0.0 or _max3(em) > 0.0))
        beta = _get3(F, p, BETA)
        if in_med and F[p, LEAD] > 0.0:
            # the origin sits `lead` past the boundary it just crossed: attenuate that gap exactly
            beta = _mul3(beta, transmittance3(st, F[p, LEAD]))
        F[p, LEAD] = 0.0
        beta_in = beta  # throughput at the segment start (lamp hits look back at it)
        scatter = False
        t_scatter = np.inf
        p_surv = (0.0, 0.0, 0.0)  # channel pdf of the free flight, for lamps crossed
        sampled = False
        event_g = g  # HG parameter of the scattering event
        grid_event = False

        # ---- medium segment ----------------------------------------------------------------
        if in_med:
            if _max3(em) > 0.0:
                _add_radiance(L, pid, _mul3(beta, emission_integral1(em, st, t_seg)))
            if in_grid:
                in_scatter = 0.0
                if not tat and n_lights > 0:
                    n_shadow, in_scatter = _grid_nee(S, T, SP, SPS, GR, F, I, K, C, p, iteration, o, d, beta, ss, st,
                                                     g, t_seg, Q, n_shadow, margin)
                boost = I[p, BOUNCE] == 0 and _world_dimmer(T, in_scatter)
                beta, scatter, t_scatter, event_g, grid_event = _grid_segment(
                    S, GR, K, C, L, p, pid, iteration, o, d, beta, beta_in, ss, st, g, t_seg, tat, F[p, TIME],
                    _bounce_mis(S, F, I, p), boost)
            elif not tat and _max3(ss) > 0.0:
                if n_lights > 0:
                    n_shadow = _medium_nee(S, T, SP, SPS, F, I, K, C, p, iteration, o, d, beta, ss, st, g, t_seg,
                                           Q, n_shadow, margin)
                # free flight (untruncated; reaching the surface is the survival event)
                pc = channel_probabilities1(beta, ss, st, 1.0, 1.0, 1.0)
                p_surv = pc
                sampled = True
                u_channel, u_distance = _u2(K, p, iteration, D_CHANNEL)
                ts = sample_distance1(st, pc, u_channel, u_distance)
                grey = st[1] == st[0] and st[2] == st[0]
                if ts < t_seg:
                    scatter = True
                    t_scatter = ts
                    if grey:  # T / pdf = 1 / sigma_t
                        beta = _scale3(_mul3(beta, ss), 1.0 / st[0])
                    else:
                        pdf, _, tr = distance_pdf1(st, pc, ts)
                        beta = _scale3(_mul3(_mul3(beta, ss), tr), 1.0 / max(pdf, 1e-300))
                elif not grey:  # grey: T / survival = 1
                    _, surv, tr = distance_pdf1(st, pc, t_seg)
                    beta = _scale3(_mul3(beta, tr), 1.0 / surv) if surv > 0.0 else (0.0, 0.0, 0.0)
            else:
                beta = _mul3(beta, transmittance3(st, t_seg))
        _set3(F, p, BETA, beta)

        # ---- lamps crossed before the end of the segment (they do not block) --------------
        if n_lamps > 0:
            # grid paths weight lamps by an independent ratio-tracking estimate of the
            # transmittance (unbiased whatever their own collision), so they reach every lamp
            reach = t_seg if in_grid else min(t_scatter, t_seg)
            prev = _get3(F, p, PREV)
            travelled = F[p, TRAVELLED]
            for k in range(n_lamps):
                if I[p, BOUNCE] == 0 and not T.camera_visible[T.hittable_rows[k]]:
                    continue
                t_l, r0, r1, r2, lpdf = lamp_crossing_unselected(T, k, prev[0], prev[1], prev[2], d[0], d[1], d[2],
                                                                 travelled, travelled + reach)
                if not np.isfinite(t_l):
                    continue
                w = _mis_from_last_vertex(T, F, I, p, T.hittable_rows[k], lpdf)
                weight = beta_in
                if in_med:
                    local_t = t_l - travelled
                    if sampled:
                        _, surv, tr = distance_pdf1(st, p_surv, local_t)
                        weight = _scale3(_mul3(weight, tr), 1.0 / max(surv, 1e-300))
                    else:
                        weight = _mul3(weight, transmittance3(st, local_t))
                    if in_grid:
                        weight = _mul3(weight, grids_transmittance(S, GR, C, p, o, d, local_t, K[p],
                                                                   grid_stream(iteration, P_LAMP, k, 0), F[p, TIME]))
                _add_radiance(L, pid, _scale3(_mul3(weight, (r0, r1, r2)), w))

        # ---- escaped rays ------------------------------------------------------------------
        if not geo and not scatter:
            r = escaped_emission_mis_at(T, d[0], d[1], d[2], F[p, PREV_PDF], I[p, BOUNCE] == 0, F[p, MIS_P],
                                        F[p, MIS_P + 1], F[p, MIS_P + 2], F[p, MIS_N], F[p, MIS_N + 1],
                                        F[p, MIS_N + 2], F[p, MIS_T], I[p, MIS_MODE])
            _add_radiance(L, pid, _mul3(beta, r))
            alive[p] = False
            continue

        if scatter:
            # ---- volume scattering vertex ---------------------------------------------------
            stats[0] += 1
            x = (o[0] + d[0] * t_scatter, o[1] + d[1] * t_scatter, o[2] + d[2] * t_scatter)
            u1, u2 = _u2(K, p, iteration, D_PHASE_U)
            # the share of lamps glowing in this medium (glow_guide): homogeneous one-lobe vertices
            share = medium_glow_share(S.glow, C, p) if S.glow.count > 0 and not in_grid else 0.0
            if grid_event:
                wx, wy, wz, pdf = hg_sample1(d[0], d[1], d[2], event_g, u1, u2)
                wo = (wx, wy, wz)
            elif S.mixed_phase and _phase_is_mixed(S, C, p):
                # beta *= f / (sigma_s pdf): the collision weight already holds sigma_s
                wo, f, pdf = _phase_mixture_sample(S, C, p, d, u1, u2)
                for c in range(3):
                    ok = ss[c] > 0.0 and pdf > 0.0
                    F[p, BETA + c] *= f[c] / (ss[c] * pdf) if ok else 0.0
            elif share > 0.0:  # partly toward lamps glowing in this medium
                if u1 < GLOW_SHARE:
                    wo, ok = medium_glow_sample(S.glow, C, p, share, x, u1 / GLOW_SHARE, u2)
                    phase = hg_eval1(g, _dot3(d, wo)) if ok else 0.0
                else:
                    wx, wy, wz, phase = hg_sample1(d[0], d[1], d[2], g, _rescaled_above(u1, GLOW_SHARE), u2)
                    wo = (wx, wy, wz)
                pdf = mixture_pdf(phase, medium_glow_pdf(S.glow, C, p, share, x, wo))
                _set3(F, p, BETA, _scale3(_get3(F, p, BETA), phase / pdf if pdf > 0.0 else 0.0))
            else:
                wx, wy, wz, pdf = hg_sample1(d[0], d[1], d[2], g, u1, u2)  # phase / pdf == 1
                wo = (wx, wy, wz)
            if in_grid:  # MIS needs the pdf of the whole phase mixture at x (as grid NEE uses)
                pdf = _grid_phase_pdf(S, GR, C, p, x, ss, g, _dot3(d, wo), F[p, TIME])
            _scatter_to(S, F, I, p, x, wo, pdf, VOLUME, S.volume_bounces)
            _set_mis_origin(F, I, p, o, d, t_seg, MODE_VOLUME)  # the segment its NEE chose a light for
            alive[p] = _russian_roulette(S, F, I, K, p, iteration)
        else:
            alive[p], n_shadow = _surface(S, T, GR, SN, BT, CB, SP, SPS, F, I, K, C, p, iteration, prim, hit_inst[p],
                                          hit_t[p], hit_u[p], hit_v[p], L, Q, n_shadow, margin, stats)
        if alive[p]:
            alive[p] = F[p, BETA] > 0.0 or F[p, BETA + 1] > 0.0 or F[p, BETA + 2] > 0.0
        if alive[p]:
            _write_ray(F, p, O, D, TMAX, o32, d32, t32, p)
    return n_shadow


@stage_kernel
def _set_mis_origin(F, I, p, x, n, t, mode):
    """Record where path p's last scattering vertex selected its light (light_tree)."""
    _set3(F, p, MIS_P, x)
    _set3(F, p, MIS_N, n)
    F[p, MIS_T] = t
    I[p, MIS_MODE] = mode


@inline_stage_kernel
def _mis_from_last_vertex(T, F, I, p, row, pdf):
    """MIS weight of light `row` found by BSDF / phase sampling, pdf its solid-angle light-sampling
    pdf from the last vertex: times the probability that vertex's light selection picks it
    (light_tree.tree_pdf, Cycles light/tree.h light_tree_pdf)."""
    prev_pdf = F[p, PREV_PDF]
    if not prev_pdf > 0.0:
        return 1.0
    sel = tree_pdf(T.tree, row, F[p, MIS_P], F[p, MIS_P + 1], F[p, MIS_P + 2], F[p, MIS_N], F[p, MIS_N + 1],
                   F[p, MIS_N + 2], F[p, MIS_T], I[p, MIS_MODE])
    return mis_weight(prev_pdf, pdf * sel)


@inline_stage_kernel
def _select_in_segment(T, K, p, iteration, o, d, t):
    """A light for the next-event vertex of the segment o + s d, s in [0, t]: (row, probability)."""
    return tree_select(T.tree, _u(K, p, iteration, D_MED_SELECT), o[0], o[1], o[2], d[0], d[1], d[2], t, MODE_VOLUME)


@inline_stage_kernel
def _medium_light_sample(S, T, SP, SPS, u_light, row, sel, o, d, t, time):
    """The next-event vertex x = o + t d of a medium segment and a sample of light `row` (chosen
    with probability sel) from it with the pair u_light (D_MED_LU, D_MED_LV) at the path's shutter
    time: (x, wi, dist, value, light pdf, cos(d, wi)), shared by homogeneous and grid NEE."""
    x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
    u1, u2 = u_light
    wx, wy, wz, dist, v0, v1, v2, light_pdf = sample_light_selected(T, row, sel, x[0], x[1], x[2], u1, u2, time)
    value = _textured_light_value(S, T, SP, SPS, row, u1, u2, (wx, wy, wz), (v0, v1, v2), time)
    return x, (wx, wy, wz), dist, value, light_pdf, d[0] * wx + d[1] * wy + d[2] * wz


@inline_stage_kernel
def _rescaled_above(u, start):
    """u in [start, 1) mapped onto [0, 1). A next event picks its technique by where its one
    distance number falls (distance below `start`, equiangular above) and rescales it, as Cycles
    (shade_volume.h volume_integrate_state_init splits rscatter at 0.5): each technique's distances
    stay stratified over a pixel's samples, where a separate technique number would leave each
    technique a random subset of them (measured: 4x the direct-light error of a spot in fog)."""
    return min((u - start) / (1.0 - start), 1.0 - 1e-16)


@inline_stage_kernel
def _equiangular_setup_if(prob_eq, T, u_light, row, o, d, t_lit0, t_lit1, time):
    """equiangular_setup1 toward the light's centre (equiangular_centre, aimed with the light
    sample's own pair u_light) where the technique is used (prob_eq > 0); else a placeholder never
    sampled nor evaluated: a sun's next event skips the square root and the arctan2 (sun row:
    atan2 1.8 % of its render)."""
    if prob_eq > 0.0:
        centre = equiangular_centre(T, row, u_light[0], u_light[1], time)
        return equiangular_setup1(o, d, t_lit0, t_lit1, centre)
    return 0.0, 1.0, 0.0, t_lit0, t_lit1


@inline_stage_kernel
def _equiangular_share(D, pc, st, g):
    """How often a segment's next event draws its distance equiangularly rather than by distance
    (one-sample MIS: any share that depends on the segment alone keeps it unbiased). Equiangular
    sampling is nearly proportional to the integrand where transmittance and phase hardly vary
    across its peak (width ~D): light well within a mean free path of the ray (sigma D small) and a
    flat phase function. With Cycles' fixed 1/2 (shade_volume.h volume_integrate_state_init) a
    segment passing close to a point lamp weighs its equiangular samples twice (distance sampling
    spreads over the whole segment; README, session 17); dense media and peaked phases (the
    integrand then follows the phase, which distance sampling places better near the ray's start)
    keep ~1/2."""
    sigma = pc[0] * st[0] + pc[1] * st[1] + pc[2] * st[2]
    flat = 1.0 - abs(g)
    return 0.5 + 0.5 * flat * flat * np.exp(-sigma * D)


@inline_stage_kernel
def _weighted_equiangular_pdf(prob_eq, setup, t):
    """prob_eq x the equiangular pdf of distance t: 0 without evaluating a placeholder setup."""
    return prob_eq * equiangular_pdf1(setup, t) if prob_eq > 0.0 else 0.0


@inline_stage_kernel
def _medium_nee(S, T, SP, SPS, F, I, K, C, p, iteration, o, d, beta, ss, st, g, t_end, Q, n_shadow, margin):
    """One next-event vertex on the segment [0, t_end] (see module docstring)."""
    mode = S.volume_sampling
    row, sel = _select_in_segment(T, K, p, iteration, o, d, t_end)
    if row < 0:
        return n_shadow
    u_t, u_channel = _u2(K, p, iteration, D_MED_T)  # (D_MED_T, D_MED_CHANNEL): one Sobol' pair, one shuffle
    finite = np.isfinite(t_end)
    pc = channel_probabilities1(beta, ss, st, 1.0 if (st[0] > 0.0 or finite) else 0.0,
                                1.0 if (st[1] > 0.0 or finite) else 0.0, 1.0 if (st[2] > 0.0 or finite) else 0.0)
    can_distance = pc[0] + pc[1] + pc[2] > 0.0
    can_equi = light_has_position(T, row) and mode != 1
    if mode == 2 or not can_distance:
        prob_eq = 1.0 if can_equi else 0.0
    else:
        prob_eq = 0.5 if can_equi else 0.0
    t_lit0, t_lit1 = light_segment(T, row, o, d, t_end)  # where the light can reach
    if not (can_equi or can_distance) or not t_lit0 <= t_lit1:
        return n_shadow
    u_light = _u2(K, p, iteration, D_MED_LU)  # the light sample's pair, also the equiangular centre's
    setup = _equiangular_setup_if(prob_eq, T, u_light, row, o, d, t_lit0, t_lit1, F[p, TIME])
    if 0.0 < prob_eq < 1.0:
        prob_eq = _equiangular_share(setup[1], pc, st, g)
    # Both techniques stay on the lit part [t_lit0, t_lit1]: the light reaches nothing else (Cycles
    # volume_integrate_homogeneous samples its direct distance on that interval too).
    lit_length = t_lit1 - t_lit0
    if u_t >= 1.0 - prob_eq:  # one number picks the technique and its distance: both stay stratified
        t = equiangular_sample1(setup, _rescaled_above(u_t, 1.0 - prob_eq))
    else:
        t = t_lit0 + sample_distance_truncated1(st, pc, u_channel, u_t / (1.0 - prob_eq),
                                                lit_length)
    if not np.isfinite(t):
        t = 0.0
    tr = transmittance3(st, t)
    pdf_t = _weighted_equiangular_pdf(prob_eq, setup, t)
    if can_distance and t_lit0 <= t <= t_lit1:
        pdf_t += (1.0 - prob_eq) * truncated_distance_pdf1(st, pc, transmittance3(st, t - t_lit0), lit_length)
    if not (pdf_t > 0.0 and np.isfinite(pdf_t)):
        return n_shadow
    x, wi, dist, value, light_pdf, cos_theta = _medium_light_sample(S, T, SP, SPS, u_light, row, sel, o, d, t,
                                                                    F[p, TIME])
    if S.mixed_phase and _phase_is_mixed(S, C, p):
        scattering, phase = _phase_mixture_eval(S, C, p, cos_theta)
    else:
        phase = hg_eval1(g, cos_theta)  # the phase pdf (MIS) and sigma_s x phase per channel
        scattering = _scale3(ss, phase)
        share = medium_glow_share(S.glow, C, p) if S.glow.count > 0 else 0.0
        if share > 0.0:  # a scatter here would mix the glow guide into phase sampling
            phase = mixture_pdf(phase, medium_glow_pdf(S.glow, C, p, share, x, wi))
    w = power_heuristic(light_pdf, phase) if light_pdf > 0.0 else 1.0
    contrib = _scale3(_mul3(_mul3(_mul3(beta, tr), scattering), value), w / pdf_t)
    if _max3(contrib) > 0.0:
        n_shadow = _push_shadow(Q, C, K, p, n_shadow, x, wi, dist, contrib, st, margin,
                                I[p, PID], P_SHADOW_MEDIUM, F[p, TIME])
    return n_shadow


@inline_stage_kernel
def _cross_volume(S, F, C, p, prim, front):
    """Path p crosses triangle prim's volume boundary: its stack and medium coefficients follow."""
    cross_boundary(S, C, p, prim, front)
    if S.any_medium:
        stack_coefficients(S, C, p, F)


@inline_stage_kernel
def _advance_through(S, F, C, p, prim, front, t, d):
    """Move path p just past the surface it hit at distance t, keeping its direction (null
    boundaries and transparent surfaces); the volume stack follows the crossing."""
    _cross_volume(S, F, C, p, prim, front)
    step = t + S.epsilon
    for c in range(3):
        F[p, O + c] += d[c] * step
    F[p, LEAD] = S.epsilon
    F[p, TRAVELLED] += step
    F[p, TMAX] -= step


@inline_stage_kernel
def _placed_normal(S, inst, time, x, y, z):
    """An object-space normal of an instanced hit in world space (unnormalised): through accel's
    instance_normals (inverse transpose), or for a moving
    instance through its transform at the ray's time (instance_motion.normal_map1). World-space
    hits (inst < 0) keep theirs."""
    if inst < 0:
        return x, y, z
    if S.inst_steps[inst] > 1:
        return normal_map1(S.inst_motion, S.inst_steps[inst], inst, time, x, y, z)
    m = S.inst_normal
    return (m[inst, 0, 0] * x + m[inst, 0, 1] * y + m[inst, 0, 2] * z,
            m[inst, 1, 0] * x + m[inst, 1, 1] * y + m[inst, 1, 2] * z,
            m[inst, 2, 0] * x + m[inst, 2, 1] * y + m[inst, 2, 2] * z)


@inline_stage_kernel
def _geometric_normal(S, prim, inst, time):
    """The outward unit geometric normal of triangle prim (of instance inst) in world space at
    shutter time `time`."""
    x, y, z = S.normals[prim, 0], S.normals[prim, 1], S.normals[prim, 2]
    if S.has_deformation and S.deform_rows[prim, 0] >= 0:
        x, y, z = deformed_normal1(S.deform_rows, S.deform_corners, prim, time)
    if inst < 0:
        return x, y, z
    x, y, z = _placed_normal(S, inst, time, x, y, z)
    length = max(np.sqrt(x * x + y * y + z * z), 1e-30)
    return x / length, y / length, z / length


@stage_kernel  # calls, not inlined: only deforming meshes pay for this code
def deformed_normal1(rows, c, prim, time):
    """Unit geometric normal of a deforming triangle at `time`: the cross product of its corners
    interpolated between the steps (outward for counter-clockwise corners)."""
    a, b, t = deform_step(rows, prim, time)
    p0x, p0y, p0z = (1.0 - t) * c[a, 0, 0] + t * c[b, 0, 0], (1.0 - t) * c[a, 0, 1] + t * c[b, 0, 1], \
        (1.0 - t) * c[a, 0, 2] + t * c[b, 0, 2]
    e1x, e1y, e1z = (1.0 - t) * c[a, 1, 0] + t * c[b, 1, 0] - p0x, (1.0 - t) * c[a, 1, 1] + t * c[b, 1, 1] - p0y, \
        (1.0 - t) * c[a, 1, 2] + t * c[b, 1, 2] - p0z
    e2x, e2y, e2z = (1.0 - t) * c[a, 2, 0] + t * c[b, 2, 0] - p0x, (1.0 - t) * c[a, 2, 1] + t * c[b, 2, 1] - p0y, \
        (1.0 - t) * c[a, 2, 2] + t * c[b, 2, 2] - p0z
    x, y, z = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    length = max(np.sqrt(x * x + y * y + z * z), 1e-30)
    return x / length, y / length, z / length


@stage_kernel
def deformed_shading_normal1(rows, dn, prim, time, w0, hu, hv):
    """Corner normals of a deforming triangle interpolated to `time`, then to (w0, hu, hv)."""
    a, b, t = deform_step(rows, prim, time)
    sx = (1.0 - t) * (dn[a, 0, 0] * w0 + dn[a, 1, 0] * hu + dn[a, 2, 0] * hv) \
        + t * (dn[b, 0, 0] * w0 + dn[b, 1, 0] * hu + dn[b, 2, 0] * hv)
    sy = (1.0 - t) * (dn[a, 0, 1] * w0 + dn[a, 1, 1] * hu + dn[a, 2, 1] * hv) \
        + t * (dn[b, 0, 1] * w0 + dn[b, 1, 1] * hu + dn[b, 2, 1] * hv)
    sz = (1.0 - t) * (dn[a, 0, 2] * w0 + dn[a, 1, 2] * hu + dn[a, 2, 2] * hv) \
        + t * (dn[b, 0, 2] * w0 + dn[b, 1, 2] * hu + dn[b, 2, 2] * hv)
    return sx, sy, sz


@inline_stage_kernel
def _frame_row(S, SP, SPS, prim, inst, time):
    """The hit's object frame in SP.frames: its mesh's, or its instance's; -1 for a moving object,
    whose frame at the ray's time is then in SPS.frame (surface_programs.frame_at_time) until
    the next call."""
    return frame_at_time(SP, SPS, SP.tri_mesh[prim] if inst < 0 else S.inst_frame_base + inst, time)


@inline_stage_kernel
def _shading_normal(S, prim, inst, time, hu, hv, n_face):
    """Interpolated (smooth) normal at barycentrics (hu, hv), flipped to n_face's side."""
    if not S.has_smooth:
        return n_face
    w0 = 1.0 - hu - hv
    cn = S.corner_normals
    sx = cn[prim, 0, 0] * w0 + cn[prim, 1, 0] * hu + cn[prim, 2, 0] * hv
    sy = cn[prim, 0, 1] * w0 + cn[prim, 1, 1] * hu + cn[prim, 2, 1] * hv
    sz = cn[prim, 0, 2] * w0 + cn[prim, 1, 2] * hu + cn[prim, 2, 2] * hv
    if S.has_deformation and S.deform_rows[prim, 3] == 1:  # corner normals at the ray's time
        sx, sy, sz = deformed_shading_normal1(S.deform_rows, S.deform_normals, prim, time, w0, hu, hv)
    sx, sy, sz = _placed_normal(S, inst, time, sx, sy, sz)
    length = max(np.sqrt(sx * sx + sy * sy + sz * sz), 1e-30)
    flip = -1.0 if (sx * n_face[0] + sy * n_face[1] + sz * n_face[2]) < 0.0 else 1.0
    return sx / length * flip, sy / length * flip, sz / length * flip


@inline_stage_kernel
def _textured_light_value(S, T, SP, SPS, row, u1, u2, w, value, time):
    """A light sample's value, times the emitter's radiance at the sampled point when the light is
    a triangle whose material's emission is a surface program (unit strength in the light table,
    surface_programs.py); the pdf is unchanged. w: unit direction to the light; a moving emitter
    is evaluated where it is at the shutter time `time`."""
    if T.kind[row] != TRIANGLE:
        return value
    prim = T.triangle[row]
    material = S.tri_material[prim]
    if not has_program_emission(SP, material):
        return value
    hu, hv = triangle_sample_barycentrics(u1, u2)
    w0 = 1.0 - hu - hv
    if is_deforming(S.deform_rows, prim):
        c = deformed_corners1(S.deform_rows, S.deform_corners, prim, time)
        y = (c[0] * w0 + c[3] * hu + c[6] * hv, c[1] * w0 + c[4] * hu + c[7] * hv, c[2] * w0 + c[5] * hu + c[8] * hv)
    else:
        k = T.corners[prim]
        y = (k[0, 0] * w0 + k[1, 0] * hu + k[2, 0] * hv, k[0, 1] * w0 + k[1, 1] * hu + k[2, 1] * hv,
             k[0, 2] * w0 + k[1, 2] * hu + k[2, 2] * hv)
    ng = _geometric_normal(S, prim, -1, time)
    wi = (-w[0], -w[1], -w[2])  # from the emitter towards the shading point
    front = _dot3(wi, ng) > 0.0
    n_face = _scale3(ng, 1.0 if front else -1.0)
    # emitters are traced as world triangles (accel._must_flatten, moving ones deforming): no instance
    ns = _shading_normal(S, prim, -1, time, hu, hv, n_face)
    e = program_emission(SP, SPS, material, prim, _frame_row(S, SP, SPS, prim, -1, time), hu, hv, y[0], y[1], y[2],
                         ns, n_face, wi, not front)
    return _mul3(value, e)


@inline_stage_kernel
def _push_surface_shadow(S, F, C, K, Q, p, n_shadow, prim, front, above, below, n_face, wi, dist, contrib, margin,
                         pid, purpose):
    """Queue a surface vertex's shadow ray toward wi (from below the surface when it transmits:
    the ray then crosses into or out of the surface's volume)."""
    transmits = _dot3(wi, n_face) < 0.0
    q = n_shadow
    n_shadow = _push_shadow(Q, C, K, p, n_shadow, below if transmits else above, wi, dist, contrib, _get3(F, p, ST),
                            margin, pid, purpose, F[p, TIME])
    if transmits and S.tri_volume[prim] >= 0:
        cross_boundary(S, Q.C, q, prim, front)
        _set3(Q.F, q, S_ST, stack_sigma_t(S, Q.C, q))
    return n_shadow


@inline_stage_kernel
def _bounce_mis(S, F, I, p):
    """(pdf, x, y, z) for grid tracking: the solid-angle pdf of the surface bounce path p's ray is
    and that vertex, whose emissive-media sample the emission it collects weighs against
    (emissive_media); pdf 0 for camera rays, volume vertices' rays and delta bounces."""
    if S.emitters.count == 0 or I[p, MIS_MODE] == MODE_VOLUME:
        return 0.0, 0.0, 0.0, 0.0
    return F[p, PREV_PDF], F[p, MIS_P], F[p, MIS_P + 1], F[p, MIS_P + 2]


@inline_stage_kernel
def _emissive_media_nee(S, GR, CB, count, BT, F, C, K, Q, p, iteration, prim, front, pb, above, below, n_face, ns,
                        wi_view, beta, guide, n_shadow, margin, pid):
    """A surface vertex's sample of the emissive media (emissive_media): a point x drawn by the
    cells' mean emission, a shadow ray to it carrying f |cos| E(x) / (p_point r^2) x its MIS
    weight against the vertex's bounce (which collects the same emission along its ray)."""
    u1, u2 = _u2(K, p, iteration, D_EMIT_U)
    gi, x, point_pdf = sample_emissive_point(S.emitters, _u(K, p, iteration, D_EMIT_CELL), u1, u2,
                                             _u(K, p, iteration, D_EMIT_W))
    if not point_pdf > 0.0:
        return n_shadow
    # the distance and direction from the shadow ray's origin: above the surface, or below it
    # for a transmitting direction (the bounce starts there too)
    origin = above
    dx, dy, dz = x[0] - above[0], x[1] - above[1], x[2] - above[2]
    if dx * n_face[0] + dy * n_face[1] + dz * n_face[2] < 0.0:
        origin = below
        dx, dy, dz = x[0] - below[0], x[1] - below[1], x[2] - below[2]
    dist2 = dx * dx + dy * dy + dz * dz
    if not dist2 > 0.0:
        return n_shadow
    dist = np.sqrt(dist2)
    wi = (dx / dist, dy / dist, dz / dist)
    f, bsdf_pdf = surface_eval(CB, count, BT, wi_view, wi, ns, n_face)
    if not _max3(f) > 0.0:
        return n_shadow
    if guide:
        bsdf_pdf = mixture_pdf(bsdf_pdf, glow_pdf(S.glow, pb, wi))
    er, eg, eb, rate, density = slot_emission(GR, gi, F[p, TIME], x)
    if not max(abs(er), max(abs(eg), abs(eb))) > 0.0:
        return n_shadow
    # the bounce's weight from the vertex point itself (its MIS origin): both sides the same number
    mx, my, mz = x[0] - pb[0], x[1] - pb[1], x[2] - pb[2]
    w = 1.0 - bounce_share(bsdf_pdf, rate, mx * mx + my * my + mz * mz, density)
    contrib = _scale3(_mul3(_mul3(beta, f), (er, eg, eb)), w / (point_pdf * dist2))
    if not _max3(contrib) > 0.0:
        return n_shadow
    if S.emitters.direct:  # the transmittance here; the shadow ray only asks about opaque geometry
        contrib = _mul3(_mul3(contrib, transmittance3(_get3(F, p, ST), dist)), _sampled_media_transmittance(
            S.emitters, GR, origin, wi, dist, K[p], grid_stream(iteration, P_EMISSION_DIRECT, 0, 0), F[p, TIME]))
        if not _max3(contrib) > 0.0:
            return n_shadow
        return _push_shadow(Q, C, K, p, n_shadow, origin, wi, dist, contrib, _get3(F, p, ST), 0.0, pid,
                            P_EMISSION_DIRECT, F[p, TIME])
    return _push_surface_shadow(S, F, C, K, Q, p, n_shadow, prim, front, above, below, n_face, wi, dist, contrib,
                                0.0, pid, P_SHADOW_EMISSION)


@inline_stage_kernel
def _sampled_media_transmittance(E, GR, o, d, dist, key, stream, time):
    """Transmittance (rgb) of the grids over [0, dist] of ray (o, d) in a scene whose only volumes
    are the sampled media (E.direct), each box-bounded: each one's tracking across the part of the
    segment inside its box (a slab test in its index space)."""
    t0 = t1 = t2 = 1.0
    for k in range(E.count):
        M = E.world_to_index[k]
        near, far = 0.0, dist
        for axis in range(3):
            oa = M[axis, 0] * o[0] + M[axis, 1] * o[1] + M[axis, 2] * o[2] + M[axis, 3]
            da = M[axis, 0] * d[0] + M[axis, 1] * d[1] + M[axis, 2] * d[2]
            lo, hi = E.clip[k, 0, axis], E.clip[k, 1, axis]
            if da == 0.0:
                if not lo <= oa <= hi:
                    far = -1.0
            else:
                a, b = (lo - oa) / da, (hi - oa) / da
                near, far = max(near, min(a, b)), min(far, max(a, b))
        if far > near:
            gi = E.slot[k]
            r = slot_transmittance(GR, gi, time, (o[0] + d[0] * near, o[1] + d[1] * near, o[2] + d[2] * near), d,
                                   far - near, key, stream + np.uint64(gi) * np.uint64(STREAM_DIMENSIONS))
            t0, t1, t2 = t0 * r[0], t1 * r[1], t2 * r[2]
    return t0, t1, t2


@inline_stage_kernel
def _surface(S, T, GR, SN, BT, CB, SP, SPS, F, I, K, C, p, iteration, prim, inst, t, hu, hv, L, Q, n_shadow, margin,
             stats):
    """Shade a surface hit with its material's closures (bsdfs.closures); returns (continues,
    shadow queue length). Cycles kernel/integrator/shade_surface.h: emission, light sampling
    with MIS, BSDF sampling; a transmission enters/leaves the material's volume
    (volume_stack_enter_exit), a transparent sample continues straight."""
    eps = S.epsilon
    d = _get3(F, p, D)
    ng = _geometric_normal(S, prim, inst, F[p, TIME])
    front = _dot3(d, ng) < 0.0
    if S.tri_null[prim]:
        # null boundary: cross it, update the volume stack, keep the direction
        _advance_through(S, F, C, p, prim, front, t, d)
        I[p, BOUNDS] += 1
        return I[p, BOUNDS] <= MAX_VOLUME_BOUNDS, n_shadow
    stats[0] += 1
    pid = I[p, PID]
    beta = _get3(F, p, BETA)
    pb = (F[p, O] + d[0] * t, F[p, O + 1] + d[1] * t, F[p, O + 2] + d[2] * t)
    sign = 1.0 if front else -1.0
    n_face = _scale3(ng, sign)  # geometric normal on the viewer's side
    ns = _shading_normal(S, prim, inst, F[p, TIME], hu, hv, n_face)
    wi_view = (-d[0], -d[1], -d[2])
    frame = _frame_row(S, SP, SPS, prim, inst, F[p, TIME])  # read before NEE (which may move SPS.frame)
    # emission (two-sided by default), MIS against the light-sampling pdf
    if S.tri_emissive[prim]:
        prev = _get3(F, p, PREV)
        r0, r1, r2, lpdf, light_row = triangle_emission_unselected(T, prim, d[0], d[1], d[2], F[p, TRAVELLED] + t,
                                                                   front, F[p, TIME])
        if has_program_emission(SP, S.tri_material[prim]):  # textured: unit strength x the program's
            e = program_emission(SP, SPS, S.tri_material[prim], prim, frame, hu, hv, pb[0], pb[1], pb[2], ns,
                                 n_face, wi_view, not front)
            r0, r1, r2 = r0 * e[0], r1 * e[1], r2 * e[2]
        _add_radiance(L, pid, _scale3(_mul3(beta, (r0, r1, r2)), _mis_from_last_vertex(T, F, I, p, light_row, lpdf)))
    if I[p, TAT] != 0:  # terminate-after-transparent paths end here
        return False, n_shadow
    nodes, row, n_closure, tangent = SN, S.tri_material[prim], ns, (0.0, 0.0, 0.0)
    if SP.any and SP.mat_program[row] >= 0:
        # textured inputs: this hit's node values in SPS.nodes (material 0 there), normal, tangent
        n_closure, tangent = shade_surface_program(SP, SPS, SN, row, prim, frame, hu, hv, pb[0], pb[1], pb[2], ns,
                                                   n_face, wi_view, not front)
        ns = program_shading_normal(SP, SPS, row, ns)  # a Displacement bump sets sd->N itself
        nodes, row = SPS.nodes, 0
    count = setup_surface_tangent(nodes, BT, row, wi_view, n_closure, n_face, not front, tangent, CB)
    if count == 0:  # black: absorbs everything
        return False, n_shadow
    above = (pb[0] + n_face[0] * eps, pb[1] + n_face[1] * eps, pb[2] + n_face[2] * eps)
    below = (pb[0] - n_face[0] * eps, pb[1] - n_face[1] * eps, pb[2] - n_face[2] * eps)
    # bounce directions partly toward lamps glowing in a medium (glow_guide): both techniques
    # below weigh against the mixture pdf
    guide = S.glow.count > 0 and not surface_has_delta(CB, count)
    # light selection at (pb, ns): Cycles' sd->P, sd->N, transmitting closures see both sides
    mis_mode = MODE_SURFACE_TRANSMIT if surface_is_transmissive(CB, count) else MODE_SURFACE
    row, sel = tree_select(T.tree, _u(K, p, iteration, D_SURF_SELECT), pb[0], pb[1], pb[2], ns[0], ns[1], ns[2], 0.0,
                           mis_mode)
    if row >= 0:
        u1, u2 = _u2(K, p, iteration, D_SURF_LU)
        wx, wy, wz, dist, v0, v1, v2, light_pdf = sample_light_selected(T, row, sel, above[0], above[1], above[2],
                                                                        u1, u2, F[p, TIME])
        wi = (wx, wy, wz)
        v0, v1, v2 = _textured_light_value(S, T, SP, SPS, row, u1, u2, wi, (v0, v1, v2), F[p, TIME])
        f, bsdf_pdf = surface_eval(CB, count, BT, wi_view, wi, ns, n_face)
        if guide:
            bsdf_pdf = mixture_pdf(bsdf_pdf, glow_pdf(S.glow, pb, wi))
        if _max3(f) > 0.0:
            w = power_heuristic(light_pdf, bsdf_pdf) if light_pdf > 0.0 else 1.0
            contrib = _scale3(_mul3(_mul3(beta, f), (v0, v1, v2)), w)
            if _max3(contrib) > 0.0:
                n_shadow = _push_surface_shadow(S, F, C, K, Q, p, n_shadow, prim, front, above, below, n_face, wi,
                                                dist, contrib, margin, pid, P_SHADOW_SURFACE)
    if S.emitters.count > 0:
        n_shadow = _emissive_media_nee(S, GR, CB, count, BT, F, C, K, Q, p, iteration, prim, front, pb, above, below,
                                       n_face, ns, wi_view, beta, guide, n_shadow, margin, pid)
    u_bsdf, v_bsdf = _u2(K, p, iteration, D_BSDF_U)
    u_pick = _u(K, p, iteration, D_SURF_PICK)
    if guide and u_pick < GLOW_SHARE:  # toward a glowing lamp (the pick number rescaled picks it)
        wo, ok = glow_sample(S.glow, pb, u_pick / GLOW_SHARE, u_bsdf, v_bsdf)
        f, bsdf_pdf = surface_eval(CB, count, BT, wi_view, wo, ns, n_face)
        pdf = mixture_pdf(bsdf_pdf, glow_pdf(S.glow, pb, wo))
        label = guided_label(CB, count, wo, n_face) if ok and pdf > 0.0 and _max3(f) > 0.0 else 0
        weight = _scale3(f, 1.0 / pdf) if label != 0 else (0.0, 0.0, 0.0)
    else:
        if guide:
            u_pick = _rescaled_above(u_pick, GLOW_SHARE)
        wo, weight, pdf, label = surface_sample(CB, count, BT, wi_view, ns, n_face, u_pick, u_bsdf, v_bsdf)
        if guide and pdf > 0.0:  # a rough direction: weighed against the mixture
            mixture = mixture_pdf(pdf, glow_pdf(S.glow, pb, wo))
            weight = _scale3(weight, pdf / mixture)
            pdf = mixture
    if label == 0:
        return False, n_shadow
    _set3(F, p, BETA, _mul3(beta, weight))
    if not label & LABEL_TRANSPARENT:
        _set_mis_origin(F, I, p, pb, ns, 0.0, mis_mode)
    if label & LABEL_TRANSPARENT:
        # straight on, counting only against the transparent limit (path_state_next)
        _advance_through(S, F, C, p, prim, front, t, d)
        I[p, TRANSPARENT] += 1
        if I[p, TRANSPARENT] > S.transparent_bounces:
            I[p, TAT] = 1
        return True, n_shadow
    if label & LABEL_TRANSMIT:
        if S.tri_volume[prim] >= 0:  # glass holding a liquid: enter / leave it
            _cross_volume(S, F, C, p, prim, front)
        # translucent (TRANSMIT|DIFFUSE) too counts as a transmission bounce in path_state_next
        _scatter_to(S, F, I, p, below, wo, pdf, TRANSMISSION, S.transmission_bounces)
    elif label & LABEL_DIFFUSE:
        _scatter_to(S, F, I, p, above, wo, pdf, DIFFUSE, S.diffuse_bounces)
    else:
        _scatter_to(S, F, I, p, above, wo, pdf, GLOSSY, S.glossy_bounces)
    return _russian_roulette(S, F, I, K, p, iteration), n_shadow


# ---------------------------------------------------------------------------------------------
# Heterogeneous (grid) media: delta tracking and ratio tracking from grid_kernels. A homogeneous
# medium overlapping a grid is sampled first and the grid tracked only up to its event (the
# earlier of two independent collision processes is the first event of their sum).
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def _grid_segment(S, GR, K, C, L, p, pid, iteration, o, d, beta, beta_in, ss, st, g, t_seg, tat, time, mis, camera):
    """Free flight of path p inside grid volumes (placed at its shutter time); returns (beta,
    scattered, t, event g, grid event). mis: _bounce_mis; camera: no scattering on the path yet."""
    key = K[p]
    stream0 = grid_stream(iteration, P_FREE_FLIGHT, 0, 0)
    if tat:  # attenuation and emission only (Cycles adds volume emission on these paths too)
        w = (1.0, 1.0, 1.0)
        for v in range(S.vol_grid.shape[0]):
            gi = S.vol_grid[v]
            if C[p, v] > 0 and gi >= 0:
                w0, w1, w2, e0, e1, e2 = slot_attenuation(GR, gi, time, o, d, t_seg, key,
                                                          stream0 + np.uint64(gi) * np.uint64(STREAM_DIMENSIONS), mis)
                _add_radiance(L, pid, _mul3(_mul3(beta_in, w), (e0, e1, e2)))
                w = _mul3(w, (w0, w1, w2))
        return _mul3(_mul3(beta, w), transmittance3(st, t_seg)), False, np.inf, g, False
    hom = _max3(ss) > 0.0
    pc = (0.0, 0.0, 0.0)
    ts = np.inf
    if hom:
        pc = channel_probabilities1(beta, ss, st, 1.0, 1.0, 1.0)
        u_channel, u_distance = _u2(K, p, iteration, D_CHANNEL)
        ts = sample_distance1(st, pc, u_channel, u_distance)
    t_end = min(ts, t_seg)
    w = (1.0, 1.0, 1.0)
    grid_event = False
    event_g = g
    for v in range(S.vol_grid.shape[0]):
        gi = S.vol_grid[v]
        if C[p, v] <= 0 or gi < 0:
            continue
        t, scattered, w0, w1, w2, e0, e1, e2 = slot_free_flight(
            GR, gi, time, o, d, t_end, key, stream0 + np.uint64(gi) * np.uint64(STREAM_DIMENSIONS), _mul3(beta, w),
            mis, camera)
        _add_radiance(L, pid, _mul3(_mul3(beta_in, w), (e0, e1, e2)))
        w = _mul3(w, (w0, w1, w2))
        if scattered:
            t_end = t
            grid_event = True
            event_g = slot_g(GR, gi)
    hom_event = hom and not grid_event and ts < t_seg
    event = grid_event or hom_event
    t_eval = t_end if event else t_seg
    factor = transmittance3(st, t_eval)  # absorbing-only homogeneous part
    if hom:
        pdf, surv, tr = distance_pdf1(st, pc, t_eval)
        if hom_event:
            factor = _scale3(_mul3(ss, tr), 1.0 / max(pdf, 1e-300))
        elif surv > 0.0:
            factor = _scale3(tr, 1.0 / surv)
        else:
            factor = (0.0, 0.0, 0.0)
    return _mul3(_mul3(beta, w), factor), event, (t_eval if event else np.inf), event_g, grid_event


#: how much brighter than the world a camera segment's in-scattered light must be for its free
#: flight to collide more often (_world_dimmer)
WORLD_MARGIN = 4.0


@inline_stage_kernel
def _world_dimmer(T, in_scatter):
    """Whether the world is dimmer than the radiance the camera segment's next-event vertex scatters
    toward the camera per unit albedo (in_scatter, unshadowed, from _grid_nee): then the segment's
    free flight may collide more often (grid_kernels.CAMERA_COLLISION_BOOST), else (a bright sky,
    no next event) it keeps the plain collision rate. In a thin medium the boost pays where a
    collision's value (about albedo x in_scatter) exceeds what passing paths carry; what the camera
    ray meets behind the medium is not known yet (the segment ends at the medium's boundary): the
    world stands for it. Noise cloud: world strength 10 gave +63 % variance with the boost on
    every camera segment, none with this test; the table's dim world -15 % (-19 % ungated)."""
    world = 0.0
    if T.world_row >= 0 and T.camera_visible[T.world_row]:
        world = (T.world_radiance[0] + T.world_radiance[1] + T.world_radiance[2]) / 3.0
    return in_scatter > WORLD_MARGIN * world


@inline_stage_kernel
def _grid_phase_mixture(S, GR, C, p, x, ss_hom, g_hom, cos_theta, time):
    """Sum of sigma_s HG over every medium scattering at x (homogeneous components and grids) and
    the mixture's pdf (weights: mean sigma_s), as _phase_mixture_eval for grid paths."""
    f0 = f1 = f2 = 0.0
    num = den = 0.0
    n_hom = S.phase_g.shape[0] if S.mixed_phase else 1
    for k in range(n_hom):
        if S.mixed_phase:
            sk = _component_sigma(S, C, p, k)
            gk = S.phase_g[k]
        else:
            sk = ss_hom
            gk = g_hom
        ph = hg_eval1(gk, cos_theta)
        f0, f1, f2 = f0 + sk[0] * ph, f1 + sk[1] * ph, f2 + sk[2] * ph
        w = (sk[0] + sk[1] + sk[2]) / 3.0
        num += w * ph
        den += w
    for v in range(S.vol_grid.shape[0]):
        gi = S.vol_grid[v]
        if C[p, v] <= 0 or gi < 0:
            continue
        sk, gk = slot_scattering(GR, gi, time, x)
        ph = hg_eval1(gk, cos_theta)
        f0, f1, f2 = f0 + sk[0] * ph, f1 + sk[1] * ph, f2 + sk[2] * ph
        w = (sk[0] + sk[1] + sk[2]) / 3.0
        num += w * ph
        den += w
    return (f0, f1, f2), (num / den if den > 0.0 else 0.0)


@inline_stage_kernel
def _grid_phase_pdf(S, GR, C, p, x, ss_hom, g_hom, cos_theta, time):
    """The pdf of _grid_phase_mixture. With one grid and no other scattering medium on the stack
    the mixture is that grid's HG lobe alone: no evaluation of its coefficients at x (on shader-program
    media, a run of the program)."""
    if not S.mixed_phase and not _max3(ss_hom) > 0.0:
        only, count = 0, 0
        for v in range(S.vol_grid.shape[0]):
            if C[p, v] > 0 and S.vol_grid[v] >= 0:
                only, count = S.vol_grid[v], count + 1
        if count == 1:
            return hg_eval1(slot_g(GR, only), cos_theta)
    return _grid_phase_mixture(S, GR, C, p, x, ss_hom, g_hom, cos_theta, time)[1]


@inline_stage_kernel
def _empty_cell_survival(S, GR, C, p, x, ss_hom, time):
    """Russian roulette of a grid next-event vertex before its coefficients are evaluated (on a
    shader-program medium, a run of the program): where every grid on the stack found its majorant
    cell empty (its largest sampled extinction 0) and no homogeneous medium scatters, the vertex
    survives with EMPTY_CELL_SURVIVAL and is weighted by its inverse; elsewhere 1. Unbiased whatever
    the sampling missed. Equiangular vertices land anywhere on the segment, also in the empty
    corners of a procedural cloud's box, where the run found sigma_s = 0."""
    if S.mixed_phase or _max3(ss_hom) > 0.0:
        return 1.0
    for v in range(S.vol_grid.shape[0]):
        gi = S.vol_grid[v]
        if C[p, v] > 0 and gi >= 0 and slot_cell_max_extinction(GR, gi, time, x) > 0.0:
            return 1.0
    return EMPTY_CELL_SURVIVAL


@inline_stage_kernel
def _first_grid(S, C, p):
    """Index (into GR) of the first grid medium on path p's volume stack."""
    for v in range(S.vol_grid.shape[0]):
        if C[p, v] > 0 and S.vol_grid[v] >= 0:
            return S.vol_grid[v]
    return 0


@inline_stage_kernel
def _grid_nee(S, T, SP, SPS, GR, F, I, K, C, p, iteration, o, d, beta, ss, st, g, t_end, Q, n_shadow, margin):
    """Next-event vertex per segment for paths inside grid volumes: the distance is drawn by
    equiangular sampling (positional lights) or, on the bounded segment, from the first grid's
    control extinction (grid_kernels.grid_nee_distance_sample_pdf: follows the medium cell by cell, as
    Cycles' distance-sampled direct scatter does), one-sample MIS of the two, the equiangular share
    scaled by how evenly the control fills the segment (GRID_EQUIANGULAR_SHARE); sigma_s and
    transmittance come from the grids (residual ratio tracking). Returns (queue length, the radiance
    a unit albedo would scatter toward -d at the vertex from this light sample, unshadowed; 0
    without a shadow ray)."""
    mode = S.volume_sampling
    row, sel = _select_in_segment(T, K, p, iteration, o, d, t_end)
    if row < 0:
        return n_shadow, 0.0
    finite = np.isfinite(t_end) and t_end > 0.0
    can_equi = light_has_position(T, row) and (mode != 1 or not finite)
    if mode == 2:
        prob_eq = 1.0 if can_equi else 0.0
    else:
        prob_eq = (S.grid_equiangular_share if finite else 1.0) if can_equi else 0.0
    t_lit0, t_lit1 = light_segment(T, row, o, d, t_end)  # where the light can reach
    if not (can_equi or finite) or not t_lit0 <= t_lit1:
        return n_shadow, 0.0
    u_light = _u2(K, p, iteration, D_MED_LU)  # the light sample's pair, also the equiangular centre's
    setup = _equiangular_setup_if(prob_eq, T, u_light, row, o, d, t_lit0, t_lit1, F[p, TIME])
    u_t = _u(K, p, iteration, D_MED_T)
    gi = _first_grid(S, C, p)
    sigma_extra = (st[0] + st[1] + st[2]) / 3.0
    total = -1.0  # the segment's control depth, once walked (else the distance sampler walks it)
    if 0.0 < prob_eq < 1.0:  # equiangular distances ignore the density: fewer where it fills less
        total, occupancy = slot_control_occupancy(GR, gi, F[p, TIME], o, d, t_end, sigma_extra)
        prob_eq *= occupancy
    if u_t >= 1.0 - prob_eq:  # as _medium_nee: one number for the technique and the distance
        t = equiangular_sample1(setup, _rescaled_above(u_t, 1.0 - prob_eq))
        if not np.isfinite(t):
            t = 0.0
        pdf_t = prob_eq * equiangular_pdf1(setup, t)
        if finite and prob_eq < 1.0:
            pdf_t += (1.0 - prob_eq) * slot_nee_distance_pdf_given(GR, gi, F[p, TIME], o, d, t_end, sigma_extra,
                                                                   total, t)
    else:  # (prob_eq < 1 here, so the segment is finite)
        t, pdf_distance = slot_nee_distance_sample_pdf_given(GR, gi, F[p, TIME], o, d, t_end, sigma_extra, total,
                                                             _u(K, p, iteration, D_MED_TECH), u_t / (1.0 - prob_eq))
        pdf_t = (1.0 - prob_eq) * pdf_distance + _weighted_equiangular_pdf(prob_eq, setup, t)
    if not (pdf_t > 0.0 and np.isfinite(pdf_t)):
        return n_shadow, 0.0
    x, wi, dist, value, light_pdf, cos_theta = _medium_light_sample(S, T, SP, SPS, u_light, row, sel, o, d, t,
                                                                    F[p, TIME])
    survival = _empty_cell_survival(S, GR, C, p, x, ss, F[p, TIME])
    if survival < 1.0 and _u(K, p, iteration, D_MED_ROULETTE) >= survival:
        return n_shadow, 0.0
    f, phase_pdf = _grid_phase_mixture(S, GR, C, p, x, ss, g, cos_theta, F[p, TIME])
    w = power_heuristic(light_pdf, phase_pdf) if light_pdf > 0.0 else 1.0
    contrib = _scale3(_mul3(_mul3(_mul3(beta, transmittance3(st, t)), f), value), w / (pdf_t * survival))
    in_scatter = 0.0
    if _max3(contrib) > 0.0:
        contrib = _mul3(contrib, grids_transmittance(S, GR, C, p, o, d, t, K[p],
                                                     grid_stream(iteration, P_NEE_SEGMENT, 0, 0), F[p, TIME]))
        n_shadow = _push_shadow(Q, C, K, p, n_shadow, x, wi, dist, contrib, st, margin,
                                I[p, PID], P_SHADOW_MEDIUM, F[p, TIME])
        in_scatter = phase_pdf * w * (value[0] + value[1] + value[2]) / 3.0
    return n_shadow, in_scatter


# ---------------------------------------------------------------------------------------------
# Shadow rays
# ---------------------------------------------------------------------------------------------
@stage_kernel
def shadow_unoccluded(SF, SI, m, blocked, margin, L):
    # (no null boundaries means no volumes, hence no grids)
    """Scenes without null boundaries: one occlusion query per shadow ray; transmittance of the
    single medium segment (its coefficients were stored with the ray)."""
    for q in range(m):
        if blocked[q]:
            continue
        tr = transmittance3(_get3(SF, q, S_ST), SF[q, S_REMAINING] + margin)
        _add_radiance(L, SI[q, SI_PID], _mul3(_get3(SF, q, S_CONTRIB), tr))


@stage_kernel
def shadow_step(S, GR, SN, BT, CB, SP, SPS, Q, m, hit_t, hit_prim, hit_inst, hit_u, hit_v, margin, L, iteration,
                step, blocked_steps):
    """One closest-hit step of shadow rays through null boundaries and transparent surfaces:
    attenuate the segment, stop at opaque geometry (T = 0) or at the light (add contrib x T),
    cross null boundaries (the volume stack and the segment's sigma_t change) and transparent
    surfaces (x their transparency, Cycles shade_shadow.h / surface_shader_transparency). Returns
    how many rays continue (in place at the front of the queue, their rays rewritten);
    blocked_steps[0] += the steps each ray stopped by opaque geometry took (wavefront: whether an
    opaque-only occlusion query first would pay)."""
    S, GR, SN, BT, CB, SP, SPS = (table_ref(S), table_ref(GR), table_ref(SN), table_ref(BT), table_ref(CB),
                                  table_ref(SP), table_ref(SPS))  # callees take references (table_ref.py)
    SF, SI, SK, SC = Q.F, Q.I, Q.K, Q.C
    eps = S.epsilon
    out = 0
    for q in range(m):
        hit = hit_prim[q] >= 0
        prim = hit_prim[q] if hit else 0
        if hit and not (S.tri_null[prim] or S.tri_transparent[prim]):
            blocked_steps[0] += step + 1
            continue  # blocked by opaque geometry
        seg = hit_t[q] if hit else SF[q, S_REMAINING]
        length = seg + SF[q, S_LEAD] + (0.0 if hit else margin)
        tr = transmittance3(_get3(SF, q, S_ST), length)
        if S.has_grids:
            tr = _mul3(tr, grids_transmittance(S, GR, SC, q, _get3(SF, q, S_O), _get3(SF, q, S_D), seg, SK[q],
                                               grid_stream(iteration, SI[q, SI_PURPOSE], step, 0), SF[q, S_TIME]))
        d = _get3(SF, q, S_D)
        front = False
        if hit:
            inst = hit_inst[q]
            ng = _geometric_normal(S, prim, inst, SF[q, S_TIME])
            front = _dot3(d, ng) < 0.0
            if not S.tri_null[prim]:
                n_face = _scale3(ng, 1.0 if front else -1.0)
                nodes, row, n_closure, tangent = SN, S.tri_material[prim], n_face, (0.0, 0.0, 0.0)
                wi = (-d[0], -d[1], -d[2])
                if SP.any and SP.mat_program[row] >= 0:  # textured alpha / transparency
                    ns = _shading_normal(S, prim, inst, SF[q, S_TIME], hit_u[q], hit_v[q], n_face)
                    x = _get3(SF, q, S_O)
                    t_hit = hit_t[q]
                    n_closure, tangent = shade_surface_program(
                        SP, SPS, SN, row, prim, _frame_row(S, SP, SPS, prim, inst, SF[q, S_TIME]), hit_u[q], hit_v[q],
                        x[0] + d[0] * t_hit, x[1] + d[1] * t_hit, x[2] + d[2] * t_hit, ns, n_face, wi, not front)
                    nodes, row = SPS.nodes, 0
                count = setup_surface_tangent(nodes, BT, row, wi, n_closure, n_face, not front, tangent, CB)
                tr = _mul3(tr, surface_transparency(CB, count))
        for c in range(3):
            SF[q, S_CONTRIB + c] *= tr[c]
        if not hit:
            _add_radiance(L, SI[q, SI_PID], _get3(SF, q, S_CONTRIB))
            continue
        if not _max3(_get3(SF, q, S_CONTRIB)) > 0.0:
            continue  # fully absorbed by a transparent surface
        cross_boundary(S, SC, q, prim, front)
        for c in range(3):
            SF[q, S_O + c] += d[c] * (seg + eps)
        SF[q, S_REMAINING] -= seg + eps
        SF[q, S_LEAD] = eps
        _set3(SF, q, S_ST, stack_sigma_t(S, SC, q))
        if not SF[q, S_REMAINING] > 0.0:
            _add_radiance(L, SI[q, SI_PID], _get3(SF, q, S_CONTRIB))
            continue
        # keep: move to the front of the queue
        if out != q:
            _move_entry(SF, SI, SK, SC, q, out)
        _write_ray(SF, out, S_O, S_D, S_REMAINING, Q.o32, Q.d32, Q.t32, out)
        out += 1
    return out


@stage_kernel
def drop_blocked(Q, m, blocked, L):
    """Keep the shadow rays not blocked (an opaque occluder found: accel.MASK_OPAQUE), in their
    order at the front of the queue, rays included; returns how many. Their random streams are
    keyed by path and purpose, not by queue slot, so the image is the one without this cull.
    Direct emissive-media samples (their transmittance already in) end here: added to L."""
    out = 0
    for q in range(m):
        if blocked[q]:
            continue
        if Q.I[q, SI_PURPOSE] == P_EMISSION_DIRECT:
            _add_radiance(L, Q.I[q, SI_PID], _get3(Q.F, q, S_CONTRIB))
            continue
        if out != q:
            _move_entry(Q.F, Q.I, Q.K, Q.C, q, out)
            _move_row(Q.o32, q, out)
            _move_row(Q.d32, q, out)
            Q.t32[out] = Q.t32[q]
        out += 1
    return out


# ---------------------------------------------------------------------------------------------
# Queue plumbing
# ---------------------------------------------------------------------------------------------
@stage_kernel
def _move_row(A, src, dst):
    for j in range(A.shape[1]):
        A[dst, j] = A[src, j]


@inline_stage_kernel
def _move_entry(F, I, K, C, src, dst):
    """Copy one queue entry (float fields, int fields, key, volume stack) from src to dst: the
    path state and the shadow queue share this layout."""
    _move_row(F, src, dst)
    _move_row(I, src, dst)
    K[dst] = K[src]
    _move_row(C, src, dst)


@stage_kernel
def compact(F, I, K, C, n, alive, o32, d32, t32):
    """Fill the slots of finished paths with live paths from the end of the batch, rays included;
    returns how many live. Only as many rows move as paths ended (a stable compaction moves every
    row behind the first gap); the order is free because results are keyed by path id."""
    lo, hi = 0, n - 1
    while True:
        while lo < n and alive[lo]:
            lo += 1
        while hi >= 0 and not alive[hi]:
            hi -= 1
        if lo >= hi:
            return lo
        _move_entry(F, I, K, C, hi, lo)
        _move_row(o32, hi, lo)
        _move_row(d32, hi, lo)
        t32[lo] = t32[hi]
        alive[lo] = True
        alive[hi] = False
