"""Evaluated geometry -> world-space VolPath meshes, all array work in numpy.

Each distinct evaluated mesh is triangulated once (loop triangles / foreach_get) and then
transformed per instance, so instancing costs one matrix product per copy.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

import volpath_native as vp

from .. import compat

# Object types that evaluate to a mesh (Object.to_mesh supports them).
GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "FONT", "META"})


@dataclass
class LocalMesh:
    """A triangulated mesh in object space; material_slots are the slot indices per triangle."""

    vertices: np.ndarray  # (V, 3) float32
    triangles: np.ndarray  # (T, 3) int32
    material_slots: np.ndarray  # (T,) int32
    corner_normals: Optional[np.ndarray]  # (T, 3, 3) float32 or None (flat)
    corner_attributes: dict = None  # name -> (T, 3, k) float32, object space (corner_attributes.py)
    generated: Optional[np.ndarray] = None  # (3, 4) object -> Generated texture space


def triangulate(obj, requests=frozenset(), reporter=None) -> Optional[LocalMesh]:
    """The evaluated object's geometry as triangles (None when it has none). Every array is read
    with one foreach_get into a preallocated array (compat: attribute block copies where Blender
    has them; the triangles' corners from Blender's own array, compat.triangle_corners).
    `requests` names the per-corner attributes surface programs read (volpath_native.surface_programs)."""
    mesh, temporary = _evaluated_mesh(obj, requests)
    try:
        if mesh is None:
            return None
        mesh.calc_loop_triangles()
        n_tri = len(mesh.loop_triangles)
        if n_tri == 0:
            return None
        tri_loops = compat.triangle_corners(mesh, n_tri)
        corner_vertices = compat.corner_vertices(mesh)
        triangles = corner_vertices[tri_loops].reshape(-1, 3)
        tri_faces = compat.triangle_faces(mesh, n_tri)
        material_slots = compat.face_material_indices(mesh)[tri_faces]
        smooth = compat.face_smooth(mesh)
        corner_normals = None
        if smooth.any() or mesh.has_custom_normals:
            # Corner normals hold the face normal on flat faces (and sharp edges where Cycles splits).
            corner_normals = compat.triangle_corner_normals(mesh, smooth, tri_loops, tri_faces, triangles)
        positions = compat.mesh_positions(mesh)
        attributes = {}
        if requests:
            from .corner_attributes import corner_attribute_arrays
            attributes = corner_attribute_arrays(obj, mesh, requests, reporter, tri_loops, tri_faces, corner_vertices)
        from .procedural_media import generated_transform
        generated = np.asarray(generated_transform(obj, positions), np.float64).reshape(3, 4)
        return LocalMesh(positions, triangles, material_slots, corner_normals, attributes, generated)
    finally:
        if temporary:
            obj.to_mesh_clear()


def _evaluated_mesh(obj, requests):
    """(mesh, temporary): a mesh object's evaluated data itself, read in place as Cycles reads it
    (blender/util.h object_to_mesh copies only for edit mode and subdivision) -- its normals and
    loop triangles are cached there, where Object.to_mesh's copy computes them again; a temporary
    to_mesh copy for other object types, meshes in edit mode, tangents (Mesh.calc_tangents writes
    to the mesh) and Blender < 4.1 (split normals are written to the mesh)."""
    data = obj.data if obj.type == "MESH" else None
    if data is not None and compat.BLENDER_VERSION >= (4, 1, 0) and not data.is_editmode \
            and not any(name.startswith("tangent:") for name in requests):
        return data, False
    return obj.to_mesh(), True


def to_world(name: str, local: LocalMesh, matrix_world: np.ndarray, slot_materials: np.ndarray) -> vp.Mesh:
    """Place a LocalMesh in the world; slot_materials maps slot index -> Scene.materials index."""
    linear = matrix_world[:3, :3]
    if np.array_equal(matrix_world, np.eye(4)):
        vertices = _identity_placed(local.vertices)
    else:
        vertices = local.vertices.astype(np.float64) @ linear.T + matrix_world[:3, 3]  # per vertex, not corner
    triangles = local.triangles
    corner_normals = local.corner_normals
    if corner_normals is not None and not np.array_equal(linear, np.eye(3)):
        # Normals transform with the inverse transpose: n_world = n @ inverse(linear); in float32
        # (Cycles' normals are floats), without a float64 copy of every corner.
        normals = corner_normals.reshape(-1, 3) @ np.linalg.inv(linear).astype(np.float32)
        normals /= np.maximum(np.sqrt(np.einsum("ij,ij->i", normals, normals)), 1e-30)[:, None]
        corner_normals = normals.reshape(-1, 3, 3)
    attributes = dict(local.corner_attributes or {})
    if np.linalg.det(linear) < 0.0:
        # A mirroring transform flips the winding: swap two corners to keep normals outward.
        triangles = triangles[:, [0, 2, 1]]
        if corner_normals is not None:
            corner_normals = corner_normals[:, [0, 2, 1]]
        attributes = {name: values[:, [0, 2, 1]] for name, values in attributes.items()}
    frame = None
    if local.generated is not None:  # Texture Coordinate Object / Generated / Normal of surfaces
        frame = np.stack([np.linalg.inv(matrix_world)[:3], local.generated])
    # Blender clamps out-of-range material indices to the last slot.
    slots = np.clip(local.material_slots, 0, len(slot_materials) - 1)
    return vp.Mesh(name=name, vertices=vertices, triangles=triangles,
                   material_ids=slot_materials[slots], corner_normals=corner_normals, corner_attributes=attributes,
                   object_frame=frame)


def _identity_placed(vertices: np.ndarray) -> np.ndarray:
    """float32 vertices under the identity transform, as the float64 product gives them (x + 0.0:
    -0.0 becomes 0.0, nothing else changes), in a buffer padded as Embree reads it (Mesh keeps it
    without another copy, volpath_native.scene.padded_rows)."""
    padded = np.empty((len(vertices) + 2, 3), np.float32)
    np.add(vertices, np.float32(0.0), out=padded[:len(vertices)])
    return padded[:len(vertices)]
