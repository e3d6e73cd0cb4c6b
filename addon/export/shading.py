"""Blender materials and the world -> VolPath Material / Medium / World.

The node trees are read, not executed: the closures VolPath supports combine linearly (Add Shader,
Mix Shader with a constant factor), so a tree reduces to sums of weighted terms.

Supported, with Cycles' meaning (intern/cycles/kernel/svm/closure.h):
- Surface: the BSDF nodes of surfaces.py (Principled, Glossy, Glass, ...), Emission, Add / Mix
  Shader; a white Transparent BSDF feeding the output directly is an invisible (null) surface.
- Volume: Principled Volume, Volume Scatter (Henyey-Greenstein), Volume Absorption, Volume
  Coefficients (5.0), Emission, Add / Mix Shader.
- World: Background colour x strength, and the Volume output.
Documented fallbacks (each one reported as a warning naming the material and the node):
- a linked input (texture, attribute...) uses the socket's own unlinked value; RGB and Value nodes
  feeding an input are read as the constants they are;
- an unsupported surface node renders as a 0.8 grey diffuse (surfaces.py);
- an unsupported volume node contributes no medium.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

import volpath_native as vp
from volpath_native.grid_medium import blackbody_emission

from volpath_native.bsdfs.nodes import SurfaceNode

from .. import compat
from . import validate
from .procedural_media import ProceduralMedia
from .images import ImageRegistry
from .shader_compiler import ShaderCompiler
from .surface_programs import SurfaceProgramCompiler
from .surfaces import surface_terms

# Cycles clamps Henyey-Greenstein's g to +-(1 - 1e-3) (kernel/closure/volume_henyey_greenstein.h).
HG_G_LIMIT = 1.0 - 1e-3


class Reporter:
    """Collects warnings once each, in order."""

    def __init__(self):
        self.messages: list[str] = []
        self._seen: set[str] = set()

    def warn(self, message: str):
        if message not in self._seen:
            self._seen.add(message)
            self.messages.append(message)


# ----------------------------------------------------------------------------------------------
# Reading node inputs
# ----------------------------------------------------------------------------------------------
def _source_socket(socket):
    """The output socket feeding `socket` through reroutes and muted links, or None."""
    for link in socket.links:
        if link.is_muted or not link.is_valid:
            continue
        source = link.from_socket
        if source.node.type == "REROUTE":  # follow it to what feeds the reroute
            inputs = source.node.inputs
            return _source_socket(inputs[0]) if inputs and inputs[0].is_linked else None
        return source
    return None


def _shader_node(socket):
    """The unmuted shader node feeding `socket`, or None (nothing connected: black / no medium)."""
    source = _source_socket(socket)
    if source is None or source.node.mute:
        return None
    return source.node


class NodeReader:
    """Reads constant inputs of one material's nodes, warning about what it cannot evaluate."""

    def __init__(self, owner: str, reporter: Reporter, program=None):
        self.owner = owner  # e.g. "material 'Fog'"
        self.reporter = reporter
        # surface_programs.SurfaceProgramCompiler: varying BSDF inputs are compiled, not warned about
        self.program = program

    def warn(self, node, message: str):
        self.reporter.warn(f"{self.owner}: node '{node.name}' ({node.bl_idname}): {message}")

    def value(self, node, socket):
        """The socket's constant value: float, or an RGB float64 array for colours/vectors
        (non-finite values replaced and warned about: validate.finite_socket_value)."""
        source = _source_socket(socket) if socket.is_linked else None
        value = None
        if source is not None:
            if source.node.type in ("RGB", "VALUE"):  # constants feeding the input
                value = _as_value(source.default_value)
            elif self.program is not None and self.program.handles(node, socket):
                pass  # evaluated per hit by the material's surface program; this is its fallback
            else:
                self.warn(node, f"input '{socket.name}' is driven by '{source.node.name}' "
                                f"({source.node.bl_idname}), which VolPath cannot evaluate; "
                                "using the input's own value")
        if value is None:
            value = _as_value(socket.default_value)
        return validate.finite_socket_value(value, lambda message: self.warn(node, message), socket.name)

    def rgb(self, node, name_or_socket) -> np.ndarray:
        socket = node.inputs[name_or_socket] if isinstance(name_or_socket, str) else name_or_socket
        value = self.value(node, socket)
        return value if isinstance(value, np.ndarray) else np.full(3, value)

    def scalar(self, node, name_or_socket) -> float:
        socket = node.inputs[name_or_socket] if isinstance(name_or_socket, str) else name_or_socket
        value = self.value(node, socket)
        return float(np.mean(value)) if isinstance(value, np.ndarray) else float(value)


