"""Moving instances at a ray's shutter time, as Cycles shades them: each motion step decomposed
(embree/motion.py: rotation quaternion, translation, scale/shear matrix S), interpolated between
the two steps around the time -- quaternion slerp (normalised lerp when nearly parallel), linear
translation and S (Cycles util/transform.h transform_motion_array_interpolate, quat_interpolate)
-- and composed M = R S (transform_compose). The tables are packed per instance; Embree traces the
same steps (rtcSetGeometryTransformQuaternion)."""
from __future__ import annotations

import numpy as np

from .camera_motion import slerp_rotation1
from .embree.motion import decomposed_steps
from .jit import inline_stage_kernel, stage_kernel

QUAT, TRANSLATION, SCALE = 0, 4, 7  # columns of a step in the motion table
STEP_WIDTH = 16


def motion_table(placements: list) -> tuple[np.ndarray, np.ndarray]:
    """(steps per instance (n,) int64, (n, max steps, 16) float64 decomposed steps) of the
    instances' (S_k, 3, 4) transforms; a static instance has 1 step (unused by the kernels)."""
    n = max(len(placements), 1)
    steps = np.ones(n, np.int64)
    width = max([len(p) for p in placements] or [1])
    table = np.zeros((n, width, STEP_WIDTH))
    for k, transforms in enumerate(placements):
        steps[k] = len(transforms)
        if len(transforms) < 2:
            continue
        for s, (quaternion, translation, scale) in enumerate(decomposed_steps(transforms)):
            table[k, s, QUAT:QUAT + 4] = quaternion
            table[k, s, TRANSLATION:TRANSLATION + 3] = translation
            table[k, s, SCALE:SCALE + 9] = scale.reshape(-1)
    return steps, table


@inline_stage_kernel
def transform_at1(table, steps, k, time):
    """(M row by row as 9 numbers, translation (3,)) of instance k at shutter time in [0, 1]."""
    maxstep = steps - 1
    step = min(max(np.int64(time * maxstep), 0), maxstep - 1)
    t = min(max(time * maxstep - step, 0.0), 1.0)
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = slerp_rotation1(table[k, step, QUAT:QUAT + 4],
                                                                  table[k, step + 1, QUAT:QUAT + 4], t)
    s00 = (1.0 - t) * table[k, step, SCALE + 0] + t * table[k, step + 1, SCALE + 0]
    s01 = (1.0 - t) * table[k, step, SCALE + 1] + t * table[k, step + 1, SCALE + 1]
    s02 = (1.0 - t) * table[k, step, SCALE + 2] + t * table[k, step + 1, SCALE + 2]
    s10 = (1.0 - t) * table[k, step, SCALE + 3] + t * table[k, step + 1, SCALE + 3]
    s11 = (1.0 - t) * table[k, step, SCALE + 4] + t * table[k, step + 1, SCALE + 4]
    s12 = (1.0 - t) * table[k, step, SCALE + 5] + t * table[k, step + 1, SCALE + 5]
    s20 = (1.0 - t) * table[k, step, SCALE + 6] + t * table[k, step + 1, SCALE + 6]
    s21 = (1.0 - t) * table[k, step, SCALE + 7] + t * table[k, step + 1, SCALE + 7]
    s22 = (1.0 - t) * table[k, step, SCALE + 8] + t * table[k, step + 1, SCALE + 8]
    m = (r00 * s00 + r01 * s10 + r02 * s20, r00 * s01 + r01 * s11 + r02 * s21, r00 * s02 + r01 * s12 + r02 * s22,
         r10 * s00 + r11 * s10 + r12 * s20, r10 * s01 + r11 * s11 + r12 * s21, r10 * s02 + r11 * s12 + r12 * s22,
         r20 * s00 + r21 * s10 + r22 * s20, r20 * s01 + r21 * s11 + r22 * s21, r20 * s02 + r21 * s12 + r22 * s22)
    offset = ((1.0 - t) * table[k, step, TRANSLATION] + t * table[k, step + 1, TRANSLATION],
              (1.0 - t) * table[k, step, TRANSLATION + 1] + t * table[k, step + 1, TRANSLATION + 1],
              (1.0 - t) * table[k, step, TRANSLATION + 2] + t * table[k, step + 1, TRANSLATION + 2])
    return m, offset


