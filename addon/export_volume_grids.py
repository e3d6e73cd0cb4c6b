"""Export Blender Volume objects (OpenVDB grids) to dense numpy grids (ExportedVolume).

The scene exporter (addon/export/__init__.py, _export_grid_media) calls
`export_volume_objects(depsgraph, warnings)`; the grids become media through the converter Volume
objects share with fluid domains (addon/export/grid_media.py, `grid_medium_from_volume`).

How the grids are read: the *evaluated* Volume's grids (after modifiers / geometry nodes) are
written with `Volume.grids.save()` to a temporary .vdb and read back with the `openvdb` module that
Blender's bundled Python ships. Inside a real Blender it imports directly; with the `bpy` module
from PyPI its folder (Blender's bundled site-packages) is added to sys.path explicitly.
Each float or vector grid is copied (copyToArray) into a dense float32 array over the union of the
active-voxel bounding boxes of the grids on its voxel lattice (so density, colour, temperature and
flame align voxel for voxel); its index->world transform is the grid's own linear transform composed with the
object's matrix_world, as Cycles does (intern/cycles/scene/image_vdb.cpp: index_to_object from the
grid's affine map; object transform applied on top).

Bad input never raises into Blender: a missing file, an unsupported grid type, an empty grid, a
non-linear (frustum) transform or a grid too large for dense storage produce a warning string and
the grid (or the whole object, when its density grid is unusable) is skipped.
"""
from __future__ import annotations

import os
import sys
import tempfile
from typing import Optional

import bpy
import numpy as np

from volpath_native.grid_medium import volume_object_density_factor

from .export.motion import instance_key
# The shared grid -> medium converter; re-exported for callers of this module.
from .export.grid_media import (DenseGrid, ExportedVolume, grid_medium_from_volume,  # noqa: F401
                                material_grid_names, principled_volume_inputs)

#: Grid names Cycles maps to standard attributes (intern/cycles/blender/volume.cpp).
STANDARD_GRIDS = ("density", "color", "temperature", "flame", "heat")
#: Dense storage cap: 512^3 float32 voxels = 512 MB; larger grids are skipped with a warning.
MAX_DENSE_VOXELS = 512 ** 3


class OpenVDBUnavailable(ImportError):
    """Blender's bundled openvdb module could not be imported."""


def import_openvdb():
    """The `openvdb` module Blender ships (bundled site-packages), or OpenVDBUnavailable."""
    try:
        import openvdb
        return openvdb
    except ImportError:
        pass
    bundled = os.path.join(bpy.utils.resource_path("LOCAL"), "python", "lib",
                           f"python{sys.version_info.major}.{sys.version_info.minor}", "site-packages")
    if os.path.isdir(bundled) and bundled not in sys.path:
        sys.path.append(bundled)
    try:
        import openvdb
        return openvdb
    except ImportError as error:
        raise OpenVDBUnavailable(
            f"the openvdb module Blender bundles was not found (looked in {bundled}): "
            "Volume objects cannot be exported") from error



def _affine_from_openvdb(transform) -> Optional[np.ndarray]:
    """4x4 index->object matrix of a linear openvdb.Transform (None if not linear)."""
    if not transform.isLinear:
        return None
    origin = np.array(transform.indexToWorld((0.0, 0.0, 0.0)), dtype=np.float64)
    matrix = np.eye(4)
    for axis in range(3):
        unit = [0.0, 0.0, 0.0]
        unit[axis] = 1.0
        matrix[:3, axis] = np.array(transform.indexToWorld(tuple(unit)), dtype=np.float64) - origin
    matrix[:3, 3] = origin
    return matrix


def _usable(grid, warnings: list, label: str) -> bool:
    """True for a non-empty float/vector grid with a linear transform (else a warning)."""
    if grid.valueTypeName not in ("float", "double", "vec3s", "vec3d"):
        warnings.append(f"{label}: grid '{grid.name}' has unsupported type '{grid.valueTypeName}', skipped")
        return False
    if grid.activeVoxelCount() == 0:
        warnings.append(f"{label}: grid '{grid.name}' is empty, skipped")
        return False
    if _affine_from_openvdb(grid.transform) is None:
        warnings.append(f"{label}: grid '{grid.name}' has a non-linear (frustum) transform, skipped")
        return False
    return True


