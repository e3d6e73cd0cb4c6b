"""Ray queries against all triangles of a scene through Embree, in bulk.

One Embree scene holds every non-degenerate triangle; per-triangle tables (material, geometric
normal, area, owning mesh) are indexed by Embree's primitive id. The queries are compiled loops
over Embree's own library (embree/: shared buffers, no copies) that release the GIL, so several
threads trace at once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .embree import TriangleScene
from .scene import TRIANGLE_CHUNK as _CHUNK, Mesh, doubled_areas, padded_rows, triangle_cross as _cross

MISS = -1


@dataclass
class Hits:
    t: np.ndarray        # (N,) float64 hit distance, inf on a miss
    prim: np.ndarray     # (N,) int32 triangle index, MISS (-1) on a miss
    u: np.ndarray        # (N,) float32 barycentric of vertex 1
    v: np.ndarray        # (N,) float32 barycentric of vertex 2


class Accelerator:
    """All triangles of the scene, flattened, and an Embree BVH over them.

    Per triangle it keeps: vertex indices (int32), material and mesh ids (int32), the geometric
    normal (float64 x3), the area (float64) and, for smooth meshes, corner normals (float32 x9);
    the float64 corner positions (`corners`, 72 bytes a triangle) only when asked for
    (triangle_corners for a few). Array work runs in chunks, so temporaries stay small."""

    def __init__(self, meshes: list[Mesh]):
        meshes = [copy for mesh in meshes for copy in mesh.world_copies()]
        verts, tris, mats, mesh_ids, kept_meshes = [], [], [], [], []
        base = 0
        for mesh_index, mesh in enumerate(meshes):
            t = mesh.triangles
            if len(t):
                keep = doubled_areas(mesh.vertices, t) > 1e-20  # degenerate ones dropped (Scene.validate warns)
                everything = bool(keep.all())
                verts.append(mesh.vertices)
                tris.append((t if everything else t[keep]) + base)
                mats.append(mesh.material_ids if everything else mesh.material_ids[keep])
                mesh_ids.append(np.full(len(tris[-1]), mesh_index, dtype=np.int32))
                kept_meshes.append((mesh, None if everything else keep))
            base += len(mesh.vertices)
        self.has_smooth = any(mesh.corner_normals is not None for mesh, _ in kept_meshes)
        if tris:
            self.vertices = padded_rows(_joined(verts, np.float32))
            self.triangles = _joined(tris, np.int32)
            self.material_ids = _joined(mats, np.int32)
            self.mesh_ids = _joined(mesh_ids, np.int32)
        else:
            self.vertices = np.zeros((0, 3), np.float32)
            self.triangles = np.zeros((0, 3), np.int32)
            self.material_ids = np.zeros(0, np.int32)
            self.mesh_ids = np.zeros(0, np.int32)
        n = len(self.triangles)
        self.normals = np.empty((n, 3))  # outward for CCW triangles
        self.areas = np.empty(n)
        for lo in range(0, n, _CHUNK):
            hi = min(lo + _CHUNK, n)
            cross = _cross(self.vertices, self.triangles[lo:hi])
            length = np.sqrt(np.einsum("ij,ij->i", cross, cross))
            self.normals[lo:hi] = cross / np.maximum(length, 1e-30)[:, None]
            self.areas[lo:hi] = 0.5 * length
        if self.has_smooth:
            self.corner_normals = np.empty((n, 3, 3), np.float32)
            start = 0
            for mesh, keep in kept_meshes:
                count = len(mesh.triangles) if keep is None else int(np.count_nonzero(keep))
                normals = mesh.corner_normals
                if normals is None:  # flat mesh among smooth ones: the geometric normal at every corner
                    self.corner_normals[start:start + count] = self.normals[start:start + count, None, :]
                else:
                    self.corner_normals[start:start + count] = normals if keep is None else normals[keep]
                start += count
        used = np.zeros(len(self.vertices), bool)
        used[self.triangles.reshape(-1)] = True
        lo = self.vertices[used].min(axis=0).astype(np.float64) if n else np.zeros(3)
        hi = self.vertices[used].max(axis=0).astype(np.float64) if n else np.zeros(3)
        self.bounds = (lo, hi)
        # Ray offset scale: relative to the scene extent, so it works in mm and km scenes.
        self.epsilon = 1e-5 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
        self._meshes = list(meshes)  # per-corner attributes and frames (surface programs)
        self._kept = kept_meshes
        self._corners = None
        self._embree = None
        if n:
            # Embree reads self.vertices / self.triangles in place (they live as long as self)
            self._embree = TriangleScene()
            self._embree.add_triangles(self.vertices, self.triangles, 0)
            self._embree.commit()

    def corner_attributes(self, names) -> tuple:
        """(T, 3, C) float32 per-corner values of the named attributes for every kept triangle, and
        {name: (first channel, width)}; meshes without an attribute read 0."""
        widths = {}
        for name in names:
            widths[name] = max([m.corner_attributes[name].shape[2] for m in self._meshes
                                if name in m.corner_attributes] or [0])
        channels, offset = {}, 0
        for name in names:
            if widths[name]:
                channels[name] = (offset, widths[name])
                offset += widths[name]
        table = np.zeros((max(self.triangle_count, 1), 3, max(offset, 1)), np.float32)
        row = 0
        for mesh, keep in self._kept:
            n = len(mesh.triangles) if keep is None else int(np.count_nonzero(keep))
            for name, (first, width) in channels.items():
                values = mesh.corner_attributes.get(name)
                if values is not None:
                    table[row:row + n, :, first:first + values.shape[2]] = values if keep is None else values[keep]
            row += n
        return table, channels

    def mesh_frames(self) -> np.ndarray:
        """(n_meshes, 2, 3, 4) world -> object and object -> Generated maps per mesh (Mesh.frame)."""
        if not self._meshes:
            return np.zeros((1, 2, 3, 4))
        return np.ascontiguousarray(np.stack([m.frame() for m in self._meshes]), dtype=np.float64)

    def triangle_corners(self, index) -> np.ndarray:
        """(k, 3, 3) float64 corner positions of the triangles `index`."""
        return self.vertices[self.triangles[index]].astype(np.float64)

    @property
    def corners(self) -> np.ndarray:
        """(T, 3, 3) float64 corner positions of every triangle (computed on first use: 72 bytes a
        triangle, only mesh lights need them all)."""
        if self._corners is None:
            self._corners = self.triangle_corners(slice(None))
        return self._corners

    @property
    def triangle_count(self) -> int:
        return len(self.triangles)

    def intersect(self, origins: np.ndarray, directions: np.ndarray, tmax=None) -> Hits:
        """Closest hit of each ray (origins, unit directions (N,3)) within (0, tmax]."""
        n = len(origins)
        if self._embree is None or n == 0:
            return Hits(np.full(n, np.inf), np.full(n, MISS, np.int32), np.zeros(n, np.float32),
                        np.zeros(n, np.float32))
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        t32 = np.full(n, 1e37 if tmax is None else 0, np.float32)
        if tmax is not None:
            t32[:] = np.minimum(tmax, 1e30)
        t, prim, _, u, v = self._embree.intersect(o, d, t32)
        t = t.astype(np.float64)
        t[prim < 0] = np.inf
        return Hits(t, prim, u, v)

    def intersect_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray) -> Hits:
        """Closest hits for contiguous float32 rays as the compiled stages use them: t is Embree's
        float32 tfar (meaningless on a miss: check prim >= 0), no conversions."""
        n = len(o32)
        if self._embree is None or n == 0:
            return Hits(t32.copy(), np.full(n, MISS, np.int32), np.zeros(n, np.float32), np.zeros(n, np.float32))
        t, prim, _, u, v = self._embree.intersect(o32, d32, t32)
        return Hits(t, prim, u, v)

    def occluded_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray) -> np.ndarray:
        """True where something blocks the contiguous float32 ray before t32."""
        if self._embree is None or len(o32) == 0:
            return np.zeros(len(o32), dtype=bool)
        return self._embree.occluded(o32, d32, t32)

    def shading_normals(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Interpolated smooth normals where the mesh has them, else geometric normals."""
        if not self.has_smooth:
            return self.normals[prim]
        c = self.corner_normals[prim]
        w0 = (1.0 - u - v)[:, None]
        n = c[:, 0] * w0 + c[:, 1] * u[:, None] + c[:, 2] * v[:, None]
        return n / np.maximum(np.linalg.norm(n, axis=1), 1e-30)[:, None]


def _joined(arrays: list, dtype) -> np.ndarray:
    """One contiguous array of the parts (no copy when there is one part of the right type)."""
    if len(arrays) == 1:
        return np.ascontiguousarray(arrays[0], dtype=dtype)
    return np.concatenate(arrays).astype(dtype, copy=False)
