"""Panoramic projections: image coordinates (u, v) in [0, 1]^2 -> direction in the panoramic
camera's space, exactly as Cycles maps them (kernel/camera/projection.h, panorama_to_direction and
the functions it dispatches to). Cycles' panoramic camera space looks along +x with +z up (Blender
object space is reached by PANORAMA_TO_OBJECT below); the mirror ball looks along -y.

A zero direction means "no ray" (outside a fisheye's circle or the mirror ball): Cycles returns a
zero camera sensitivity there, so the sample adds nothing to its pixel.
"""
from __future__ import annotations

import numpy as np

from .jit import kernel, stage_kernel
from .scene import PANORAMA_TYPES  # noqa: F401 (the kinds, in the order of their codes below)

EQUIRECTANGULAR, FISHEYE_EQUIDISTANT, FISHEYE_EQUISOLID, MIRRORBALL, CENTRAL_CYLINDRICAL = range(5)

# Columns of Cycles' fixed panoramic camera matrices (intern/cycles/blender/camera.cpp
# blender_camera_matrix): panoramic camera space -> the Blender camera object's space. Cycles
# points the panorama's centre (+x) along the camera's view axis (-z); the mirror ball swaps y, z.
PANORAMA_TO_OBJECT = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
MIRRORBALL_TO_OBJECT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def equirectangular_range(latitude_min, latitude_max, longitude_min, longitude_max) -> np.ndarray:
    """Cycles' kcam->equirectangular_range (scene/camera.cpp Camera::update)."""
    return np.array([longitude_min - longitude_max, -longitude_min, latitude_min - latitude_max,
                     -latitude_min + 0.5 * np.pi])


def central_cylindrical_range(u_min, u_max, v_min, v_max) -> np.ndarray:
    """Cycles' kcam->central_cylindrical_range (scene/camera.cpp Camera::update); v_min and v_max
    already divided by the cylinder's radius (blender/camera.cpp blender_camera_sync)."""
    return np.array([-u_min, -u_max, v_min, v_max])


@stage_kernel
def _fisheye_to_direction(theta, u, v, r):
    """projection.h fisheye_to_direction."""
    c = u / r if r != 0.0 else 0.0  # safe_divide
    phi = np.arccos(min(max(c, -1.0), 1.0))  # safe_acosf
    if v < 0.0:
        phi = -phi
    return np.cos(theta), -np.cos(phi) * np.sin(theta), np.sin(phi) * np.sin(theta)


@stage_kernel
def panorama_to_direction(kind, u, v, eq_range, cyl_range, fisheye_fov, fisheye_lens, sensor_width,
                          sensor_height):
    """projection.h panorama_to_direction: (x, y, z), not normalised; (0, 0, 0) for no ray."""
    if kind == EQUIRECTANGULAR:  # equirectangular_range_to_direction + spherical_to_direction
        phi = eq_range[0] * u + eq_range[1]
        theta = eq_range[2] * v + eq_range[3]
        return np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)
    if kind == FISHEYE_EQUIDISTANT:  # fisheye_equidistant_to_direction
        u = (u - 0.5) * 2.0
        v = (v - 0.5) * 2.0
        r = np.sqrt(u * u + v * v)
        if r > 1.0:
            return 0.0, 0.0, 0.0
        return _fisheye_to_direction(r * fisheye_fov * 0.5, u, v, r)
    if kind == FISHEYE_EQUISOLID:  # fisheye_equisolid_to_direction
        u = (u - 0.5) * sensor_width
        v = (v - 0.5) * sensor_height
        rmax = 2.0 * fisheye_lens * np.sin(fisheye_fov * 0.25)
        r = np.sqrt(u * u + v * v)
        if r > rmax:
            return 0.0, 0.0, 0.0
        return _fisheye_to_direction(2.0 * np.arcsin(r / (2.0 * fisheye_lens)), u, v, r)
    if kind == MIRRORBALL:  # mirrorball_to_direction: reflect (0, -1, 0) off the ball's normal
        x = 2.0 * u - 1.0
        z = 2.0 * v - 1.0
        if x * x + z * z > 1.0:
            return 0.0, 0.0, 0.0
        y = -np.sqrt(max(1.0 - x * x - z * z, 0.0))
        d = -y  # dot(n, I) with I = (0, -1, 0)
        return 2.0 * d * x, 2.0 * d * y + 1.0, 2.0 * d * z
    # CENTRAL_CYLINDRICAL: central_cylindrical_to_direction
    theta = cyl_range[0] + u * (cyl_range[1] - cyl_range[0])
    z = cyl_range[2] + v * (cyl_range[3] - cyl_range[2])
    return np.cos(theta), np.sin(theta), z


@kernel
def _directions_many(kind, u, v, eq_range, cyl_range, fov, lens, sw, sh, out):
    for i in range(u.shape[0]):
        d = panorama_to_direction(kind, u[i], v[i], eq_range, cyl_range, fov, lens, sw, sh)
        out[i, 0], out[i, 1], out[i, 2] = d[0], d[1], d[2]


def panorama_directions(kind: int, u, v, eq_range, cyl_range, fisheye_fov=np.pi, fisheye_lens=10.5,
                        sensor_width=36.0, sensor_height=24.0) -> np.ndarray:
    """(N, 3) directions in panoramic camera space for arrays of (u, v) (for tests and tools)."""
    u = np.ascontiguousarray(u, np.float64).ravel()
    v = np.ascontiguousarray(v, np.float64).ravel()
    out = np.empty((len(u), 3))
    _directions_many(int(kind), u, v, np.asarray(eq_range, np.float64), np.asarray(cyl_range, np.float64),
                     float(fisheye_fov), float(fisheye_lens), float(sensor_width), float(sensor_height), out)
    return out
