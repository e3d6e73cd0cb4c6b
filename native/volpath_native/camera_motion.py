"""Camera motion blur as Cycles does it: a shutter time per camera ray drawn from the shutter
curve, and the camera transform interpolated at that time between its motion steps.

- Shutter time (Cycles scene/camera.cpp Camera::device_update: util_cdf_inverted of the shutter
  curve into SHUTTER_TABLE_SIZE entries; kernel/camera/camera.h camera_sample reads it with
  lookup_table_read, then applies the rolling shutter).
- Transform (util/transform.cpp transform_motion_decompose: rotation quaternion + translation,
  consecutive quaternions on the same hemisphere; util/transform.h
  transform_motion_array_interpolate: slerp, or normalised lerp when nearly parallel, and linear
  translation between the two steps around the time).
"""
from __future__ import annotations

import numpy as np

from .jit import stage_kernel

SHUTTER_TABLE_SIZE = 256  # Cycles kernel/types.h


def shutter_table(curve) -> np.ndarray:
    """The inverted CDF of the shutter curve (values at evenly spaced times of the shutter; empty:
    constant), SHUTTER_TABLE_SIZE entries in [0, 1] (Cycles util/math_cdf.h util_cdf_inverted with
    resolution SHUTTER_TABLE_SIZE, from 0 to 1, not symmetric)."""
    curve = np.asarray(curve, dtype=np.float64).ravel()
    resolution = SHUTTER_TABLE_SIZE - 1  # util_cdf_inverted evaluates the CDF at resolution - 1

    def curve_eval(x):  # scene/camera.cpp shutter_curve_eval
        if curve.size == 0:
            return 1.0
        if x <= 0.0:  # Cycles reads one element before the array here; the first value is meant
            return curve[0]
        x = min(max(x, 0.0), 1.0) * curve.size - 1
        index = int(x)
        frac = x - index
        if index < curve.size - 1:
            return curve[index] + frac * (curve[index + 1] - curve[index])
        return curve[-1]

    cdf = np.zeros(resolution + 1)
    for i in range(resolution):  # util_cdf_evaluate
        cdf[i + 1] = cdf[i] + abs(curve_eval(i / (resolution - 1)))
    cdf *= 0.0 if cdf[resolution] == 0.0 else 1.0 / cdf[resolution]
    cdf[resolution] = 1.0
    size = SHUTTER_TABLE_SIZE
    inverse = np.empty(size)
    for i in range(size):  # util_cdf_invert, make_symmetric = false
        x = (i + 0.5) / size
        index = int(np.searchsorted(cdf, x, side="right")) - 1
        if index < len(cdf) - 1:
            t = (x - cdf[index]) / (cdf[index + 1] - cdf[index])
        else:
            t, index = 0.0, size
        inverse[i] = (index + t) / size
    return inverse


@stage_kernel
def shutter_time1(table, u):
    """kernel/util/lookup_table.h lookup_table_read of the shutter table at u."""
    size = table.shape[0]
    x = min(max(u, 0.0), 1.0) * (size - 1)
    index = min(np.int64(x), size - 1)
    following = min(index + 1, size - 1)
    t = x - index
    if t == 0.0:
        return table[index]
    return (1.0 - t) * table[index] + t * table[following]


def _quaternion(rotation: np.ndarray) -> np.ndarray:
    """(x, y, z, w) of a proper rotation matrix (any sign: transform_motion_decompose matches
    consecutive signs afterwards)."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 0.5 / np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) * s, (m[0, 2] - m[2, 0]) * s, (m[1, 0] - m[0, 1]) * s, 0.25 / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def decompose_motion(rotations, translations) -> tuple[np.ndarray, np.ndarray]:
    """(S, 4) quaternions with consecutive ones on the same hemisphere and (S, 3) translations of
    the camera's motion steps (rotations: (S, 3, 3) proper rotations)."""
    quats = np.array([_quaternion(np.asarray(r, np.float64)) for r in rotations]).reshape(-1, 4)
    for i in range(1, len(quats)):
        if np.dot(quats[i - 1], quats[i]) < 0.0:
            quats[i] = -quats[i]
    return np.ascontiguousarray(quats), np.ascontiguousarray(np.asarray(translations, np.float64).reshape(-1, 3))


@stage_kernel
def slerp_rotation1(a, b, t):
    """Rotation (3x3 as 9 numbers row by row) of the unit quaternions a, b (x, y, z, w)
    interpolated at t in [0, 1] as Cycles' quat_interpolate (util/transform.h): normalised lerp
    when nearly parallel, else slerp."""
    a0, a1, a2, a3 = a[0], a[1], a[2], a[3]
    b0, b1, b2, b3 = b[0], b[1], b[2], b[3]
    cos_theta = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
    if cos_theta > 0.9995:
        x, y, z, w = (1.0 - t) * a0 + t * b0, (1.0 - t) * a1 + t * b1, (1.0 - t) * a2 + t * b2, (1.0 - t) * a3 + t * b3
        norm = np.sqrt(x * x + y * y + z * z + w * w)
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
    else:
        theta = np.arccos(min(max(cos_theta, -1.0), 1.0))
        p0, p1, p2, p3 = b0 - a0 * cos_theta, b1 - a1 * cos_theta, b2 - a2 * cos_theta, b3 - a3 * cos_theta
        norm = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        c, s = np.cos(theta * t), np.sin(theta * t) / norm
        x, y, z, w = a0 * c + p0 * s, a1 * c + p1 * s, a2 * c + p2 * s, a3 * c + p3 * s
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


@stage_kernel
def interpolate_motion1(quats, translations, time):
    """(rotation 3x3 as 9 numbers row by row, position (3,)) of the camera at shutter time in [0, 1]."""
    maxstep = quats.shape[0] - 1
    step = min(np.int64(time * maxstep), maxstep - 1)
    t = time * maxstep - step
    rotation = slerp_rotation1(quats[step], quats[step + 1], t)
    position = ((1.0 - t) * translations[step, 0] + t * translations[step + 1, 0],
                (1.0 - t) * translations[step, 1] + t * translations[step + 1, 1],
                (1.0 - t) * translations[step, 2] + t * translations[step + 1, 2])
    return rotation, position
