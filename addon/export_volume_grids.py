"""Export Blender Volume objects (OpenVDB grids) to dense numpy grids and GridMedium instances.

The scene exporter (addon/export/__init__.py, _export_volume_objects) calls
`export_volume_objects(depsgraph, warnings)` and `grid_medium_from_volume(exported, warnings)`.

How the grids are read: the *evaluated* Volume's grids (after modifiers / geometry nodes) are
written with `Volume.grids.save()` to a temporary .vdb and read back with the `openvdb` module that
Blender's bundled Python ships. Inside a real Blender it imports directly; with the `bpy` module
from PyPI its folder (Blender's bundled site-packages) is added to sys.path explicitly.
Each float or vector grid is copied (copyToArray) into a dense float32 array over the union of the
active-voxel bounding boxes of the grids on its voxel lattice (so density, colour, temperature and
flame align voxel for voxel); its index->world transform is the grid's own linear transform composed with the
object's matrix_world, as Cycles does (intern/cycles/scene/image_vdb.cpp: index_to_object from the
grid's affine map; object transform applied on top).

Material (Cycles' Principled Volume, kernel/svm/closure.h): Density x the density attribute grid,
Color x the colour grid, the object's density factor (scene/object.cpp), Emission Strength x Emission
Color (or, when an Attribute node feeds Emission Strength, that grid per voxel: Blender's flame setup),
and blackbody emission from Temperature x the temperature grid (or the constant Temperature when the
grid is absent), computed per voxel and interpolated like Cycles' stochastic lookups. Other node
setups: a warning and the socket values / defaults.

Bad input never raises into Blender: a missing file, an unsupported grid type, an empty grid, a
non-linear (frustum) transform or a grid too large for dense storage produce a warning string and
the grid (or the whole object, when its density grid is unusable) is skipped.
"""
from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import dataclass, field
from typing import Optional

import bpy
import numpy as np

from volpath_native.grid_medium import (GridMedium, blackbody_emission, principled_volume_coefficients,
                                        volume_object_density_factor)

from .compat import material_node_tree

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


@dataclass
class DenseGrid:
    """One grid as a dense array: data[i, j, k] (float32; (..., 3) for vector grids) holds the value
    at index-space point (i, j, k), which index_to_world (4x4) maps to world space."""

    name: str
    data: np.ndarray
    index_to_world: np.ndarray
    index_origin: tuple  # OpenVDB index coordinate of data[0, 0, 0]
    grid_to_object: np.ndarray  # the grid's own index->object transform (4x4)


@dataclass
class ExportedVolume:
    """The grids of one Volume object, the object's transform and Cycles' density scale."""

    object_name: str
    object_to_world: np.ndarray
    grids: dict = field(default_factory=dict)
    density_factor: float = 1.0
    material: Optional[object] = None  # bpy.types.Material or None


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
        warnings.append(f"{label}: grid '{grid.name}' has non-finite values, replaced by 0")
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
        source = read[key]
        if source is None:
            continue
        object_to_world = np.array(instance.matrix_world, dtype=np.float64)
        grids = {name: DenseGrid(g.name, g.data, object_to_world @ g.grid_to_object @ _shift(g.index_origin),
                                 g.index_origin, g.grid_to_object) for name, g in source.grids.items()}
        exported.append(ExportedVolume(
            obj.name, object_to_world, grids,
            volume_object_density_factor(object_to_world, object_space=obj.data.render.space == "OBJECT"),
            obj.active_material))
    return exported


def _shift(origin) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = origin
    return m