def _shared_boxes(grids) -> dict:
    """Grid name -> (lo, hi) index box to copy: grids on the same voxel lattice (equal transforms)
    share the union of their active boxes, so their arrays align voxel for voxel (temperature and
    colour are then looked up at the density's voxels, and none loses voxels outside the others')."""
    boxes, groups = {}, []  # groups: [affine, lo, hi, names]
    for grid in grids:
        affine = _affine_from_openvdb(grid.transform)
        lo, hi = (np.array(v, dtype=np.int64) for v in grid.evalActiveVoxelBoundingBox())
        for group in groups:
            if np.allclose(group[0], affine, rtol=1e-6, atol=1e-9):
                group[1], group[2] = np.minimum(group[1], lo), np.maximum(group[2], hi)
                group[3].append(grid.name)
                break
        else:
            groups.append([affine, lo, hi, [grid.name]])
    for _, lo, hi, names in groups:
        for name in names:
            boxes[name] = (tuple(int(v) for v in lo), tuple(int(v) for v in hi))
    return boxes


def _dense_copy(grid, warnings: list, label: str, box=None) -> Optional[DenseGrid]:
    """Copy one openvdb grid to a DenseGrid over `box` ((lo, hi) index corners, inclusive; default
    its active bounding box). None + warning if unusable."""
    value_type = grid.valueTypeName
    if value_type in ("float", "double"):
        channels = 1
    elif value_type in ("vec3s", "vec3d"):
        channels = 3
    else:
        warnings.append(f"{label}: grid '{grid.name}' has unsupported type '{value_type}', skipped")
        return None
    if grid.activeVoxelCount() == 0:
        warnings.append(f"{label}: grid '{grid.name}' is empty, skipped")
        return None
    grid_to_object = _affine_from_openvdb(grid.transform)
    if grid_to_object is None:
        warnings.append(f"{label}: grid '{grid.name}' has a non-linear (frustum) transform, skipped")
        return None
    lo, hi = box if box is not None else grid.evalActiveVoxelBoundingBox()
    shape = tuple(int(b - a + 1) for a, b in zip(lo, hi))
    if int(np.prod(shape, dtype=np.int64)) * channels > MAX_DENSE_VOXELS:
        warnings.append(f"{label}: grid '{grid.name}' spans {shape} voxels, too large for dense storage "
                        f"(limit {MAX_DENSE_VOXELS} values), skipped")
        return None
    data = np.zeros(shape + ((channels,) if channels == 3 else ()),
                    dtype=np.float64 if value_type.endswith("d") or value_type == "double" else np.float32)
    grid.copyToArray(data, ijk=tuple(int(v) for v in lo))
    data = data.astype(np.float32, copy=False)
    if not np.all(np.isfinite(data)):
        # Cycles' max(density x NaN, 0) is 0 (kernel/svm/closure.h); inf would give non-finite weights.
        bad = int((~np.isfinite(data)).reshape(data.shape[:3] + (-1,)).any(axis=-1).sum())
        warnings.append(f"{label}: grid '{grid.name}' has {bad} non-finite voxels (NaN/inf), treated as 0")
        data = np.nan_to_num(data, nan=0.0, posinf=0.0, neginf=0.0)
    index_shift = np.eye(4)
    index_shift[:3, 3] = lo  # data index -> OpenVDB index
    return DenseGrid(grid.name, data, grid_to_object @ index_shift, tuple(int(v) for v in lo), grid_to_object)