def _as_value(default_value):
    try:
        return np.array(default_value[:3], dtype=np.float64)
    except TypeError:
        return float(default_value)


def _mix_factor(reader: NodeReader, node) -> float:
    return float(np.clip(reader.scalar(node, node.inputs[0]), 0.0, 1.0))


# ----------------------------------------------------------------------------------------------
# Volumes
# ----------------------------------------------------------------------------------------------
@dataclass
class _Volume:
    """Sums of coefficients, and the scattering closures as (sigma_s RGB, g) terms."""

    sigma_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sigma_a: np.ndarray = field(default_factory=lambda: np.zeros(3))
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    g_terms: list = field(default_factory=list)  # (sigma_s RGB, g) per scattering closure

    def scaled(self, w: float) -> "_Volume":
        return _Volume(self.sigma_s * w, self.sigma_a * w, self.emission * w,
                       [(s * w, g) for s, g in self.g_terms])

    def __add__(self, other: "_Volume") -> "_Volume":
        return _Volume(self.sigma_s + other.sigma_s, self.sigma_a + other.sigma_a,
                       self.emission + other.emission, self.g_terms + other.g_terms)

    @property
    def is_empty(self) -> bool:
        return not (np.any(self.sigma_s) or np.any(self.sigma_a) or np.any(self.emission))


def _scatter_term(sigma_s: np.ndarray, g: float) -> list:
    # Cycles clamps g per closure (kernel/closure/volume_henyey_greenstein.h).
    return [(np.asarray(sigma_s, dtype=np.float64), float(np.clip(g, -HG_G_LIMIT, HG_G_LIMIT)))]


