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
from .embree.queries import intersect_rays, new_rayhit, occluded_rays
from .jit import stage_kernel

# The scene's Embree queries: the scene handle (has_scene False: no triangles, every ray misses),
# the tables turning Embree's geometry / instance ids into triangle ids (accel.Accelerator), and
# whether rays carry shutter times (only moving geometry reads them).
RayQueries = namedtuple("RayQueries", ["scene", "has_scene", "geom_base", "inst_base", "inst_index", "has_motion"])
# One thread's hit records of a query (as accel.Hits), occlusion flags, ray times and Embree scratch.
HitBuffers = namedtuple("HitBuffers", ["t", "prim", "inst", "u", "v", "blocked", "times", "rayhit"])

# counts: what a batch traced (render stats)
VERTICES, RAYS, SHADOW_RAYS = 0, 1, 2
N_COUNTS = 3


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
def closest_hits(E, H, o32, d32, t32, m, fields, time_column):
    """Closest hits of rays 0..m-1 into H[:m] (accel.Accelerator.intersect_raw: t = t32 and
    prim -1 on a miss, u = v = 0 there)."""
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
                   E.inst_index, H.t[:m], H.prim[:m], H.inst[:m], H.u[:m], H.v[:m])


@stage_kernel
def _occluded(E, H, Q, m):
    if not E.has_scene:
        for i in range(m):
            H.blocked[i] = False
        return
    timed = _fill_ray_times(E, H, Q.F, pk.S_TIME, m)
    occluded_rays(E.scene, H.rayhit, Q.o32[:m], Q.d32[:m], Q.t32[:m], H.times[:timed], H.blocked[:m])


@stage_kernel
def trace_batch(S, T, GR, SN, BT, CB, SP, SPS, E, H, n, F, I, K, C, o32, d32, t32, alive, L, Q, has_null, margin,
                stop, counts):
    """Trace the n live paths (path_kernels' state, their next rays in o32 / d32 / t32) to their
    ends, adding radiance to L; counts += vertices, rays and shadow rays traced. Returns False if
    stop[0] was set (Integrator.request_stop) and the batch abandoned part-way."""
    iteration = 0
    while n:
        if stop[0] != 0:
            return False
        closest_hits(E, H, o32, d32, t32, n, F, pk.TIME)
        counts[RAYS] += n
        m = pk.shade(S, T, GR, SN, BT, CB, SP, SPS, n, iteration, F, I, K, C, H.t[:n], H.prim[:n], H.inst[:n],
                     H.u[:n], H.v[:n], L, alive, Q, counts[VERTICES:VERTICES + 1], o32, d32, t32)
        if m and not has_null:
            _occluded(E, H, Q, m)
            counts[SHADOW_RAYS] += m
            pk.shadow_unoccluded(Q.F, Q.I, m, H.blocked[:m], margin, L)
        elif m:
            for step in range(pk.MAX_VOLUME_BOUNDS):
                if not m:
                    break
                if stop[0] != 0:
                    return False
                closest_hits(E, H, Q.o32, Q.d32, Q.t32, m, Q.F, pk.S_TIME)
                counts[SHADOW_RAYS] += m
                m = pk.shadow_step(S, GR, SN, BT, CB, SP, SPS, Q, m, H.t[:m], H.prim[:m], H.inst[:m], H.u[:m],
                                   H.v[:m], margin, L, iteration, step)
            # rays still crossing boundaries after the limit count as blocked (Cycles VOLUME_BOUNDS_MAX)
        n = pk.compact(F, I, K, C, n, alive, o32, d32, t32)
        iteration += 1
    return True
