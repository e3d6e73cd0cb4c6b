"""Volume materials whose nodes vary over space -> one ProgramMedium per object that uses them.

A material's program is compiled once (shading.MaterialTable); the medium also needs the object it
is evaluated on -- its transform (Texture Coordinate > Object), its texture space (Generated) and
its bounds (where Cycles evaluates the volume) -- so each (material, object instance) pair gets its
own medium and a copy of the material pointing at it.
"""
from __future__ import annotations

import numpy as np

import volpath_native as vp
from volpath_native.program_medium import ProgramMedium
from volpath_native.shading import program as P
from volpath_native.shading.images import empty_image_table
from volpath_native.shading.interpreter import run_program_many

from .motion import moving_volume_note


def generated_transform(obj, vertices: np.ndarray) -> np.ndarray:
    """3x4 object -> Generated map of a mesh: (P - L) / 2S + 0.5 with the evaluated data's texture
    space L, S (auto texture space = the bounds; Cycles' create_mesh stores this transform,
    intern/cycles/blender/mesh.cpp, and volume_normalized_position applies it)."""
    data = getattr(obj, "data", None)
    location = getattr(data, "texspace_location", None)
    size = getattr(data, "texspace_size", None)
    if location is None or size is None:
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        location, size = (lo + hi) / 2.0, (hi - lo) / 2.0
    location = np.asarray(location, dtype=np.float64)
    size = np.asarray(size, dtype=np.float64)
    size = np.where(np.abs(size) > 1e-12, size, 1.0)  # Blender keeps a flat texture space at 1
    out = np.zeros((3, 4))
    out[:, :3] = np.diag(1.0 / (2.0 * size))
    out[:, 3] = 0.5 - location / (2.0 * size)
    return out


def phase_of(program, frame: np.ndarray, points: np.ndarray, label: str, reporter, attributes=None,
             world_to_index=None) -> float:
    """The anisotropy of the program's scattering closures, read where they scatter among `points`
    (the medium's phase function is constant: a varying or mixed anisotropy is warned about)."""
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    regs = np.zeros(program.n_registers)
    out = np.zeros((len(points), P.MAX_LOBES * P.LOBE_STRIDE))
    attributes = np.zeros((1, 1, 1, 1), np.float32) if attributes is None else attributes
    world_to_index = np.zeros((3, 4)) if world_to_index is None else np.ascontiguousarray(world_to_index[:3])
    run_program_many(program.code, program.init, program.tables, regs, np.ascontiguousarray(frame), attributes,
                     world_to_index, points, out, P.R_LOBES, out.shape[1], empty_image_table())
    lobes = out.reshape(len(points), P.MAX_LOBES, P.LOBE_STRIDE)
    weights, gs = lobes[..., :3].mean(axis=2).ravel(), lobes[..., 3].ravel()
    used = weights > 0
    if not used.any():
        return 0.0
    mean = float(np.average(gs[used], weights=weights[used]))
    if np.ptp(gs[used]) > 1e-6:
        reporter.warn(f"{label}: the anisotropy of its volume varies over space or between its scattering "
                      f"shaders; rendered with the mean anisotropy {mean:.3g}")
    return mean


