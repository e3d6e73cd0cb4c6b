"""Instance motion as Cycles hands it to Embree: each step's object -> world decomposed into a
rotation quaternion, a translation and a scale/skew matrix (Cycles util/transform.cpp
transform_decompose: polar decomposition M = R S by iterating R <- (R + R^-T) / 2, R flipped to
a proper rotation by negating S; transform_motion_decompose: consecutive quaternions on one
hemisphere), passed per time step to rtcSetGeometryTransformQuaternion with scale (S_xx, S_yy,
S_zz), skew (S_xy, S_xz, S_yz) and the translation (Cycles bvh/embree.cpp add_instance). Embree
interpolates the quaternion by slerp and the rest linearly, as Cycles' kernel
(transform_motion_array_interpolate). Embree's scale/skew matrix is upper triangular, so S's lower
part is dropped as in Cycles: exact for rotation + scale, approximate for moving sheared objects
(Cycles has the same limitation)."""
from __future__ import annotations

import numpy as np

from .library import RTCQuaternionDecomposition


def decompose(transform: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(quaternion (x, y, z, w), translation (3,), S (3, 3)) of an object -> world (3, 4)."""
    linear = np.asarray(transform, np.float64)[:, :3]
    rotation = linear.copy()
    for _ in range(100):  # transform_decompose's polar iteration
        following = 0.5 * (rotation + np.linalg.inv(rotation).T)
        change = np.abs(rotation - following).sum(axis=1).max()
        rotation = following
        if change <= 1e-12:
            break
    if np.linalg.det(rotation) < 0.0:
        rotation = -rotation
    scale = np.linalg.inv(rotation) @ linear
    return _quaternion(rotation), np.asarray(transform, np.float64)[:, 3].copy(), scale


def decomposed_steps(transforms: np.ndarray) -> list:
    """[(quaternion, translation, S)] of the steps, quaternions on one hemisphere."""
    steps = [decompose(t) for t in np.asarray(transforms, np.float64).reshape(-1, 3, 4)]
    for i in range(1, len(steps)):
        if np.dot(steps[i - 1][0], steps[i][0]) < 0.0:
            steps[i] = (-steps[i][0], steps[i][1], steps[i][2])
    return steps


def quaternion_decompositions(transforms: np.ndarray) -> list:
    """RTCQuaternionDecomposition per step, filled as Cycles' add_instance does."""
    out = []
    for (x, y, z, w), translation, scale in decomposed_steps(transforms):
        d = RTCQuaternionDecomposition()
        d.scale_x, d.scale_y, d.scale_z = scale[0, 0], scale[1, 1], scale[2, 2]
        d.skew_xy, d.skew_xz, d.skew_yz = scale[0, 1], scale[0, 2], scale[1, 2]
        d.shift_x = d.shift_y = d.shift_z = 0.0
        d.quaternion_r, d.quaternion_i, d.quaternion_j, d.quaternion_k = w, x, y, z
        d.translation_x, d.translation_y, d.translation_z = translation
        out.append(d)
    return out


def _quaternion(rotation: np.ndarray) -> np.ndarray:
    """(x, y, z, w) of a proper rotation matrix."""
    from ..camera_motion import _quaternion as quaternion_of
    return quaternion_of(rotation)
