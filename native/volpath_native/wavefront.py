"""One batch's wavefront loop as a single compiled call: closest hits (Embree) -> the path stage
-> shadow rays -> compaction, repeated until no path lives. The stages are path_kernels' own,
called in the order Integrator.render_paths(stepwise=True) calls them from Python; the image is
the same, bit for bit (tests/native/test_wavefront.py).

Why: every call from Python into a kernel unboxes each array of the table tuples it is given
(scene, lights, grids, BSDF and surface-program tables: hundreds of arrays), ~40 us a call. A
batch of a few thousand paths runs ~25 iterations (a long tail of few paths) and each shadow
step through a null boundary was another call, so on the equal-time scenes the dispatches were a
quarter of the render (README, "Session 10, speed per sample"). Here they are calls between compiled
functions, which pass the tuples without unboxing; the GIL is released for the whole batch.
pbrt-v4's wavefront integrator (src/pbrt/wavefront/integrator.cpp, Render) likewise loops over its
stages without returning to the host per stage.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np

from . import path_kernels as pk
from .accel import ALL_MASK, MASK_OPAQUE, MASK_SEE_THROUGH
from .embree.queries import intersect_rays, new_rayhit, occluded_rays
from .jit import stage_kernel

# The scene's Embree queries: the scene handle (has_scene False: no triangles, every ray misses),
# the tables turning Embree's geometry / instance ids into triangle ids (accel.Accelerator), and
# whether rays carry shutter times (only moving geometry reads them), whether the geometry is masked
# by class (accel.MASK_OPAQUE / MASK_SEE_THROUGH: shadow rays ask about opaque geometry first).
RayQueries = namedtuple("RayQueries", ["scene", "has_scene", "geom_base", "inst_base", "inst_index", "has_motion",
                                       "masked"])
# One thread's hit records of a query (as accel.Hits), occlusion flags, ray times and Embree scratch.
HitBuffers = namedtuple("HitBuffers", ["t", "prim", "inst", "u", "v", "blocked", "times", "rayhit"])

# counts: what a batch traced (render stats)
VERTICES, RAYS, SHADOW_RAYS = 0, 1, 2
N_COUNTS = 3

#: Shadow rays through null boundaries ask first whether anything opaque lies on them (one
#: occlusion query each over accel.MASK_OPAQUE) when that pays: when, traced without it, the rays
#: opaque geometry stopped took more closest-hit steps than there were rays (a sun through a
#: window: most are blocked after crossing a fog box's boundary; a lamp inside fog: almost none
#: are, and the query would only add one per ray). Decided once this many shadow rays were queued
#: without it; the image is the same either way (path_kernels.drop_blocked).
CULL_DECISION_SHADOWS = 4096
# the decision's state (an int64 array shared by a render's threads; a race only delays it)
CULL_DECIDED, CULL_QUEUED, CULL_BLOCKED_STEPS = 0, 1, 2
CULL_UNDECIDED = -1


def new_cull_state(masked: bool) -> np.ndarray:
    """[decision (CULL_UNDECIDED, 0, 1), shadow rays queued, steps of the blocked ones]."""
    return np.array([CULL_UNDECIDED if masked else 0, 0, 0], np.int64)


@stage_kernel
def learn_cull(cull_state, queued):
    """Count m shadow rays traced without the cull (shadow_step counted the blocked ones' steps
    into cull_state[CULL_BLOCKED_STEPS]); decide once CULL_DECISION_SHADOWS were."""
    if cull_state[CULL_DECIDED] != CULL_UNDECIDED:
        return
    cull_state[CULL_QUEUED] += queued
    if cull_state[CULL_QUEUED] >= CULL_DECISION_SHADOWS:
        cull_state[CULL_DECIDED] = 1 if cull_state[CULL_BLOCKED_STEPS] > cull_state[CULL_QUEUED] else 0


def new_hit_buffers(capacity: int) -> HitBuffers:
    return HitBuffers(np.empty(capacity, np.float32), np.empty(capacity, np.int32), np.empty(capacity, np.int32),
                      np.empty(capacity, np.float32), np.empty(capacity, np.float32), np.empty(capacity, bool),
                      np.empty(capacity, np.float32), new_rayhit())


@stage_kernel
def _fill_ray_times(E, H, fields, column, m):
    """H.times[:m] = shutter times of rays 0..m-1 in Embree's float32; returns how many rays
    carry a time (0 when nothing moves: Embree traces them at time 0). Kernels without the
    reference-counting runtime cannot return array views, hence the count."""
    if not E.has_motion:
        return 0
    for i in range(m):
        H.times[i] = np.float32(fields[i, column])
    return m


@stage_kernel
def closest_hits(E, H, o32, d32, t32, m, fields, time_column, mask):
    """Closest hits of rays 0..m-1 among the geometry classes `mask` into H[:m]
    (accel.Accelerator.intersect_raw: t = t32 and prim -1 on a miss, u = v = 0 there)."""
    for i in range(m):
        H.u[i] = 0.0
        H.v[i] = 0.0
    if not E.has_scene:
        for i in range(m):
            H.t[i] = t32[i]
            H.prim[i] = -1
            H.inst[i] = -1
        return
    timed = _fill_ray_times(E, H, fields, time_column, m)
    intersect_rays(E.scene, H.rayhit, o32[:m], d32[:m], t32[:m], H.times[:timed], E.geom_base, E.inst_base,
                   E.inst_index, H.t[:m], H.prim[:m], H.inst[:m], H.u[:m], H.v[:m], mask)


@stage_kernel
def _occluded(E, H, Q, m, mask):
    if not E.has_scene:
        for i in range(m):
            H.blocked[i] = False
        return
    timed = _fill_ray_times(E, H, Q.F, pk.S_TIME, m)
    occluded_rays(E.scene, H.rayhit, Q.o32[:m], Q.d32[:m], Q.t32[:m], H.times[:timed], H.blocked[:m], mask)


@stage_kernel
def trace_batch(S, T, GR, SN, BT, CB, SP, SPS, E, H, n, F, I, K, C, o32, d32, t32, alive, L, Q, has_null, margin,
                stop, counts, cull_state):
    """Trace the n live paths (path_kernels' state, their next rays in o32 / d32 / t32) to their
    ends, adding radiance to L; counts += vertices, rays and shadow rays traced. cull_state
    (new_cull_state): whether shadow rays through null boundaries first ask about opaque geometry
    (CULL_DECISION_SHADOWS). Returns False if stop[0] was set (Integrator.request_stop) and the
    batch abandoned part-way."""
    iteration = 0
    while n:
        if stop[0] != 0:
            return False
        closest_hits(E, H, o32, d32, t32, n, F, pk.TIME, ALL_MASK)
        counts[RAYS] += n
        m = pk.shade(S, T, GR, SN, BT, CB, SP, SPS, n, iteration, F, I, K, C, H.t[:n], H.prim[:n], H.inst[:n],
                     H.u[:n], H.v[:n], L, alive, Q, counts[VERTICES:VERTICES + 1], o32, d32, t32)
        if m and not has_null:
            _occluded(E, H, Q, m, ALL_MASK)
            counts[SHADOW_RAYS] += m
            pk.shadow_unoccluded(Q.F, Q.I, m, H.blocked[:m], margin, L)
        elif m:
            queued = m
            learning = cull_state[CULL_DECIDED] == CULL_UNDECIDED
            mask = ALL_MASK
            # opaque hits end rays; the rest step through (direct emissive-media samples end here)
            if E.masked and (cull_state[CULL_DECIDED] == 1 or S.emitters.direct):
                _occluded(E, H, Q, m, MASK_OPAQUE)
                counts[SHADOW_RAYS] += m
                m = pk.drop_blocked(Q, m, H.blocked[:m], L)
                mask = MASK_SEE_THROUGH
            for step in range(pk.MAX_VOLUME_BOUNDS):
                if not m:
                    break
                if stop[0] != 0:
                    return False
                closest_hits(E, H, Q.o32, Q.d32, Q.t32, m, Q.F, pk.S_TIME, mask)
                counts[SHADOW_RAYS] += m
                m = pk.shadow_step(S, GR, SN, BT, CB, SP, SPS, Q, m, H.t[:m], H.prim[:m], H.inst[:m], H.u[:m],
                                   H.v[:m], margin, L, iteration, step,
                                   cull_state[CULL_BLOCKED_STEPS:CULL_BLOCKED_STEPS + 1])
            # rays still crossing boundaries after the limit count as blocked (Cycles VOLUME_BOUNDS_MAX)
            if learning:
                learn_cull(cull_state, queued)
        n = pk.compact(F, I, K, C, n, alive, o32, d32, t32)
        iteration += 1
    return True
