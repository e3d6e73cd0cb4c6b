"""The one conversion of voxel grids into a grid medium, for Volume objects and fluid domains alike.

Producers hand over an ExportedVolume (dense grids on index lattices mapped to world space, the
object's material and Cycles' density scale): addon/export_volume_grids.py for Volume objects
(OpenVDB grids), addon/export/fluid.py for Mantaflow gas domains. `grid_medium_from_volume`
applies the material the way Cycles' Principled Volume does (kernel/svm/closure.h,
svm_node_principled_volume): Density x the density attribute grid, Color x the colour grid, the
density factor (scene/object.cpp object_volume_density), Emission Strength x Emission Color (or,
when an Attribute node feeds Emission Strength, that grid per voxel: Blender's flame setup), and
blackbody emission from Temperature x the temperature grid (or the constant Temperature when the
grid is absent), computed per voxel and interpolated like Cycles' stochastic lookups. Other node
setups: a warning and the socket values / defaults.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from volpath_native.grid_medium import GridMedium, blackbody_emission, principled_volume_coefficients
from volpath_native.program_medium import ProgramMedium
from volpath_native.scene import SceneError

from ..compat import material_node_tree

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
    """The grids of one Volume object or fluid domain, its transform and Cycles' density scale.
    label names it in warnings (default "volume '<object_name>'")."""

    object_name: str
    object_to_world: np.ndarray
    grids: dict = field(default_factory=dict)
    density_factor: float = 1.0
    material: Optional[object] = None  # bpy.types.Material or None
    label: str = ""
    instance_key: tuple = ()  # export.motion.instance_key of its depsgraph instance (its motion blur)

    def __post_init__(self):
        self.label = self.label or f"volume '{self.object_name}'"





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


def _volume_output(material):
    node_tree = material_node_tree(material)
    if node_tree is None:
        return None
    outputs = [n for n in node_tree.nodes
               if n.bl_idname == "ShaderNodeOutputMaterial" and n.target in ("ALL", "CYCLES")]
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    return output.inputs.get("Volume") if output is not None else None


def principled_volume_inputs(material, warnings: list, label: str) -> dict:
    """The Principled Volume socket values of a material's active Volume output.

    No material: Cycles' default volume shader, a Principled Volume with default values
    (intern/cycles/scene/shader.cpp, "default_volume"). Other node setups and linked inputs are
    not evaluated: warning + the socket's own value / the defaults."""
    values = dict(PRINCIPLED_DEFAULTS)
    if material_node_tree(material) is None:
        return values
    volume_socket = _volume_output(material)
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


def needs_program(material) -> bool:
    """Whether the material's volume is more than a Principled Volume reading grid attributes (and
    an Attribute node feeding Emission Strength): then its nodes are compiled to a shader program."""
    socket = _volume_output(material) if material is not None else None
    if socket is None or not socket.is_linked:
        return False
    node = socket.links[0].from_node
    if node.bl_idname != "ShaderNodeVolumePrincipled":
        return True
    return any(s.is_linked and not (s.name == "Emission Strength" and _attribute_source(s))
               for s in node.inputs if s.name in PRINCIPLED_DEFAULTS)


class _ListReporter:
    def __init__(self, warnings: list):
        self.warnings = warnings

    def warn(self, message: str):
        if message not in self.warnings:
            self.warnings.append(message)


def program_medium_from_volume(exported: ExportedVolume, warnings: list) -> Optional[ProgramMedium]:
    """A ProgramMedium for a Volume object whose material computes its medium with nodes: the
    program reads the object's grids as attributes (trilinear, 0 outside; the expectation of Cycles'
    stochastic lookups only where the nodes are linear in them), in the density grid's padded box;
    Generated is raw object space, as Cycles 5.0 gives volume geometry no texture-space transform."""
    from .procedural_media import phase_of
    from .shader_compiler import ShaderCompiler

    label = exported.label
    program = ShaderCompiler(f"{label} (material '{exported.material.name}')", _ListReporter(warnings),
                             attributes=set(exported.grids)).compile_volume(_volume_output(exported.material),
                                                                            weight=exported.density_factor)
    reference = exported.grids.get("density") or next(iter(exported.grids.values()), None)
    if reference is None:
        warnings.append(f"{label}: no grids; skipped")
        return None
    shape = reference.data.shape[:3]
    channels = []
    for name, width in program.attributes:
        grid = exported.grids.get(name)
        data = None if grid is None else grid.data
        if data is not None and (data.shape[:3] != shape or not np.allclose(grid.index_to_world, reference.index_to_world)):
            warnings.append(f"{label}: grid '{name}' is not on the '{reference.name}' grid's voxels; read as 0")
            data = None
        if data is None:
            data = np.zeros(shape + ((width,) if width > 1 else ()), np.float32)
        data = data.reshape(shape + (-1,))
        channels.append(np.repeat(data, width, axis=3) if data.shape[3] == 1 and width > 1 else data[..., :width])
    stacked = np.concatenate(channels, axis=3) if channels else np.zeros(shape + (1,), np.float32)
    # zero padding, one voxel below and two above (GridMedium's box = Cycles' volume bounds)
    attributes = np.zeros(tuple(np.add(shape, 3)) + (stacked.shape[3],), np.float32)
    attributes[1:-2, 1:-2, 1:-2] = np.nan_to_num(stacked, nan=0.0, posinf=0.0, neginf=0.0)
    shift = np.eye(4)
    shift[:3, 3] = -1.0
    index_to_world = reference.index_to_world @ shift
    box = np.random.default_rng(0).random((256, 3)) * (np.array(attributes.shape[:3]) - 1)
    samples = box @ index_to_world[:3, :3].T + index_to_world[:3, 3]
    frame = np.stack([np.linalg.inv(exported.object_to_world)[:3], np.eye(4)[:3]])
    g = phase_of(program, frame, samples, label, _ListReporter(warnings), attributes,
                 np.linalg.inv(index_to_world))
    try:
        medium = ProgramMedium(exported.object_name, program, exported.object_to_world, (np.zeros(3), np.zeros(3)),
                               np.eye(4)[:3], attributes=attributes, grid_index_to_world=index_to_world, g=g)
    except SceneError as error:
        warnings.append(f"{label}: {error}; skipped")
        return None
    warnings.extend(medium.warnings())
    return medium


def grid_medium_from_volume(exported: ExportedVolume, warnings: list, **medium_kwargs) -> Optional[GridMedium]:
    """A GridMedium for an exported Volume object and its material, with Cycles' conversions:
    density x density grid, Color x colour grid, the object's density factor
    (kernel/svm/closure.h svm_node_principled_volume; scene/object.cpp object_volume_density).
    Materials whose volume is computed by other nodes become a ProgramMedium instead."""
    if exported.material is not None and needs_program(exported.material):
        return program_medium_from_volume(exported, warnings)
    label = exported.label
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
