"""Embree scenes built over the renderer's own arrays (shared buffers: nothing is copied but what
Embree's BVH itself stores), with instances of prototype scenes and motion time steps."""
from __future__ import annotations

import weakref

import numpy as np

from ..scene import padded_rows
from . import library as lib
from .queries import ALL_MASK, intersect_rays, new_rayhit, occluded_rays

# Build quality: MEDIUM, as Cycles for static scenes (bvh/embree.cpp: HIGH only with spatial
# splits, LOW for dynamic scenes); robust triangle tests (Cycles sets RTC_SCENE_FLAG_ROBUST too,
# and so does embreex: the same hits as before this binding).


class EmbreeError(RuntimeError):
    pass


_device = None


def device():
    """The process's Embree device (created on first use)."""
    global _device
    if _device is None:
        _device = lib.api.NewDevice(None)
        if not _device:
            raise EmbreeError("rtcNewDevice failed")
    return _device


def _check(what: str):
    code = lib.api.GetDeviceError(device())
    if code:
        message = lib.api.GetDeviceLastErrorMessage(device())
        raise EmbreeError(f"Embree: {what}: error {code}: {(message or b'').decode(errors='replace')}")


def _triangle_geometry(vertex_steps: list, triangles: np.ndarray, quality: int, mask: int):
    """A triangle geometry over shared buffers: one vertex buffer per time step."""
    geometry = lib.api.NewGeometry(device(), lib.GEOMETRY_TYPE_TRIANGLE)
    lib.api.SetGeometryMask(geometry, mask)
    if len(vertex_steps) > 1:
        lib.api.SetGeometryTimeStepCount(geometry, len(vertex_steps))
    for slot, vertices in enumerate(vertex_steps):
        lib.api.SetSharedGeometryBuffer(geometry, lib.BUFFER_TYPE_VERTEX, slot, lib.FORMAT_FLOAT3,
                                        vertices.ctypes.data, 0, 12, len(vertices))
    lib.api.SetSharedGeometryBuffer(geometry, lib.BUFFER_TYPE_INDEX, 0, lib.FORMAT_UINT3, triangles.ctypes.data,
                                    0, 12, len(triangles))
    lib.api.SetGeometryBuildQuality(geometry, quality)
    lib.api.CommitGeometry(geometry)
    _check("triangle geometry")
    return geometry


class _Handle:
    """An RTCScene released when its owner goes (weakref.finalize keeps no reference cycle)."""

    def __init__(self, owner, scene):
        self.scene = scene
        weakref.finalize(owner, lib.api.ReleaseScene, scene)


