"""Bulk ray queries over contiguous float32 rays, compiled: one loop per call that fills an
RTCRayHit / RTCRay and calls rtcIntersect1 / rtcOccluded1 (rtcore_scene.h) by the names
library.register_symbols gives them, without the GIL, so render threads trace in parallel. The loops are
cached on disk like every kernel (jit.py): an external function called by name is relocated when
the cached code is loaded, after library.py has put the symbols into LLVM's table."""
from __future__ import annotations

import numpy as np
from numba import types

from ..jit import stage_kernel
from . import library as lib

_rtc_intersect1 = types.ExternalFunction(lib.SYMBOL_PREFIX + "rtcIntersect1",
                                         types.void(types.uintp, types.uintp, types.uintp))
_rtc_occluded1 = types.ExternalFunction(lib.SYMBOL_PREFIX + "rtcOccluded1",
                                        types.void(types.uintp, types.uintp, types.uintp))

RAY_ORG, RAY_TNEAR, RAY_DIR, RAY_TIME = lib.RAY_ORG, lib.RAY_TNEAR, lib.RAY_DIR, lib.RAY_TIME
RAY_TFAR, RAY_MASK, RAY_ID, RAY_FLAGS = lib.RAY_TFAR, lib.RAY_MASK, lib.RAY_ID, lib.RAY_FLAGS
HIT_U, HIT_V, HIT_PRIM, HIT_GEOM, HIT_INST = lib.HIT_U, lib.HIT_V, lib.HIT_PRIM, lib.HIT_GEOM, lib.HIT_INST
INVALID = np.uint32(lib.INVALID_ID)
ALL_MASK = np.uint32(0xFFFFFFFF)


def new_rayhit() -> np.ndarray:
    """Scratch for one RTCRayHit: float32 words, 64-byte aligned (the struct needs 16)."""
    raw = np.zeros(lib.RAYHIT_WORDS + 16, np.float32)
    start = (-raw.ctypes.data % 64) // 4
    return raw[start:start + lib.RAYHIT_WORDS]


@stage_kernel
def _set_ray(f, w, o, d, i, tfar, time, mask):
    f[RAY_ORG], f[RAY_ORG + 1], f[RAY_ORG + 2] = o[i, 0], o[i, 1], o[i, 2]
    f[RAY_TNEAR] = 0.0
    f[RAY_DIR], f[RAY_DIR + 1], f[RAY_DIR + 2] = d[i, 0], d[i, 1], d[i, 2]
    f[RAY_TIME] = time
    f[RAY_TFAR] = tfar
    w[RAY_MASK] = mask
    w[RAY_ID] = 0
    w[RAY_FLAGS] = 0


@stage_kernel
def intersect_rays(scene, rayhit, o, d, tfar, times, geom_base, inst_base, inst_index, t_out, prim_out, inst_out, u_out,
                   v_out, mask):
    """Closest hit of rays i < len(o) within (0, tfar[i]] at times[i] (times empty: time 0) among
    the geometries whose mask shares a bit with `mask` (rtcSetGeometryMask; ALL_MASK: all).
    t_out = the hit distance (tfar[i] on a miss), prim_out = geom_base[geomID] + primID for
    world-space geometry or inst_base[instID] + primID inside an instance (-1 on a miss),
    inst_out = inst_index[instID], the instance's own number (-1: none), u_out / v_out =
    barycentrics of vertices 1 and 2."""
    f = rayhit
    w = rayhit.view(np.uint32)
    address = rayhit.ctypes.data
    timed = times.shape[0] > 0
    for i in range(o.shape[0]):
        _set_ray(f, w, o, d, i, tfar[i], times[i] if timed else np.float32(0.0), mask)
        w[HIT_GEOM] = INVALID
        w[HIT_INST] = INVALID
        _rtc_intersect1(scene, address, 0)
        t_out[i] = f[RAY_TFAR]
        geom = w[HIT_GEOM]
        if geom == INVALID:
            prim_out[i] = -1
            inst_out[i] = -1
            continue
        instance = w[HIT_INST]
        if instance == INVALID:
            prim_out[i] = geom_base[geom] + np.int32(w[HIT_PRIM])
            inst_out[i] = -1
        else:
            prim_out[i] = inst_base[instance] + np.int32(w[HIT_PRIM])
            inst_out[i] = inst_index[instance]
        u_out[i] = f[HIT_U]
        v_out[i] = f[HIT_V]


@stage_kernel
def occluded_rays(scene, ray, o, d, tfar, times, blocked, mask):
    """blocked[i] = whether any geometry whose mask shares a bit with `mask` lies on ray i within
    (0, tfar[i]) at times[i]."""
    f = ray
    w = ray.view(np.uint32)
    address = ray.ctypes.data
    timed = times.shape[0] > 0
    for i in range(o.shape[0]):
        _set_ray(f, w, o, d, i, tfar[i], times[i] if timed else np.float32(0.0), mask)
        _rtc_occluded1(scene, address, 0)
        blocked[i] = f[RAY_TFAR] < 0.0  # rtcOccluded1 sets tfar to -inf on a hit