@stage_kernel  # a call, not inlined: only moving instances pay for this code (the path stage stays small)
def normal_map1(table, steps, k, time, x, y, z):
    """Object-space normal (x, y, z) of instance k in world space at `time`, unnormalised:
    M^-T n as the cofactor matrix of M (= det M M^-T) times the sign of det M (an outward normal
    stays outward, on mirrored instances too)."""
    m, _ = transform_at1(table, steps, k, time)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    c00, c01, c02 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20
    c10, c11, c12 = m02 * m21 - m01 * m22, m00 * m22 - m02 * m20, m01 * m20 - m00 * m21
    c20, c21, c22 = m01 * m12 - m02 * m11, m02 * m10 - m00 * m12, m00 * m11 - m01 * m10
    sign = 1.0 if m00 * c00 + m01 * c01 + m02 * c02 >= 0.0 else -1.0  # det M along the first row
    return (sign * (c00 * x + c01 * y + c02 * z), sign * (c10 * x + c11 * y + c12 * z),
            sign * (c20 * x + c21 * y + c22 * z))


MAX_TURN_PER_STEP = np.radians(2.0)  # a chord of a 2 degree arc is 1.5e-4 of the radius short
MAX_PLACED_STEPS = 65  # Embree takes up to 129 time steps


def placed_motion(motion: np.ndarray, vertices: np.ndarray, vertex_motion=None, corner_normals=None,
                  corner_normal_motion=None) -> tuple:
    """World positions (N, V, 3) float32 and corner normals (N, T, 3, 3) float32 (None without
    corner normals) of one moving instance at N evenly spaced shutter times: its transform
    interpolated as Cycles (transform_at1) applied to its vertices (its vertex steps interpolated
    linearly first, Cycles kernel/light/triangle.h triangle_world_space_vertices:
    motion_triangle_vertices, then the object's transform at the time). What an emitting or
    medium-bounding instance is traced as (a deforming world mesh). Between the N steps Embree
    and the stages interpolate positions linearly; N is raised until a step turns the object by
    at most MAX_TURN_PER_STEP, so the chord stays within 1.5e-4 of the arc Cycles' slerp draws."""
    motion = np.asarray(motion, np.float64)
    steps, table = motion_table([motion])
    intervals = max(len(motion) - 1, 1 if vertex_motion is None else len(vertex_motion) - 1)
    if vertex_motion is not None:  # both are 2^k + 1 steps in the exporter; otherwise the finer grid
        intervals = int(np.lcm(len(motion) - 1, len(vertex_motion) - 1))
    quats = table[0, :len(motion), QUAT:QUAT + 4]
    turn = max([2.0 * np.arccos(min(abs(float(np.dot(a, b))), 1.0)) for a, b in zip(quats[:-1], quats[1:])] or [0.0])
    split = 1
    while turn * (len(motion) - 1) / (intervals * split) > MAX_TURN_PER_STEP \
            and intervals * split * 2 + 1 <= MAX_PLACED_STEPS:
        split *= 2
    count = intervals * split + 1
    times = np.linspace(0.0, 1.0, count)
    positions = np.empty((count, len(vertices), 3), np.float32)
    normals = None if corner_normals is None else np.empty((count,) + corner_normals.shape, np.float32)
    for i, time in enumerate(times):
        m, offset = transform_at1(table, steps[0], 0, time)
        linear = np.array(m).reshape(3, 3)
        local = _linear_steps(vertex_motion, time) if vertex_motion is not None else vertices
        positions[i] = np.asarray(local, np.float64) @ linear.T + np.array(offset)
        if normals is not None:
            n = _linear_steps(corner_normal_motion, time) if corner_normal_motion is not None else corner_normals
            n = np.asarray(n, np.float64) @ np.linalg.inv(linear)  # M^-T n, as rows
            normals[i] = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    return positions, normals


def _linear_steps(values: np.ndarray, time: float) -> np.ndarray:
    """Evenly spaced steps interpolated linearly at time (Cycles motion_triangle_vertices)."""
    maxstep = len(values) - 1
    step = min(max(int(time * maxstep), 0), maxstep - 1)
    t = min(max(time * maxstep - step, 0.0), 1.0)
    return (1.0 - t) * values[step].astype(np.float64) + t * values[step + 1].astype(np.float64)