def export_volume_object(obj, warnings: list, temp_dir: Optional[str] = None,
                         grid_names=STANDARD_GRIDS) -> Optional[ExportedVolume]:
    """Dense grids of an *evaluated* Volume object (obj.evaluated_get(depsgraph)).

    Returns None (and appends a warning) when nothing usable is found. grid_names: the grids to
    read (others are ignored silently; Cycles only loads grids its shaders use)."""
    label = f"volume '{obj.name}'"
    if obj.type != "VOLUME":
        warnings.append(f"{label}: not a Volume object, skipped")
        return None
    try:
        openvdb = import_openvdb()
    except OpenVDBUnavailable as error:
        warnings.append(f"{label}: {error}")
        return None
    volume = obj.data
    if not volume.grids.load():
        message = volume.grids.error_message or "grids could not be loaded"
        warnings.append(f"{label}: {message}; skipped")
        return None
    if len(volume.grids) == 0:
        warnings.append(f"{label}: has no grids, skipped")
        return None

    object_to_world = np.array(obj.matrix_world, dtype=np.float64)
    exported = ExportedVolume(obj.name, object_to_world,
                              density_factor=volume_object_density_factor(
                                  object_to_world, object_space=volume.render.space == "OBJECT"),
                              material=obj.active_material)
    with tempfile.TemporaryDirectory(prefix="volpath_vdb_", dir=temp_dir) as tmp:
        path = os.path.join(tmp, "grids.vdb")
        try:
            if not volume.grids.save(path):
                raise RuntimeError(volume.grids.error_message or "save failed")
            grids, _ = openvdb.readAll(path)
        except Exception as error:  # noqa: BLE001 - openvdb raises plain RuntimeError/KeyError
            warnings.append(f"{label}: evaluated grids could not be written/read back ({error}), skipped")
            return None
        grids = [g for g in grids if g.name in grid_names and _usable(g, warnings, label)]
        boxes = _shared_boxes(grids)
        for grid in grids:
            dense = _dense_copy(grid, warnings, label, boxes[grid.name])
            if dense is not None:
                dense.index_to_world = object_to_world @ dense.index_to_world
                exported.grids[grid.name] = dense
    if not exported.grids:
        warnings.append(f"{label}: no usable grids among {list(grid_names)}, skipped")
        return None
    return exported


def export_volume_objects(depsgraph, warnings: list, temp_dir: Optional[str] = None) -> list:
    """ExportedVolume for every rendered Volume object instance in the evaluated depsgraph.

    Instances of the same evaluated volume share their dense arrays (read once); each gets its own
    index->world transforms and density factor from its instance matrix."""
    exported = []
    read: dict = {}  # evaluated volume data pointer -> ExportedVolume (or None if unusable)
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.type != "VOLUME" or (not instance.is_instance and not instance.show_self):
            continue
        if not np.all(np.abs(np.array(instance.matrix_world, dtype=np.float64)) < np.finfo(np.float32).max):
            continue  # non-finite or FLT_MAX: named by the scene exporter (export/validate.py finite_transform)
        key = obj.data.as_pointer()
        if key not in read:
            names = set(STANDARD_GRIDS) | material_grid_names(obj.active_material)
            read[key] = export_volume_object(obj, warnings, temp_dir, grid_names=tuple(sorted(names)))
            _warn_velocity_blur(obj, depsgraph.scene, warnings)  # its grids are loaded now
        source = read[key]
        if source is None:
            continue
        object_to_world = np.array(instance.matrix_world, dtype=np.float64)
        grids = {name: DenseGrid(g.name, g.data, object_to_world @ g.grid_to_object @ _shift(g.index_origin),
                                 g.index_origin, g.grid_to_object) for name, g in source.grids.items()}
        exported.append(ExportedVolume(
            obj.name, object_to_world, grids,
            volume_object_density_factor(object_to_world, object_space=obj.data.render.space == "OBJECT"),
            obj.active_material, instance_key=instance_key(instance)))
    return exported


def _warn_velocity_blur(obj, scene, warnings: list):
    """Cycles also blurs a Volume by its velocity grid (blender/volume.cpp, ATTR_STD_VOLUME_VELOCITY);
    VolPath blurs only the object's motion."""
    name = getattr(obj.data, "velocity_grid", "")
    if scene.render.use_motion_blur and name and name in {g.name for g in obj.data.grids}:
        warnings.append(f"volume '{obj.name}': velocity motion blur (grid '{name}') is not supported; only the "
                        "object's motion is blurred")


def _shift(origin) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = origin
    return m
