"""Ray queries against all triangles of a scene through Embree, in bulk.

One Embree scene holds every non-degenerate triangle, world-space ones directly and instanced
meshes once each, placed by Embree instances; per-triangle tables (material, geometric normal,
area, owning mesh) are indexed by the triangle id a hit reports. The queries are compiled loops
over Embree's own library (embree/: shared buffers, no copies) that release the GIL, so several
threads trace at once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .embree import TriangleScene
from .embree import library as embree_library
from .instance_motion import motion_table
from .scene import Mesh, doubled_areas, padded_rows
from .triangle_geometry import corner_bounds

MISS = -1
NO_INSTANCE = -1
#: Embree geometry masks (Accelerator(see_through=...)): geometry no shadow ray passes, and null
#: boundaries / possibly transparent surfaces, which shadow rays cross. A shadow ray first asks
#: whether anything opaque lies on it (one occlusion query with MASK_OPAQUE) and only the rays it
#: does not find blocked step through the boundaries with closest hits of MASK_SEE_THROUGH: Cycles
#: likewise finds a shadow ray's transparent hits in one any-hit traversal that stops at the first
#: opaque one (kernel/bvh/shadow_all.h) instead of one traversal per crossed boundary.
MASK_OPAQUE = np.uint32(1)
MASK_SEE_THROUGH = np.uint32(2)
ALL_MASK = np.uint32(0xFFFFFFFF)
#: static world triangles form one Embree geometry per run of triangles of one class; more runs
#: than this (materials alternating face by face) keep one geometry, masked see-through when any
#: of its triangles is (the opaque query then skips it: conservative, only slower)
MAX_MASK_RUNS = 256


@dataclass
class Hits:
    t: np.ndarray        # (N,) float64 hit distance, inf on a miss
    prim: np.ndarray     # (N,) int32 triangle index, MISS (-1) on a miss
    u: np.ndarray        # (N,) float32 barycentric of vertex 1
    v: np.ndarray        # (N,) float32 barycentric of vertex 2
    inst: np.ndarray = None  # (N,) int32 instance of the hit, NO_INSTANCE (-1) for world triangles


class Accelerator:
    """All triangles of the scene and an Embree BVH over them.

    Per triangle it keeps: vertex indices (int32), material and mesh ids (int32), the geometric
    normal (float64 x3; the meshes' own, Mesh.triangle_normals) and, for smooth meshes, corner
    normals (float32 x9; a single mesh's own table, not a copy); areas (float64) and the float64
    corner positions (`corners`, 72 bytes a triangle) only when asked for (mesh lights).

    Instanced meshes (Mesh.instances) keep their triangles once, in object space, after the
    world-space ones (triangle ids >= world_triangle_count); Embree instances them and a hit
    reports the prototype's triangle and the instance (Hits.inst). Per instance: object -> world
    (instance_transforms), the normal map n_world ~ instance_normals[k] @ n_object (the inverse
    transpose: an outward normal stays outward, on mirrored instances too, where the winding of
    the placed corners flips -- Cycles flips that cross product for negative scale) and its row in
    mesh_frames(). Instanced
    meshes whose materials emit or bound a medium are traced as world copies instead (the light
    table and the volume stacks index world triangles); moving ones as deforming world meshes
    whose vertex steps follow the interpolated transform."""

    def __init__(self, meshes: list[Mesh], materials: list | None = None, camera_samples: int | None = None,
                 see_through=None):
        """camera_samples: pixels x samples the render will trace, which picks Embree's build
        quality (build_quality); None: Cycles' MEDIUM. see_through: per material, whether shadow
        rays may cross its surfaces (null boundaries, transparency): the geometry is then masked by
        class (MASK_OPAQUE / MASK_SEE_THROUGH, `masked` True); None: every geometry in ALL_MASK."""
        world, prototypes = [], []
        self.warnings: list[str] = []
        self._copy_motion = {}  # id(world copy of a moving instance) -> (its frame's transform, its steps)
        for mesh in meshes:
            if mesh.instances is None:
                world.append(mesh)
            elif _must_flatten(mesh, materials):
                copies = mesh.world_copies()  # a moving one as deforming copies (instance_motion.placed_motion)
                if mesh.motion is not None:  # world_copies skips the singular instances
                    usable = np.nonzero(np.abs(np.linalg.det(mesh.instances[:, :, :3])) > 1e-30)[0]
                    self._copy_motion.update({id(copy): (mesh.instances[k], mesh.motion[k])
                                              for copy, k in zip(copies, usable)})
                world += copies
            else:
                prototypes.append(mesh)
        # static world meshes share one Embree geometry; deforming ones get their own (time steps)
        meshes = [m for m in world if m.vertex_motion is None] + [m for m in world if m.vertex_motion is not None] \
            + prototypes
        verts, tris, mats, mesh_ids, normals, kept_meshes = [], [], [], [], [], []
        base = 0
        for mesh_index, mesh in enumerate(meshes):
            t = mesh.triangles
            if len(t):
                mesh_normals, doubled_areas = mesh.triangle_normals()  # computed by Scene.validate
                mesh.release_triangle_normals()  # ours now: the mesh keeps no second copy
                keep = doubled_areas > 1e-20  # degenerate ones dropped (Scene.validate warns)
                everything = bool(keep.all())
                kept = t if everything else t[keep]
                verts.append(mesh.vertices)
                tris.append(kept + base if base else kept)
                mats.append(mesh.material_ids if everything else mesh.material_ids[keep])
                mesh_ids.append(np.full(len(tris[-1]), mesh_index, dtype=np.int32))
                normals.append(mesh_normals if everything else mesh_normals[keep])
                kept_meshes.append((mesh, None if everything else keep))
            base += len(mesh.vertices)
        self.has_smooth = any(mesh.corner_normals is not None for mesh, _ in kept_meshes)
        if tris:
            self.vertices = padded_rows(_joined(verts, np.float32))  # Embree reads it in place
            self.triangles = _joined(tris, np.int32)
            self.material_ids = _joined(mats, np.int32)
            self.mesh_ids = _joined(mesh_ids, np.int32)
            # outward for CCW triangles (object space for prototypes): the vertices are the
            # meshes' own float32 ones, so their normals are the same numbers
            self.normals = _joined(normals, np.float64)
        else:
            self.vertices = np.zeros((0, 3), np.float32)
            self.triangles = np.zeros((0, 3), np.int32)
            self.material_ids = np.zeros(0, np.int32)
            self.mesh_ids = np.zeros(0, np.int32)
            self.normals = np.zeros((0, 3))
        del normals
        n = len(self.triangles)
        self._areas = None
        if self.has_smooth:
            only = kept_meshes[0][0] if len(kept_meshes) == 1 and kept_meshes[0][1] is None else None
            if only is not None:  # one mesh, every triangle kept: its own table, not a copy
                self.corner_normals = only.corner_normals
            else:
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
        self._meshes = list(meshes)  # per-corner attributes and frames (surface programs)
        self._kept = kept_meshes
        self.world_triangle_count = sum(len(t) for t, (mesh, _) in zip(tris, kept_meshes) if mesh.instances is None)
        self._deformation_tables(tris, kept_meshes)
        self._place_instances(prototypes, tris, kept_meshes)
        lo, hi = self._world_bounds()
        self.bounds = (lo, hi)
        # Ray offset scale: relative to the scene extent, so it works in mm and km scenes.
        self.epsilon = 1e-5 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
        self._corners = None
        self._embree = None
        self.build_quality = build_quality(n, camera_samples)
        self.masked = see_through is not None
        see_through = np.asarray(see_through if see_through is not None else [], bool)
        self._see_through = (see_through[self.material_ids] if len(see_through) and n
                             else np.zeros(n, bool))  # per triangle (materials as scene_tables reads them)
        if n:
            # Embree reads self.vertices / self.triangles in place (they live as long as self):
            # the world triangles in the top scene, each prototype's range in a scene of its own
            # (a deforming mesh: its own vertex steps and triangles, Cycles bvh/embree.cpp add_triangles)
            self._embree = TriangleScene(self.build_quality)
            deforming = {first: (mesh, keep) for first, (mesh, keep) in self._deforming.items()}
            static = min([self.world_triangle_count] + [f for f in deforming if f < self.world_triangle_count])
            for start, end, mask in self._mask_runs(0, static):
                self._embree.add_triangles(self.vertices, self.triangles[start:end], start, mask)
            for first, (mesh, keep) in deforming.items():
                if first < self.world_triangle_count:
                    kept = _kept(mesh.triangles, keep)
                    self._embree.add_triangles(list(mesh.vertex_motion), kept, first,
                                               self._class_mask(first, first + len(kept)))
            for first, count, placements in self._prototype_ranges:
                prototype = TriangleScene(self.build_quality)
                if first in deforming:
                    mesh, keep = deforming[first]
                    prototype.add_triangles(list(mesh.vertex_motion), _kept(mesh.triangles, keep), 0)
                else:
                    prototype.add_triangles(self.vertices, self.triangles[first:first + count], 0)
                prototype.commit()
                for steps in placements:
                    self._embree.add_instance(prototype, steps, first, self._class_mask(first, first + count))
            self._embree.commit()

    def _class_mask(self, start: int, end: int) -> int:
        """The Embree mask of a geometry holding triangles [start, end): see-through if any is."""
        if not self.masked:
            return int(ALL_MASK)
        return int(MASK_SEE_THROUGH if self._see_through[start:end].any() else MASK_OPAQUE)

    def _mask_runs(self, start: int, end: int) -> list:
        """[(start, end, mask)]: triangles [start, end) split into runs of one class (MAX_MASK_RUNS)."""
        if end <= start:
            return []
        cuts = np.nonzero(np.diff(self._see_through[start:end].astype(np.int8)))[0] + 1 + start if self.masked else []
        if len(cuts) >= MAX_MASK_RUNS:
            cuts = []
        bounds = [start, *map(int, cuts), end]
        return [(a, b, self._class_mask(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]

    def _deformation_tables(self, tris: list, kept_meshes: list):
        """Deforming meshes (Mesh.vertex_motion): per triangle [first row, steps, stride, has
        normal steps] into deform_corners (rows of (3, 3) float32 corner positions: row first + s *
        stride at step s) and deform_normals (the corner normals' steps, same rows), for the
        stages' normals at a ray's time (Cycles geom/motion_triangle.h: vertices and normals
        interpolated linearly between the two steps around the time)."""
        self._deforming = {}
        rows, corners, normals, start, row = [], [], [], 0, 0
        for t, (mesh, keep) in zip(tris, kept_meshes):
            if mesh.vertex_motion is not None:
                self._deforming[start] = (mesh, keep)
                local = _kept(mesh.triangles, keep)
                steps = len(mesh.vertex_motion)
                with_normals = mesh.corner_normal_motion is not None
                rows.append((start, len(t), row, steps, len(t), int(with_normals)))
                for s in range(steps):
                    corners.append(mesh.vertex_motion[s][local])
                    normals.append(_kept(mesh.corner_normal_motion[s], keep) if with_normals
                                   else np.zeros((len(t), 3, 3), np.float32))
                row += steps * len(t)
            start += len(t)
        self.has_deformation = bool(rows)
        self.deform_rows = np.full((self.triangle_count if rows else 1, 4), -1, np.int64)
        for first, count, row0, steps, stride, with_normals in rows:
            self.deform_rows[first:first + count, 0] = row0 + np.arange(count)
            self.deform_rows[first:first + count, 1:] = (steps, stride, with_normals)
        self.deform_corners = np.ascontiguousarray(np.concatenate(corners) if rows else np.zeros((1, 3, 3)),
                                                   dtype=np.float32)
        self.deform_normals = np.ascontiguousarray(np.concatenate(normals) if rows else np.zeros((1, 3, 3)),
                                                   dtype=np.float32)

    def _place_instances(self, prototypes: list, tris: list, kept_meshes: list):
        """Per-instance tables, in the order Embree numbers the instances."""
        first = self.world_triangle_count
        ranges, transforms, frame_rows, placements = [], [], [], []
        counts = {id(mesh): len(t) for t, (mesh, _) in zip(tris, kept_meshes)}
        for mesh in prototypes:
            count = counts.get(id(mesh), 0)
            usable = np.nonzero(np.abs(np.linalg.det(mesh.instances[:, :, :3])) > 1e-30)[0]  # validate() warns
            if count and len(usable):
                steps = [mesh.motion[k] if mesh.motion is not None else mesh.instances[k][None] for k in usable]
                ranges.append((first, count, steps))
                placements += steps
                transforms += [mesh.instances[k] for k in usable]
                mesh_index = next(i for i, m in enumerate(self._meshes) if m is mesh)
                frame_rows.append((mesh_index, usable))
            first += count
        self._prototype_ranges = ranges
        self._instance_frames = frame_rows
        self._placements = placements
        self.instance_count = len(transforms)
        self.instance_transforms = np.ascontiguousarray(np.reshape(transforms, (-1, 3, 4)), dtype=np.float64)
        normals = np.zeros((max(self.instance_count, 1), 3, 3))
        if self.instance_count:  # batched: one LAPACK call per instance is slow (ms each)
            linear = self.instance_transforms[:, :, :3]
            normals[:] = np.linalg.inv(linear).transpose(0, 2, 1)
        self.instance_normals = normals
        # moving instances: decomposed steps per instance (instance_motion.py)
        self.instance_steps, self.instance_motion = motion_table(placements)
        self.has_motion = bool(np.any(self.instance_steps > 1)) or self.has_deformation

    def _world_bounds(self):
        """World-space bounds of the world triangles and of every instance's box corners (at
        every motion step)."""
        n_world = self.world_triangle_count
        points = []
        if n_world:
            points.append(np.stack(corner_bounds(self.vertices, self.triangles[:n_world])))
        for first, count, placements in self._prototype_ranges:
            lo, hi = corner_bounds(self.vertices, self.triangles[first:first + count])
            box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            steps = np.concatenate(placements)
            points.append(np.einsum("sij,bj->sbi", steps[:, :, :3], box).reshape(-1, 3)
                          + np.repeat(steps[:, :, 3], len(box), axis=0))
        if not points:
            return np.zeros(3), np.zeros(3)
        points = np.concatenate(points)
        return points.min(axis=0), points.max(axis=0)

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
        """(n_meshes + instance_count, 2, 3, 4) world -> object and object -> Generated maps per
        mesh (Mesh.frame), then per instance (its mesh's frame after world -> prototype): a hit's
        row is mesh_ids[prim], or instance_frame_base + instance for an instanced hit."""
        if not self._meshes:
            return np.zeros((1, 2, 3, 4))
        frames = [m.frame() for m in self._meshes]
        placed = [_instance_frames(frames[mesh_index], self._meshes[mesh_index].instances[ks])
                  for mesh_index, ks in self._instance_frames]
        return np.ascontiguousarray(np.concatenate([np.stack(frames)] + placed), dtype=np.float64)

    def frame_motion(self) -> tuple:
        """For the rows of mesh_frames(): (steps (R,) int64, decomposed steps (R, S, 16) as
        instance_motion.motion_table, (R, 3, 4) the object -> world each row's frame was made
        with). Rows of moving instances and of world copies of moving instances have steps > 1:
        their world -> object at a ray's time is the row's frame o placed o M(t)^-1 (Cycles reads a
        moving object's inverse transform at the shutter time: kernel/geom/object.h
        object_fetch_transform_motion_test, used for Texture Coordinate Object)."""
        placed, steps = [], []
        for mesh in self._meshes or [None]:
            transform, path = self._copy_motion.get(id(mesh), (np.eye(4)[:3], None))
            placed.append(transform)
            steps.append(path if path is not None else transform[None])
        placed += [self.instance_transforms[k] for k in range(self.instance_count)]
        steps += list(self._placements)
        counts, table = motion_table(steps)
        return counts, table, np.ascontiguousarray(np.reshape(placed, (-1, 3, 4)), dtype=np.float64)

    @property
    def instance_frame_base(self) -> int:
        """Row of instance 0 in mesh_frames()."""
        return len(self._meshes)

    def triangle_corners(self, index) -> np.ndarray:
        """(k, 3, 3) float64 corner positions of the triangles `index` (object space for
        prototypes' triangles)."""
        return self.vertices[self.triangles[index]].astype(np.float64)

    @property
    def corners(self) -> np.ndarray:
        """(T, 3, 3) float64 corner positions of every triangle (computed on first use: 72 bytes a
        triangle, only mesh lights need them all)."""
        if self._corners is None:
            self._corners = self.triangle_corners(slice(None))
        return self._corners

    @property
    def areas(self) -> np.ndarray:
        """(T,) float64 triangle areas (computed on first use: only mesh lights read them)."""
        if self._areas is None:
            self._areas = 0.5 * doubled_areas(self.vertices, self.triangles)
        return self._areas

    @property
    def triangle_count(self) -> int:
        return len(self.triangles)

    def intersect(self, origins: np.ndarray, directions: np.ndarray, tmax=None) -> Hits:
        """Closest hit of each ray (origins, unit directions (N,3)) within (0, tmax]."""
        n = len(origins)
        if self._embree is None or n == 0:
            return Hits(np.full(n, np.inf), np.full(n, MISS, np.int32), np.zeros(n, np.float32),
                        np.zeros(n, np.float32), np.full(n, NO_INSTANCE, np.int32))
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        t32 = np.full(n, 1e37, np.float32)
        if tmax is not None:
            t32[:] = np.minimum(tmax, 1e30)
        t, prim, inst, u, v = self._embree.intersect(o, d, t32)
        t = t.astype(np.float64)
        t[prim < 0] = np.inf
        return Hits(t, prim, u, v, inst)

    def intersect_at(self, origins: np.ndarray, directions: np.ndarray, times: np.ndarray) -> Hits:
        """Closest hit of each ray (origins, unit directions (N,3)) at its shutter time in [0, 1]."""
        n = len(origins)
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        hits = self.intersect_raw(o, d, np.full(n, 1e37, np.float32), np.ascontiguousarray(times, np.float32))
        t = hits.t.astype(np.float64)
        t[hits.prim < 0] = np.inf
        return Hits(t, hits.prim, hits.u, hits.v, hits.inst)

    def corners_at(self, prim: np.ndarray, times: np.ndarray) -> np.ndarray:
        """(k, 3, 3) float64 corners of triangles `prim` at shutter times (deforming ones
        interpolated between their steps, motion_triangles.deform_step; others their frame's)."""
        corners = self.triangle_corners(prim)
        if not self.has_deformation:
            return corners
        rows = self.deform_rows[prim]
        moving = rows[:, 0] >= 0
        if np.any(moving):
            row, steps, stride = rows[moving, 0], rows[moving, 1], rows[moving, 2]
            time = np.asarray(times, np.float64).reshape(-1)[moving] if np.ndim(times) else np.full(len(row), times)
            step = np.clip((time * (steps - 1)).astype(np.int64), 0, steps - 2)
            t = np.clip(time * (steps - 1) - step, 0.0, 1.0)[:, None, None]
            a, b = row + step * stride, row + (step + 1) * stride
            corners[moving] = (1.0 - t) * self.deform_corners[a] + t * self.deform_corners[b]
        return corners

    def normals_at(self, prim: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Outward unit geometric normals of world triangles `prim` at shutter times."""
        c = self.corners_at(prim, times)
        return _unit(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]))

    def swept_bounds(self, prim: np.ndarray, low: np.ndarray, high: np.ndarray) -> tuple:
        """(low, high) per triangle widened by its corners at every deformation step."""
        low, high = low.copy(), high.copy()
        rows = self.deform_rows[prim]
        for i in np.nonzero(rows[:, 0] >= 0)[0]:
            row, steps, stride = rows[i, :3]
            c = self.deform_corners[row + stride * np.arange(steps)].reshape(-1, 3)
            low[i], high[i] = np.minimum(low[i], c.min(axis=0)), np.maximum(high[i], c.max(axis=0))
        return low, high

    def intersect_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray, times=None, mask=ALL_MASK) -> Hits:
        """Closest hits for contiguous float32 rays as the compiled stages use them: t is Embree's
        float32 tfar (meaningless on a miss: check prim >= 0), no conversions. times: the rays'
        shutter times in [0, 1] (None: 0; only moving geometry reads them); mask: the geometry
        classes the rays see (MASK_*)."""
        n = len(o32)
        if self._embree is None or n == 0:
            return Hits(t32.copy(), np.full(n, MISS, np.int32), np.zeros(n, np.float32), np.zeros(n, np.float32),
                        np.full(n, NO_INSTANCE, np.int32))
        t, prim, inst, u, v = self._embree.intersect(o32, d32, t32, times, mask)
        return Hits(t, prim, u, v, inst)

    @property
    def embree(self):
        """The Embree scene (embree.TriangleScene), None when there are no triangles."""
        return self._embree

    def occluded_raw(self, o32: np.ndarray, d32: np.ndarray, t32: np.ndarray, times=None, mask=ALL_MASK) -> np.ndarray:
        """True where geometry of the `mask` classes blocks the contiguous float32 ray before t32
        (at `times`)."""
        if self._embree is None or len(o32) == 0:
            return np.zeros(len(o32), dtype=bool)
        return self._embree.occluded(o32, d32, t32, times, mask)

    def geometric_normals(self, prim: np.ndarray, inst=None) -> np.ndarray:
        """Outward unit geometric normals of hits, in world space."""
        return _unit(self._placed(self.normals[prim], inst))

    def shading_normals(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray, inst=None) -> np.ndarray:
        """Interpolated smooth normals where the mesh has them, else geometric normals (world
        space: instanced hits through their instance's normal map)."""
        if not self.has_smooth:
            return self.geometric_normals(prim, inst)
        c = self.corner_normals[prim]
        w0 = (1.0 - u - v)[:, None]
        n = c[:, 0] * w0 + c[:, 1] * u[:, None] + c[:, 2] * v[:, None]
        return _unit(self._placed(n, inst))

    def _placed(self, normals: np.ndarray, inst) -> np.ndarray:
        if inst is None or not self.instance_count:
            return normals
        normals = np.array(normals, dtype=np.float64)
        placed = inst >= 0
        normals[placed] = np.einsum("kij,kj->ki", self.instance_normals[inst[placed]], normals[placed])
        return normals


# Below this many camera samples per triangle, Embree's LOW build quality (a Morton-code BVH) is
# used: measured on a 1M-triangle Suzanne (2-core VM), it builds in ~0.3x MEDIUM's time and traces
# ~1.2x slower (the same hits, bit for bit; tests/native/test_accel_quality.py), so MEDIUM's
# extra build time (~1 us a triangle) pays off only after some 10-30 rays a triangle -- a few per
# camera sample.
LOW_QUALITY_SAMPLES_PER_TRIANGLE = 4


def build_quality(triangles: int, camera_samples: int | None) -> int:
    """Embree build quality for a render of `camera_samples` (pixels x samples) over `triangles`:
    Cycles' MEDIUM (bvh/embree.cpp BVHEmbree::build, static scenes), or LOW when the render traces
    too few rays for MEDIUM's slower build to pay off (a big mesh at a low sample count, where
    Cycles spends most of its time building too)."""
    if camera_samples is not None and camera_samples < LOW_QUALITY_SAMPLES_PER_TRIANGLE * triangles:
        return embree_library.BUILD_QUALITY_LOW
    return embree_library.BUILD_QUALITY_MEDIUM


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-30)[:, None]


def _must_flatten(mesh: Mesh, materials) -> bool:
    """Instanced meshes traced as world copies: emitters (the light table samples world
    triangles), medium boundaries (volume stacks walk world triangles) and Bump nodes (the bump
    offsets move barycentrics over world-space corners, surface_programs._bump_inputs)."""
    if materials is None or not len(mesh.material_ids):
        return False
    used = np.unique(mesh.material_ids)
    return any(materials[i].is_emissive or materials[i].medium >= 0 or _has_bump(materials[i])
               for i in used if 0 <= i < len(materials))


def _has_bump(material) -> bool:
    program = getattr(material, "surface_program", None)
    return program is not None and int(program.bump_offsets) >= 0


def _instance_frames(frame: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """(K, 2, 3, 4): a mesh frame seen from world space through K object -> world instance
    transforms: world -> object = (prototype -> object frame) o (world -> prototype)."""
    inverse = np.linalg.inv(transforms[:, :, :3])
    placed = np.repeat(np.asarray(frame, np.float64)[None], len(transforms), axis=0)
    placed[:, 0, :, :3] = frame[0, :, :3] @ inverse
    placed[:, 0, :, 3] = frame[0, :, 3] - np.einsum("kij,kj->ki", placed[:, 0, :, :3], transforms[:, :, 3])
    return placed


def _kept(values: np.ndarray, keep) -> np.ndarray:
    return values if keep is None else values[keep]


def _joined(arrays: list, dtype) -> np.ndarray:
    """One contiguous array of the parts (no copy when there is one part of the right type)."""
    if len(arrays) == 1:
        return np.ascontiguousarray(arrays[0], dtype=dtype)
    return np.concatenate(arrays).astype(dtype, copy=False)