def _volume_from(reader: NodeReader, socket) -> _Volume:
    node = _shader_node(socket)
    if node is None:
        return _Volume()
    kind = node.type
    if kind == "PRINCIPLED_VOLUME":
        # svm/closure.h svm_node_principled_volume: rho = max(Density, 0);
        # sigma_s = C rho; sigma_a = rho max(1 - C, 0) max(1 - max(sqrt(A), 0), 0);
        # emission (per unit length) = Strength x Emission Color, NOT multiplied by density.
        color = reader.rgb(node, "Color")
        density = max(reader.scalar(node, "Density"), 0.0)
        absorption_color = np.maximum(np.sqrt(np.maximum(reader.rgb(node, "Absorption Color"), 0.0)), 0.0)
        sigma_s = color * density
        sigma_a = density * np.maximum(1.0 - color, 0.0) * np.maximum(1.0 - absorption_color, 0.0)
        # `if (emission > 0)`: a negative strength emits nothing.
        emission = max(reader.scalar(node, "Emission Strength"), 0.0) * reader.rgb(node, "Emission Color")
        # Blackbody: tint x sigma/pi x mix(1, T^4, intensity) x blackbody(T) (same closure.h function;
        # a mesh has no temperature attribute, so T = Temperature).
        emission = emission + blackbody_emission(reader.scalar(node, "Temperature"),
                                                  reader.scalar(node, "Blackbody Intensity"),
                                                  reader.rgb(node, "Blackbody Tint"))
        for attribute in ("Density Attribute", "Color Attribute", "Temperature Attribute"):
            socket_attr = node.inputs.get(attribute)
            if socket_attr is not None and socket_attr.is_linked:
                reader.warn(node, f"'{attribute}' is ignored: VolPath media are homogeneous")
        if density == 0.0:
            sigma_s, sigma_a = np.zeros(3), np.zeros(3)
        return _Volume(sigma_s, sigma_a, emission, _scatter_term(sigma_s, reader.scalar(node, "Anisotropy")))
    if kind == "VOLUME_SCATTER":
        # svm_node_closure_volume: weight = Color x max(Density, 0); scattering only.
        phase = compat.volume_scatter_phase(node)
        if phase != "HENYEY_GREENSTEIN":
            reader.warn(node, f"phase function {phase} is not supported; rendered as Henyey-Greenstein")
        sigma_s = reader.rgb(node, "Color") * max(reader.scalar(node, "Density"), 0.0)
        return _Volume(sigma_s=sigma_s, g_terms=_scatter_term(sigma_s, reader.scalar(node, "Anisotropy")))
    if kind == "VOLUME_ABSORPTION":
        # svm_node_closure_volume: extinction weight = (1 - Color) x max(Density, 0).
        sigma_a = (1.0 - reader.rgb(node, "Color")) * max(reader.scalar(node, "Density"), 0.0)
        return _Volume(sigma_a=sigma_a)
    if kind == "VOLUME_COEFFICIENTS":
        # svm_node_volume_coefficients: sigma_t = scatter + absorption, emission as given.
        phase = compat.volume_scatter_phase(node)
        if phase != "HENYEY_GREENSTEIN":
            reader.warn(node, f"phase function {phase} is not supported; rendered as Henyey-Greenstein")
        sigma_s = reader.rgb(node, "Scatter Coefficients")
        return _Volume(sigma_s=sigma_s, sigma_a=reader.rgb(node, "Absorption Coefficients"),
                       emission=reader.rgb(node, "Emission Coefficients"),
                       g_terms=_scatter_term(sigma_s, reader.scalar(node, "Anisotropy")))
    if kind == "EMISSION":
        return _Volume(emission=reader.rgb(node, "Color") * reader.scalar(node, "Strength"))
    if kind == "ADD_SHADER":
        return _volume_from(reader, node.inputs[0]) + _volume_from(reader, node.inputs[1])
    if kind == "MIX_SHADER":
        f = _mix_factor(reader, node)
        return (_volume_from(reader, node.inputs[1]).scaled(1.0 - f)
                + _volume_from(reader, node.inputs[2]).scaled(f))
    reader.warn(node, "unsupported volume shader; it contributes no medium")
    return _Volume()


def _medium_from(name: str, volume: _Volume) -> vp.Medium:
    """One Henyey-Greenstein lobe per distinct anisotropy: Cycles keeps one closure per volume shader
    and merges only closures with equal g (kernel/integrator/volume_shader.h,
    volume_shader_merge_closures); the renderer samples and evaluates the exact mixture."""
    lobes: dict = {}
    for sigma_s, g in volume.g_terms:
        if np.any(sigma_s > 0):
            lobes[g] = lobes.get(g, 0.0) + sigma_s
    if len(lobes) <= 1:
        g = next(iter(lobes), 0.0)
        return vp.Medium(name=name, sigma_s=volume.sigma_s, sigma_a=volume.sigma_a, g=g, emission=volume.emission)
    return vp.Medium(name=name, sigma_s=volume.sigma_s, sigma_a=volume.sigma_a, emission=volume.emission,
                     phase_lobes=[(sigma_s, g) for g, sigma_s in lobes.items()])


