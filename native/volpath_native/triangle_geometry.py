"""Per-triangle geometric normals and areas in one compiled pass over a mesh (no (T, 3) float64
temporaries): the numbers numpy's cross product gave before, bit for bit (float64 edges from the
float32 corners, the same products and sums in the same order, no fused multiply-add)."""
from __future__ import annotations

import numpy as np

from .jit import kernel


@kernel
def _normals_and_lengths(vertices, triangles, normals, lengths, with_normals):
    for i in range(triangles.shape[0]):
        a, b, c = triangles[i, 0], triangles[i, 1], triangles[i, 2]
        p0x, p0y, p0z = np.float64(vertices[a, 0]), np.float64(vertices[a, 1]), np.float64(vertices[a, 2])
        e1x, e1y, e1z = vertices[b, 0] - p0x, vertices[b, 1] - p0y, vertices[b, 2] - p0z
        e2x, e2y, e2z = vertices[c, 0] - p0x, vertices[c, 1] - p0y, vertices[c, 2] - p0z
        x = e1y * e2z - e1z * e2y
        y = e1z * e2x - e1x * e2z
        z = e1x * e2y - e1y * e2x
        length = np.sqrt((x * x + z * z) + y * y)  # numpy's einsum order, which made these tables before
        lengths[i] = length
        if with_normals:
            scale = max(length, 1e-30)
            normals[i, 0], normals[i, 1], normals[i, 2] = x / scale, y / scale, z / scale


def normals_and_doubled_areas(vertices: np.ndarray, triangles: np.ndarray, with_normals: bool = True):
    """((T, 3) float64 unit normals (p1 - p0) x (p2 - p0), outward for counter-clockwise
    corners; (T,) float64 twice the areas) of triangles (T, 3) into float32 vertices (V, 3).
    with_normals=False: the areas alone (normals is an empty array)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    triangles = np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3)
    n = len(triangles)
    normals = np.empty((n if with_normals else 0, 3))
    lengths = np.empty(n)
    if n:
        _normals_and_lengths(vertices, triangles, normals, lengths, with_normals)
    return normals, lengths


@kernel
def _corner_bounds(vertices, triangles, lo, hi):
    for i in range(triangles.shape[0]):
        for k in range(3):
            j = triangles[i, k]
            for axis in range(3):
                value = vertices[j, axis]
                if value < lo[axis]:
                    lo[axis] = value
                if value > hi[axis]:
                    hi[axis] = value


def corner_bounds(vertices: np.ndarray, triangles: np.ndarray):
    """(lo, hi) float64 (3,) bounds of the vertices the triangles use (not of unused ones), or
    None when there are no triangles."""
    if not len(triangles):
        return None
    lo = np.full(3, np.inf, np.float32)
    hi = np.full(3, -np.inf, np.float32)
    _corner_bounds(np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3),
                   np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3), lo, hi)
    return lo.astype(np.float64), hi.astype(np.float64)
