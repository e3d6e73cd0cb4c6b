"""Ray queries against all triangles of a scene through Embree (embreex), in bulk.

One Embree scene holds every non-degenerate triangle; per-triangle tables (material, geometric
normal, area, owning mesh) are indexed by Embree's primitive id. embreex releases the GIL during
queries, so several threads can trace at once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Mesh

MISS = -1


@dataclass
class Hits:
    t: np.ndarray        # (N,) float64 hit distance, inf on a miss
    prim: np.ndarray     # (N,) int32 triangle index, MISS (-1) on a miss
    u: np.ndarray        # (N,) float32 barycentric of vertex 1
    v: np.ndarray        # (N,) float32 barycentric of vertex 2


class Accelerator:
    """All triangles of the scene, flattened, and an Embree BVH over them."""

    def __init__(self, meshes: list[Mesh]):
        verts, tris, mats, mesh_ids, corner_normals = [], [], [], [], []
        self._meshes = list(meshes)
        self._keep = []  # per mesh: the triangles kept (non-degenerate), in order
        base = 0
        for mesh_index, mesh in enumerate(meshes):
            v = mesh.vertices.astype(np.float64)
            t = mesh.triangles
            if len(t):
                p = v[t]
                area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
                keep = area2 > 1e-20  # degenerate triangles are dropped (Scene.validate warns)
                self._keep.append(keep)
                t = t[keep]
                verts.append(mesh.vertices)
                tris.append(t + base)
                mats.append(mesh.material_ids[keep])
                mesh_ids.append(np.full(len(t), mesh_index, dtype=np.int32))
                if mesh.corner_normals is not None:
                    corner_normals.append(mesh.corner_normals[keep])
                else:
                    corner_normals.append(None)
            base += len(mesh.vertices)
        self.has_smooth = any(c is not None for c in corner_normals)
        if tris:
            self.vertices = np.concatenate(verts).astype(np.float32)
            self.triangles = np.concatenate(tris).astype(np.int32)
            self.material_ids = np.concatenate(mats).astype(np.int32)
            self.mesh_ids = np.concatenate(mesh_ids)
        else:
            self.vertices = np.zeros((0, 3), np.float32)
            self.triangles = np.zeros((0, 3), np.int32)
            self.material_ids = np.zeros(0, np.int32)
            self.mesh_ids = np.zeros(0, np.int32)
        p = self.vertices.astype(np.float64)[self.triangles]
        self.corners = p  # (T, 3, 3) float64
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) if len(p) else np.zeros((0, 3))
        length = np.linalg.norm(cross, axis=1) if len(p) else np.zeros(0)
        self.normals = cross / np.maximum(length, 1e-30)[:, None]  # outward for CCW triangles
        self.areas = 0.5 * length
        if self.has_smooth:
            self.corner_normals = np.concatenate([
                c if c is not None else np.repeat(self.normals[s:s + n, None, :], 3, axis=1)
                for c, s, n in _segments(corner_normals, mats)]).astype(np.float64)
        lo = p.reshape(-1, 3).min(axis=0) if len(p) else np.zeros(3)
        hi = p.reshape(-1, 3).max(axis=0) if len(p) else np.zeros(3)
        self.bounds = (lo, hi)
        # Ray offset scale: relative to the scene extent, so it works in mm and km scenes.
        self.epsilon = 1e-5 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
        self._embree = None
        if len(self.triangles):
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
            self._embree = rtcore_scene.EmbreeScene()
            TriangleMesh(self._embree, self.vertices, self.triangles)

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
        keeps = iter(self._keep)
        for mesh in self._meshes:
            if not len(mesh.triangles):
                continue
            keep = next(keeps)
            n = int(keep.sum())
            for name, (first, width) in channels.items():
                values = mesh.corner_attributes.get(name)
                if values is not None:
                    table[row:row + n, :, first:first + values.shape[2]] = values[keep]
            row += n
        return table, channels

    def mesh_frames(self) -> np.ndarray:
        """(n_meshes, 2, 3, 4) world -> object and object -> Generated maps per mesh (Mesh.frame)."""
        if not self._meshes:
            return np.zeros((1, 2, 3, 4))
        return np.ascontiguousarray(np.stack([m.frame() for m in self._meshes]), dtype=np.float64)

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
        dists = None if tmax is None else np.minimum(tmax, 1e30).astype(np.float32)
        res = self._embree.run(o, d, dists=dists, output=1)
        prim = res["primID"].astype(np.int32, copy=False)
        t = res["tfar"].astype(np.float64)
        t[prim < 0] = np.inf
        return Hits(t, prim, res["u"], res["v"])

    def intersect_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray) -> Hits:
        """Closest hits for contiguous float32 rays as the compiled stages use them: t is Embree's
        float32 tfar (meaningless on a miss: check prim >= 0), no conversions."""
        n = len(o32)
        if self._embree is None or n == 0:
            return Hits(t32.copy(), np.full(n, MISS, np.int32), np.zeros(n, np.float32), np.zeros(n, np.float32))
        res = self._embree.run(o32, d32, dists=t32.copy(), output=1)
        return Hits(res["tfar"], res["primID"].astype(np.int32, copy=False), res["u"], res["v"])

    def occluded_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray) -> np.ndarray:
        """True where something blocks the contiguous float32 ray before t32."""
        if self._embree is None or len(o32) == 0:
            return np.zeros(len(o32), dtype=bool)
        return self._embree.run(o32, d32, dists=t32.copy(), query="OCCLUDED") >= 0


    def shading_normals(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Interpolated smooth normals where the mesh has them, else geometric normals."""
        if not self.has_smooth:
            return self.normals[prim]
        c = self.corner_normals[prim]
        w0 = (1.0 - u - v)[:, None]
        n = c[:, 0] * w0 + c[:, 1] * u[:, None] + c[:, 2] * v[:, None]
        return n / np.maximum(np.linalg.norm(n, axis=1), 1e-30)[:, None]


def _segments(corner_normals, mats):
    start = 0
    for c, m in zip(corner_normals, mats):
        yield c, start, len(m)
        start += len(m)