class TriangleScene:
    """World-space triangle geometries, each over caller-owned arrays that must outlive the scene
    (this object keeps references), plus instances of prototype TriangleScenes.

    add_triangles(vertices (or a list of S per-step vertex arrays), triangles, first) attaches a
    geometry whose primitive i is reported as triangle first + i; add_instance(prototype,
    transforms (S, 3, 4), first) one instance whose hits report first + the prototype's triangle
    and the instance's number (0, 1, ... in the order added); `mask` is the geometry's Embree mask
    (a ray sees it when their masks share a bit). commit() builds the BVH; intersect / occluded
    query contiguous float32 rays."""

    def __init__(self, quality: int = lib.BUILD_QUALITY_MEDIUM, flags: int = lib.SCENE_FLAG_ROBUST):
        self._scene = lib.api.NewScene(device())
        self._handle = _Handle(self, self._scene)
        lib.api.SetSceneFlags(self._scene, flags)
        lib.api.SetSceneBuildQuality(self._scene, quality)
        self.quality = quality
        self._keep = []  # buffers Embree reads
        self._geom_base, self._inst_base, self._inst_index = [], [], []
        self.instance_count = 0
        self.committed = False

    def add_triangles(self, vertices, triangles: np.ndarray, first: int, mask: int = int(ALL_MASK)) -> int:
        steps = vertices if isinstance(vertices, (list, tuple)) else [vertices]
        steps = [padded_rows(v) for v in steps]
        triangles = np.ascontiguousarray(triangles, dtype=np.int32).reshape(-1, 3).view(np.uint32)
        geometry = _triangle_geometry(steps, triangles, self.quality, mask)
        geom_id = lib.api.AttachGeometry(self._scene, geometry)
        lib.api.ReleaseGeometry(geometry)  # the scene holds it
        _check("attach")
        self._keep += steps + [triangles]
        self._set(self._geom_base, geom_id, first)
        return geom_id

    def add_instance(self, prototype: "TriangleScene", transforms: np.ndarray, first: int,
                     mask: int = int(ALL_MASK)) -> int:
        """An instance of `prototype` (committed) with object -> world transforms (S, 3, 4) at S
        equally spaced times over [0, 1] (S = 1: static). Motion is interpolated decomposed
        (rtcSetGeometryTransformQuaternion, as Cycles' bvh/embree.cpp add_instance)."""
        transforms = np.asarray(transforms, np.float64).reshape(-1, 3, 4)
        geometry = lib.api.NewGeometry(device(), lib.GEOMETRY_TYPE_INSTANCE)
        lib.api.SetGeometryMask(geometry, mask)
        lib.api.SetGeometryInstancedScene(geometry, prototype._scene)
        if len(transforms) == 1:
            matrix = np.ascontiguousarray(transforms[0], np.float32)
            lib.api.SetGeometryTransform(geometry, 0, lib.FORMAT_FLOAT3X4_ROW_MAJOR, matrix.ctypes.data)
        else:
            from .motion import quaternion_decompositions
            lib.api.SetGeometryTimeStepCount(geometry, len(transforms))
            for step, decomposition in enumerate(quaternion_decompositions(transforms)):
                lib.api.SetGeometryTransformQuaternion(geometry, step, decomposition)
        lib.api.CommitGeometry(geometry)
        geom_id = lib.api.AttachGeometry(self._scene, geometry)
        lib.api.ReleaseGeometry(geometry)
        _check("instance")
        self._keep.append(prototype)
        self._set(self._inst_base, geom_id, first)
        self._set(self._inst_index, geom_id, self.instance_count)
        self.instance_count += 1
        return geom_id

    @staticmethod
    def _set(table: list, index: int, value: int):
        table.extend([0] * (index + 1 - len(table)))
        table[index] = value

    def commit(self):
        lib.api.CommitScene(self._scene)
        _check("commit")
        self.geom_base = np.asarray(self._geom_base or [0], np.int32)
        self.inst_base = np.asarray(self._inst_base or [0], np.int32)
        self.inst_index = np.asarray(self._inst_index or [0], np.int32)
        self.committed = True
        return self

    @property
    def handle(self) -> int:
        """The RTCScene, for compiled queries (embree/queries.py)."""
        return self._scene

    def intersect(self, o32, d32, t32, times=None, mask=ALL_MASK):
        """(t, prim, instance, u, v) of the closest hits among the geometries whose mask shares a
        bit with `mask`: t = t32 on a miss, prim -1 on a miss."""
        n = len(o32)
        t = np.empty(n, np.float32)
        prim, inst = np.empty(n, np.int32), np.empty(n, np.int32)
        u, v = np.zeros(n, np.float32), np.zeros(n, np.float32)
        intersect_rays(self._scene, new_rayhit(), o32, d32, t32, _times(times), self.geom_base, self.inst_base,
                       self.inst_index, t, prim, inst, u, v, np.uint32(mask))
        return t, prim, inst, u, v

    def occluded(self, o32, d32, t32, times=None, mask=ALL_MASK) -> np.ndarray:
        blocked = np.empty(len(o32), bool)
        occluded_rays(self._scene, new_rayhit(), o32, d32, t32, _times(times), blocked, np.uint32(mask))
        return blocked


_NO_TIMES = np.zeros(0, np.float32)


def _times(times):
    return _NO_TIMES if times is None else np.ascontiguousarray(times, dtype=np.float32)