# ----------------------------------------------------------------------------------------------
# Material table
# ----------------------------------------------------------------------------------------------
class MaterialTable:
    """Scene.materials and Scene.media, one entry per Blender material (and one default)."""

    def __init__(self, reporter: Reporter):
        self.reporter = reporter
        self.materials: list[vp.Material] = []
        self.media: list[vp.Medium] = []
        self._index: dict = {}
        # materials whose volume varies over space: a medium per object (procedural_media.py)
        self.procedural = ProceduralMedia(self)
        self.images = ImageRegistry(reporter)  # Scene.images, one copy per image
        self.corner_requests: dict = {}  # material index -> per-corner attribute names its program reads

    def index_of(self, material) -> int:
        """Index into `materials` for a Blender material (None: Cycles' default grey diffuse)."""
        key = None if material is None else material.name_full
        if key not in self._index:
            self._index[key] = len(self.materials)
            self.materials.append(self._convert(material))
        return self._index[key]

    def _volume_program(self, name: str, socket):
        return _volume_program_of(f"material '{name}'", socket, self.reporter)

    def _convert(self, material) -> vp.Material:
        if material is None:
            return vp.Material(name="(no material)", surface_nodes=[SurfaceNode(kind="principled")])
        name = material.name_full
        tree = compat.material_node_tree(material)
        if tree is None:  # not node-based (Blender < 5): Cycles uses the viewport diffuse colour
            return vp.Material(name=name, base_color=np.array(material.diffuse_color[:3]))
        reader = NodeReader(f"material '{name}'", self.reporter)
        output = tree.get_output_node("CYCLES")
        if output is None:
            self.reporter.warn(f"material '{name}': no active Material Output node; rendered black (as Cycles)")
            return vp.Material(name=name, base_color=np.zeros(3))
        surface_socket, volume_socket = output.inputs["Surface"], output.inputs["Volume"]
        displacement = output.inputs.get("Displacement")
        displaced = displacement is not None and _source_socket(displacement) is not None
        has_surface = _source_socket(surface_socket) is not None
        has_volume = _source_socket(volume_socket) is not None
        program = self._volume_program(name, volume_socket) if has_volume else None
        medium = -1
        if program is not None and program.varying:
            # evaluated per object: ProceduralMedia.bind gives each object its own medium
            self.procedural.programs[len(self.materials)] = program
        elif has_volume:
            volume = _volume_from(reader, volume_socket)
            if not volume.is_empty:
                self.media.append(_medium_from(name, volume))
                medium = len(self.media) - 1
        if has_volume and not has_surface:
            # Volume only: an invisible boundary (scene/shader.cpp sets SD_HAS_ONLY_VOLUME, and
            # kernel/integrator/surface_shader.h makes such surfaces fully transparent).
            return vp.Material(name=name, surface="null", base_color=np.zeros(3), medium=medium)
        source = _source_socket(surface_socket)
        if (source is not None and source.node.type == "BSDF_TRANSPARENT" and not source.node.mute
                and np.all(reader.rgb(source.node, "Color") == 1.0)):
            # A white Transparent BSDF alone lets every ray through unchanged: VolPath's null
            # surface (it does not count against the transparent bounce limit; README).
            return vp.Material(name=name, surface="null", base_color=np.zeros(3), medium=medium)
        # Nothing connected to Surface (and no volume) is an opaque black surface in Cycles.
        reader.program = SurfaceProgramCompiler(f"material '{name}'", self.reporter, self.images)
        if displaced and has_surface:  # Cycles: has_bump_from_displacement needs a linked Surface too
            self._bind_displacement(material, output, reader.program)
        surface = surface_terms(reader, _shader_node, surface_socket)
        program = None
        emission = surface.emission
        try:
            if surface.emission_regs:  # emission driven by nodes: the program's, weighed by its estimate
                for reg in surface.emission_regs:
                    reader.program.add_emission(reg)
                if np.any(surface.emission != 0):
                    reader.program.add_emission(reader.program.const(list(surface.emission)))
                emission = surface.emitted_estimate()
            program = reader.program.program(surface.nodes, surface.bindings)
        except (KeyError, ValueError, TypeError, AttributeError) as error:
            self.reporter.warn(f"material '{name}': its textured inputs could not be compiled ({error}); "
                               "the inputs' own values are used")
        if program is not None:
            self.corner_requests[len(self.materials)] = reader.program.requested_attributes()
        return vp.Material(name=name, surface="diffuse", base_color=np.zeros(3), emission=emission,
                           medium=medium, surface_nodes=surface.nodes, surface_program=program)

    def _bind_displacement(self, material, output, program) -> None:
        """The Displacement output as a bump (surface_programs.bind_displacement). Cycles bumps for
        "Bump Only" (the default) and, in object space, for "Displacement and Bump", and moves the
        vertices for the other two (scene/shader.cpp has_bump_from_displacement); VolPath never
        moves vertices, so every method renders as "Bump Only", warned."""
        name = material.name_full
        method = getattr(material, "displacement_method", "BUMP")
        if method != "BUMP":
            self.reporter.warn(f"material '{name}': displacement method '{method}' moves the vertices in Cycles; "
                               "VolPath has no true displacement and renders it as 'Bump Only'")
        try:
            program.bind_displacement(output)
        except (KeyError, ValueError, TypeError, AttributeError) as error:
            self.reporter.warn(f"material '{name}': node '{output.name}': the Displacement output could not be "
                               f"compiled ({error}); rendered without displacement")