# ----------------------------------------------------------------------------------------------
# Material: Principled Volume driven by the grids
# ----------------------------------------------------------------------------------------------
PRINCIPLED_DEFAULTS = {
    "Color": (0.5, 0.5, 0.5), "Color Attribute": "", "Density": 1.0, "Density Attribute": "density",
    "Anisotropy": 0.0, "Absorption Color": (0.0, 0.0, 0.0), "Emission Strength": 0.0,
    "Emission Color": (1.0, 1.0, 1.0), "Blackbody Intensity": 0.0, "Blackbody Tint": (1.0, 1.0, 1.0),
    "Temperature": 1000.0, "Temperature Attribute": "temperature",
    # Not a socket: the grid an Attribute node feeds into Emission Strength (e.g. 'flame'), or "".
    "Emission Strength Attribute": "",
}


def _attribute_source(socket) -> str:
    """Name of the grid attribute a socket reads through a (Geometry) Attribute node's Fac/Color
    output, following reroutes; "" if it is driven by anything else."""
    link = socket.links[0] if socket.links else None
    while link is not None and link.from_node.bl_idname == "NodeReroute" and link.from_node.inputs[0].links:
        link = link.from_node.inputs[0].links[0]
    if link is None or link.is_muted or link.from_node.mute:
        return ""
    node = link.from_node
    if (node.bl_idname == "ShaderNodeAttribute" and node.attribute_type == "GEOMETRY"
            and link.from_socket.identifier in ("Fac", "Color")):  # names differ by version (Fac/Factor)
        return node.attribute_name
    return ""


def material_grid_names(material) -> set:
    """Grid names a material's Principled Volume reads (attribute sockets and Attribute nodes)."""
    inputs = principled_volume_inputs(material, [], "")
    names = {inputs["Density Attribute"], inputs["Color Attribute"], inputs["Emission Strength Attribute"]}
    if inputs["Blackbody Intensity"] > 0:
        names.add(inputs["Temperature Attribute"])
    return {name for name in names if name}


def principled_volume_inputs(material, warnings: list, label: str) -> dict:
    """The Principled Volume socket values of a material's active Volume output.

    No material: Cycles' default volume shader, a Principled Volume with default values
    (intern/cycles/scene/shader.cpp, "default_volume"). Other node setups and linked inputs are
    not evaluated: warning + the socket's own value / the defaults."""
    values = dict(PRINCIPLED_DEFAULTS)
    node_tree = material_node_tree(material)
    if node_tree is None:
        return values
    outputs = [n for n in node_tree.nodes
               if n.bl_idname == "ShaderNodeOutputMaterial" and n.target in ("ALL", "CYCLES")]
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    volume_socket = output.inputs.get("Volume") if output is not None else None
    if volume_socket is None or not volume_socket.is_linked:
        warnings.append(f"{label}: material '{material.name}' has no volume shader; Principled Volume defaults used")
        return values
    node = volume_socket.links[0].from_node
    if node.bl_idname != "ShaderNodeVolumePrincipled":
        warnings.append(f"{label}: volume shader '{node.name}' ({node.bl_idname}) is not supported yet; "
                        "Principled Volume defaults used")
        return values
    for socket in node.inputs:
        if socket.name not in values:
            continue
        if socket.name == "Emission Strength" and socket.is_linked and _attribute_source(socket):
            # Cycles evaluates the Attribute node per lookup: strength = the grid's value.
            values["Emission Strength Attribute"] = _attribute_source(socket)
            continue
        if socket.is_linked:
            warnings.append(f"{label}: '{socket.name}' input is driven by nodes, which are not evaluated; "
                            "its own value is used")
        value = socket.default_value
        values[socket.name] = value if isinstance(value, (str, float, int)) else tuple(value)[:3]
    return values


