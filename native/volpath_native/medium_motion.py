"""Moving grid and program media at a path's shutter time, as Cycles shades a moving volume: its
shader runs with the object's transform at the ray's time (kernel/geom/object.h
object_fetch_transform_motion_test at sd->time, used by shader_setup_from_volume and the volume
attribute lookups of kernel/geom/volume.h), so the density at world point P and time t is the
static density at M(t)^-1 P in object space.

A moving medium's tables (grid_kernels.GridTables) carry its object's decomposed motion steps
(instance_motion.motion_table) and its object -> padded index map. place_at_time writes, for one
shutter time, the medium's world -> index map (lookups, majorant DDA, box clipping) and, for a
program medium, its world -> object frame (Texture Coordinate Object / Generated); the program's
Position stays the world point, as Cycles' sd->P. The majorant grid lives in index space, so the
tracker walks the object's own majorants at the time: the bounds stay exact and tracking unbiased.

Those two arrays are private to a batch (GridMedium._call_tables copies them) and a batch runs its
paths one after another, so each grid call places the medium at its path's time first. A static
medium has one motion step and is never rewritten (one branch per call).
"""
from __future__ import annotations

import numpy as np

from .instance_motion import motion_table, transform_at1
from .jit import inline_stage_kernel, stage_kernel


def motion_fields(transforms, object_to_world, world_to_index) -> dict:
    """GridTables fields of a medium whose object has the (S, 3|4, 4) object -> world transforms
    `transforms` over the shutter (None: static); object_to_world is the transform its
    world_to_index (4x4, padded index space) was built with."""
    if transforms is None or len(transforms) < 2:
        return dict(motion_steps=1, motion=np.zeros((1, 1, 16)), object_to_index=np.zeros((3, 4)))
    steps, table = motion_table([np.asarray(transforms, np.float64)[:, :3, :]])
    object_to_world = np.vstack([np.asarray(object_to_world, np.float64)[:3], [0.0, 0.0, 0.0, 1.0]])
    object_to_index = (np.asarray(world_to_index, np.float64) @ object_to_world)[:3]
    return dict(motion_steps=int(steps[0]), motion=table, object_to_index=np.ascontiguousarray(object_to_index))


@inline_stage_kernel
def place_at_time(G, time):
    """Place medium G where its object is at shutter time `time` (a no-op for a static medium)."""
    if G.motion_steps > 1:
        _place(G, time)


@stage_kernel  # a call: only moving media run this code
def _place(G, time):
    m, offset = transform_at1(G.motion, np.int64(G.motion_steps), 0, time)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    # M^-1 as the adjugate over det M (rows)
    i00, i01, i02 = m11 * m22 - m12 * m21, m02 * m21 - m01 * m22, m01 * m12 - m02 * m11
    i10, i11, i12 = m12 * m20 - m10 * m22, m00 * m22 - m02 * m20, m02 * m10 - m00 * m12
    i20, i21, i22 = m10 * m21 - m11 * m20, m01 * m20 - m00 * m21, m00 * m11 - m01 * m10
    det = m00 * i00 + m01 * i10 + m02 * i20
    s = 1.0 / det if det != 0.0 else 0.0  # scaled to nothing at this time: every point maps to the origin
    i00, i01, i02, i10, i11, i12, i20, i21, i22 = (i00 * s, i01 * s, i02 * s, i10 * s, i11 * s, i12 * s,
                                                   i20 * s, i21 * s, i22 * s)
    ox, oy, oz = offset
    w03 = -(i00 * ox + i01 * oy + i02 * oz)  # world -> object: [M^-1 | -M^-1 offset]
    w13 = -(i10 * ox + i11 * oy + i12 * oz)
    w23 = -(i20 * ox + i21 * oy + i22 * oz)
    a, out = G.object_to_index, G.world_to_index
    for r in range(3):
        out[r, 0] = a[r, 0] * i00 + a[r, 1] * i10 + a[r, 2] * i20
        out[r, 1] = a[r, 0] * i01 + a[r, 1] * i11 + a[r, 2] * i21
        out[r, 2] = a[r, 0] * i02 + a[r, 1] * i12 + a[r, 2] * i22
        out[r, 3] = a[r, 0] * w03 + a[r, 1] * w13 + a[r, 2] * w23 + a[r, 3]
    if G.has_program:
        f = G.frame
        f[0, 0, 0], f[0, 0, 1], f[0, 0, 2], f[0, 0, 3] = i00, i01, i02, w03
        f[0, 1, 0], f[0, 1, 1], f[0, 1, 2], f[0, 1, 3] = i10, i11, i12, w13
        f[0, 2, 0], f[0, 2, 1], f[0, 2, 2], f[0, 2, 3] = i20, i21, i22, w23