def _volume_program_of(owner: str, socket, reporter):
    """The volume closures feeding `socket` compiled to a shader program, or None when the tree
    cannot be compiled (the constant reading of _volume_from then applies, with its warnings)."""
    quiet = Reporter()  # the constant path repeats what matters; keep the compiler's own notes
    try:
        program = ShaderCompiler(owner, quiet).compile_volume(socket)
    except (KeyError, ValueError, TypeError, AttributeError) as error:
        reporter.warn(f"{owner}: its volume nodes could not be compiled ({error}); read as constants")
        return None
    if program.varying:
        for message in quiet.messages:
            reporter.warn(message)
    return program


def export_world(world, table: MaterialTable) -> vp.World:
    """World background radiance (Background colour x strength) and the world volume."""
    if world is None:
        return vp.World()
    tree = compat.world_node_tree(world)
    if tree is None:
        return vp.World(background=np.array(world.color[:3]))
    reporter = table.reporter
    # World > Ray Visibility (Cycles' world.cycles_visibility), when the Cycles add-on is present.
    visibility = getattr(world, "cycles_visibility", None)
    if visibility is not None:
        hidden = [flag for flag in ("camera", "diffuse", "scatter") if not getattr(visibility, flag)]
        if hidden:
            reporter.warn(f"world '{world.name_full}': ray visibility off for {', '.join(hidden)} is not "
                          "supported; the background is visible to all rays")
    reader = NodeReader(f"world '{world.name_full}'", reporter)
    output = tree.get_output_node("CYCLES")
    if output is None:
        reporter.warn(f"world '{world.name_full}': no active World Output node; black background")
        return vp.World()
    background = np.zeros(3)
    source = _source_socket(output.inputs["Surface"])
    if source is not None and not source.node.mute:
        node = source.node
        if node.type == "BACKGROUND":
            # Background radiance = colour x strength (kernel/closure/emissive.h background_setup).
            background = reader.rgb(node, "Color") * reader.scalar(node, "Strength")
        else:
            reader.warn(node, "unsupported world surface shader; black background")
    medium = -1
    volume_socket = output.inputs["Volume"]
    program = (_volume_program_of(f"world '{world.name_full}'", volume_socket, reporter)
               if _source_socket(volume_socket) is not None else None)
    if program is not None and program.varying:
        # bounded like Cycles' world octree; placed once the scene's extent is known (export/__init__)
        table.procedural.world_program = program
        return vp.World(background=background, medium=-1)
    volume = _volume_from(reader, volume_socket)
    if not volume.is_empty:
        table.media.append(_medium_from(f"world '{world.name_full}'", volume))
        medium = len(table.media) - 1
    return vp.World(background=background, medium=medium)
