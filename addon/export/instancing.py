"""Object instances -> VolPath meshes: geometry shared by several instances, or moving during the
shutter, becomes one prototype in object space placed by per-instance transforms (Embree
instances), so memory grows with unique geometry, not with the instance count. Geometry used
once and static is placed in the world, as Cycles applies the static transform of a geometry
used by one object (scene/object.cpp ObjectManager::apply_static_transforms).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import volpath_native as vp

from . import geometry, validate


@dataclass
class _Group:
    name: str  # the first instance's name
    object_name: str
    local: geometry.LocalMesh
    slot_materials: np.ndarray
    matrices: list = field(default_factory=list)  # object -> world (4, 4) per instance
    motions: list = field(default_factory=list)  # per instance: [(4, 4)] * steps, or None (static)
    vertex_motion: np.ndarray | None = None  # (S, V, 3) object-space positions of a deforming mesh


class InstanceGroups:
    """Collects instances by what they share (triangulated geometry + materials + motion step
    count) and builds the meshes at the end."""

    def __init__(self, budget: validate.MemoryBudget):
        self.budget = budget
        self._groups: dict = {}
        self.instance_count = 0

    def add(self, share_key, name: str, object_name: str, local: geometry.LocalMesh, slot_materials: np.ndarray,
            matrix: np.ndarray, motion: list | None, vertex_motion: np.ndarray | None = None) -> None:
        """One instance. share_key identifies its triangulated geometry (None: never shared);
        motion: its matrix_world at its motion steps, None when it does not move; vertex_motion:
        (S, V, 3) object-space positions of a deforming mesh (its own group)."""
        if share_key is not None and vertex_motion is None:
            key = (share_key, tuple(int(i) for i in slot_materials))
        else:
            key = (id(local), name)
        group = self._groups.get(key)
        if group is None:
            group = self._groups[key] = _Group(name, object_name, local, slot_materials, vertex_motion=vertex_motion)
            self.budget.add(object_name, len(local.triangles))  # SceneError before the memory runs out
        else:
            self.budget.add(object_name, 0)
        self.instance_count += 1
        group.matrices.append(matrix)
        group.motions.append(motion)

    def meshes(self, reporter) -> list:
        out = []
        for group in (part for whole in self._groups.values() for part in _by_step_count(whole)):
            if len(group.matrices) == 1 and group.motions[0] is None and group.vertex_motion is None:
                mesh = geometry.to_world(group.name, group.local, group.matrices[0], group.slot_materials)
            else:
                mesh = _prototype(group)
            mesh = validate.finite_mesh(mesh, group.object_name, reporter)
            if mesh is not None:
                out.append(mesh)
        return out


def _by_step_count(group: _Group) -> list:
    """The group split so that its moving instances share one motion step count (a mesh's motion
    array has one); static instances stay with the first part."""
    counts = sorted({len(path) for path in group.motions if path is not None})
    if len(counts) <= 1:
        return [group]
    parts = {count: _Group(group.name, group.object_name, group.local, group.slot_materials) for count in counts}
    for matrix, path in zip(group.matrices, group.motions):
        part = parts[len(path) if path is not None else counts[0]]
        part.matrices.append(matrix)
        part.motions.append(path)
    return list(parts.values())


def _prototype(group: _Group) -> vp.Mesh:
    """The group's geometry in object space with its instances' transforms (and motion steps)."""
    local = group.local
    slots = np.clip(local.material_slots, 0, len(group.slot_materials) - 1)  # Blender clamps the index
    instances = np.stack([m[:3] for m in group.matrices]).astype(np.float64)
    motion = None
    if any(path is not None for path in group.motions):
        steps = max(len(path) for path in group.motions if path is not None)
        motion = np.stack([np.stack([m[:3] for m in path]) if path is not None else np.repeat(i[None], steps, axis=0)
                           for path, i in zip(group.motions, instances)]).astype(np.float64)
    frame = None
    if local.generated is not None:  # object space is the mesh's space: world -> object is per instance
        frame = np.stack([np.eye(4)[:3], local.generated])
    name = group.name if len(group.matrices) == 1 else f"{group.name} (x{len(group.matrices)})"
    return vp.Mesh(name=name, vertices=local.vertices, triangles=local.triangles,
                   material_ids=group.slot_materials[slots], corner_normals=local.corner_normals,
                   corner_attributes=dict(local.corner_attributes or {}), object_frame=frame,
                   instances=instances, motion=motion, vertex_motion=group.vertex_motion)
