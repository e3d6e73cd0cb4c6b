"""Deforming triangles at a ray's shutter time, from accel's deformation tables (deform_rows:
per triangle [first row, steps, stride, has normal steps]; deform_corners: (3, 3) corner
positions per row): the two steps around the time and the corners interpolated linearly between
them, as Cycles' kernel/geom/motion_triangle.h motion_triangle_vertices. Moving emitters and
medium boundaries are such triangles too (instance_motion.placed_motion), so the light table
samples them where they are at the time (Cycles kernel/light/triangle.h
triangle_world_space_vertices)."""
from __future__ import annotations

import numpy as np

from .jit import inline_stage_kernel, stage_kernel


@inline_stage_kernel
def deform_step(rows, prim, time):
    """(row of the step before `time`, row of the step after, weight of the latter) of a deforming
    triangle."""
    row, steps, stride = rows[prim, 0], rows[prim, 1], rows[prim, 2]
    maxstep = steps - 1
    step = min(max(np.int64(time * maxstep), 0), maxstep - 1)
    t = min(max(time * maxstep - step, 0.0), 1.0)
    return row + step * stride, row + (step + 1) * stride, t


@inline_stage_kernel
def is_deforming(rows, prim):
    """Whether triangle prim has vertex steps (rows is (1, 4) of -1 in scenes without any)."""
    return prim < rows.shape[0] and rows[prim, 0] >= 0


@stage_kernel
def deformed_corners1(rows, c, prim, time):
    """The corners of deforming triangle prim at `time`, 9 numbers (corner by corner)."""
    a, b, t = deform_step(rows, prim, time)
    s = 1.0 - t
    return (s * c[a, 0, 0] + t * c[b, 0, 0], s * c[a, 0, 1] + t * c[b, 0, 1], s * c[a, 0, 2] + t * c[b, 0, 2],
            s * c[a, 1, 0] + t * c[b, 1, 0], s * c[a, 1, 1] + t * c[b, 1, 1], s * c[a, 1, 2] + t * c[b, 1, 2],
            s * c[a, 2, 0] + t * c[b, 2, 0], s * c[a, 2, 1] + t * c[b, 2, 1], s * c[a, 2, 2] + t * c[b, 2, 2])