def grid_medium_from_volume(exported: ExportedVolume, warnings: list, **medium_kwargs) -> Optional[GridMedium]:
    """A GridMedium for an exported Volume object and its material, with Cycles' conversions:
    density x density grid, Color x colour grid, the object's density factor
    (kernel/svm/closure.h svm_node_principled_volume; scene/object.cpp object_volume_density)."""
    label = f"volume '{exported.object_name}'"
    inputs = principled_volume_inputs(exported.material, warnings, label)
    density_name = inputs["Density Attribute"]
    density = exported.grids.get(density_name)
    if density is None or density.data.ndim != 3:
        warnings.append(f"{label}: density attribute grid '{density_name}' missing or not a float grid; skipped")
        return None
    factor = exported.density_factor  # Cycles' weight: mix weight (1) x object volume density
    emission_color = np.asarray(inputs["Emission Color"], float)
    emission = max(inputs["Emission Strength"], 0.0) * factor * emission_color  # `if (emission > 0)`
    emission_grid = None

    def aligned_float_grid(name, what):
        grid = exported.grids.get(name)
        if grid is None:
            return None
        if grid.data.ndim != 3:
            warnings.append(f"{label}: {what} grid '{name}' is not a float grid; ignored")
        elif grid.data.shape != density.data.shape or not np.allclose(grid.index_to_world, density.index_to_world):
            warnings.append(f"{label}: {what} grid '{name}' is not on the density grid's voxels; ignored")
        else:
            return grid.data
        return None

    flame_name = inputs["Emission Strength Attribute"]
    if flame_name:
        # Emission Strength = the attribute (e.g. 'flame'); per voxel max(value, 0) x Emission Color.
        emission = np.zeros(3)
        flame = aligned_float_grid(flame_name, "emission strength")
        if flame is None and flame_name not in exported.grids:
            warnings.append(f"{label}: emission strength attribute '{flame_name}' has no grid: no emission (as Cycles)")
        if flame is not None:
            emission_grid = (np.maximum(flame, 0.0)[..., None] * (factor * emission_color)).astype(np.float32)

    if inputs["Blackbody Intensity"] > 0:
        # kernel/svm/closure.h: T = Temperature x max(temperature attribute, 0) when the grid exists,
        # else Temperature; emission = tint x sigma/pi x mix(1, T^4, intensity) x blackbody(T).
        # Per voxel, then interpolated: the expectation of Cycles' stochastic attribute lookup.
        temperature = aligned_float_grid(inputs["Temperature Attribute"], "temperature")
        if temperature is not None:
            voxel_emission = factor * blackbody_emission(
                inputs["Temperature"] * np.maximum(temperature, 0.0), inputs["Blackbody Intensity"],
                inputs["Blackbody Tint"])
            emission_grid = voxel_emission if emission_grid is None else emission_grid + voxel_emission
            emission_grid = emission_grid.astype(np.float32)
            # Outside the temperature grid's voxels T = 0 and Cycles emits sigma/pi x (1 - intensity)
            # x blackbody(0 K): below 1e-14, left out.
        else:
            emission = emission + factor * blackbody_emission(
                inputs["Temperature"], inputs["Blackbody Intensity"], inputs["Blackbody Tint"])

    color_grid = None
    color_name = inputs["Color Attribute"]
    if color_name:
        color = exported.grids.get(color_name)
        if color is None or color.data.ndim != 4:
            warnings.append(f"{label}: color attribute grid '{color_name}' missing or not a vector grid; ignored")
        elif color.data.shape[:3] != density.data.shape or not np.allclose(color.index_to_world, density.index_to_world):
            warnings.append(f"{label}: color grid '{color_name}' is not on the density grid's voxels; ignored")
        else:
            color_grid = color.data

    common = dict(g=inputs["Anisotropy"], emission=emission, emission_grid=emission_grid, **medium_kwargs)
    if color_grid is not None:
        return GridMedium.with_color_grid(
            exported.object_name, density.data, color_grid, density.index_to_world, color=inputs["Color"],
            density_scale=inputs["Density"], absorption_color=inputs["Absorption Color"],
            object_density_factor=exported.density_factor, **common)
    sigma_s, sigma_a = principled_volume_coefficients(
        inputs["Color"], inputs["Density"], inputs["Absorption Color"], exported.density_factor)
    return GridMedium(exported.object_name, density.data, density.index_to_world, sigma_s, sigma_a, **common)