class ProceduralMedia:
    """Binds the varying volume programs of a MaterialTable to the objects using them."""

    def __init__(self, table):
        self.table = table
        self.programs: dict = {}  # material index -> ShaderProgram
        self._bound: dict = {}
        self.world_program = None  # a world volume that varies over space (world_medium_box)

    def bind(self, slot_materials: np.ndarray, obj, instance_name: str, matrix: np.ndarray,
             vertices: np.ndarray, motion=None, vertex_motion=None) -> np.ndarray:
        """slot_materials with each varying-volume material replaced by its copy for this object;
        motion: the object's matrix_world at its motion steps (its medium moves with it), or None;
        vertex_motion: (S, V, 3) object-space positions of a deforming mesh (the medium's box holds
        them all: Cycles evaluates the shader wherever the deformed boundary goes)."""
        if not self.programs or not any(int(i) in self.programs for i in slot_materials):
            return slot_materials
        out = slot_materials.copy()
        for k, index in enumerate(slot_materials):
            program = self.programs.get(int(index))
            if program is None:
                continue
            key = (int(index), instance_name, matrix.tobytes())
            if key not in self._bound:
                self._bound[key] = self._new_medium(int(index), program, obj, instance_name, matrix, vertices, motion,
                                                    vertex_motion)
            out[k] = self._bound[key]
        return out

    def _new_medium(self, index, program, obj, instance_name, matrix, vertices, motion=None, vertex_motion=None) -> int:
        table = self.table
        material = table.materials[index]
        label = f"{material.name} on '{instance_name}'"
        generated = generated_transform(obj, vertices)
        extent = vertices if vertex_motion is None else np.concatenate([vertices, vertex_motion.reshape(-1, 3)])
        lo, hi = extent.min(axis=0).astype(np.float64), extent.max(axis=0).astype(np.float64)
        world_to_object = np.linalg.inv(matrix)[:3]
        local = lo + (hi - lo) * np.random.default_rng(0).random((64, 3))
        g = phase_of(program, np.stack([world_to_object, generated]), local @ matrix[:3, :3].T + matrix[:3, 3],
                     f"material '{material.name}'", table.reporter)
        try:
            medium = ProgramMedium(label, program, matrix, (lo, hi), generated, g=g)
        except vp.SceneError as error:
            table.reporter.warn(f"material '{material.name}' on '{instance_name}': {error}; no medium")
            return index
        if motion is not None:
            try:
                medium.set_motion(motion)
                table.reporter.warn(moving_volume_note(f"material '{material.name}' on '{instance_name}'"))
            except vp.SceneError as error:  # e.g. scaled to nothing at a step
                table.reporter.warn(f"{error}; its shader is evaluated where the object is at the shutter centre")
        for message in medium.warnings():
            table.reporter.warn(message)
        table.media.append(medium)
        copy = vp.Material(name=label, surface=material.surface, base_color=material.base_color,
                           emission=material.emission, two_sided_emission=material.two_sided_emission,
                           medium=len(table.media) - 1, surface_nodes=[n.copy() for n in material.surface_nodes])
        table.materials.append(copy)
        return len(table.materials) - 1


#: Cycles bounds the world volume's octree by +-10 km (scene/volume.cpp, "World volume is unbounded,
#: use some practical large number instead").
CYCLES_WORLD_VOLUME_EXTENT = 10000.0
#: VolPath bounds it by the scene's extent grown by this factor around its centre (a box 10 km wide
#: would make the majorant cells and the ray offsets of a room-sized scene far too coarse).
WORLD_BOX_GROWTH = 3.0


def world_medium_box(procedural: ProceduralMedia, meshes: list, points: list, world_name: str) -> list:
    """A varying world volume as a ProgramMedium inside a null box around the scene (meshes, camera
    and light positions), grown WORLD_BOX_GROWTH times, at most Cycles' +-10 km; returns the box
    mesh to add. Rays leave the medium at the box (Cycles: at 10 km) -- a documented difference."""
    program = procedural.world_program
    if program is None:
        return []
    table = procedural.table
    corners = [np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in points]
    corners += [m.vertices.astype(np.float64) for m in meshes if len(m.vertices)]
    everything = np.concatenate(corners) if corners else np.zeros((1, 3))
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    centre, half = (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1.0) * WORLD_BOX_GROWTH
    lo = np.maximum(centre - half, -CYCLES_WORLD_VOLUME_EXTENT)
    hi = np.minimum(centre + half, CYCLES_WORLD_VOLUME_EXTENT)
    label = f"world '{world_name}'"
    identity = np.eye(4)
    samples = lo + (hi - lo) * np.random.default_rng(0).random((256, 3))
    g = phase_of(program, np.stack([identity[:3], identity[:3]]), samples, label, table.reporter)
    try:
        medium = ProgramMedium(label, program, identity, (lo, hi), identity[:3], g=g)
    except vp.SceneError as error:
        table.reporter.warn(f"{label}: {error}; no world volume")
        return []
    for message in medium.warnings():
        table.reporter.warn(message)
    table.reporter.warn(f"{label}: its volume varies over space; VolPath evaluates it inside a box around the "
                        f"scene ({(hi - lo).round(2).tolist()} m), Cycles up to 10 km away")
    table.media.append(medium)
    table.materials.append(vp.Material(name=f"{label} (volume bounds)", surface="null", base_color=np.zeros(3),
                                       medium=len(table.media) - 1))
    return [medium.box_mesh(len(table.materials) - 1)]
