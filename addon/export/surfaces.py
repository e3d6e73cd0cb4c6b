"""Blender surface shader nodes -> VolPath SurfaceNode lists (one per BSDF node, with its mix weight).

The tree is read, not executed: closures combine linearly (Add Shader; Mix Shader with a constant
factor), so a surface is a weighted list of BSDF nodes plus an emission. The kernel side
(volpath_native.bsdfs) expands each node into lobes at the hit exactly as Cycles'
svm_node_closure_bsdf does (intern/cycles/kernel/svm/closure.h), including the Principled
layering that depends on the view direction, so the exporter only copies the node's inputs.

Supported: Principled, Diffuse, Glossy (Anisotropic), Glass, Refraction, Metallic (4.3+),
Transparent, Translucent, Sheen (4.0+), Emission, Add / Mix Shader, Holdout (black, warned).
Documented fallbacks, each warned naming material and node: an unsupported BSDF renders as a 0.8
grey diffuse surface; subsurface scattering renders as the diffuse layer (Cycles' random walk is
not implemented). Anisotropic BSDFs get their tangent from the material's surface program (the
Tangent input, else Cycles' radial default); emission driven by nodes is the program's emission.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from volpath_native.bsdfs.nodes import SurfaceNode

from .. import compat
from .surface_programs import scale_bound_weights, scale_weights

# Cycles' surface for objects without a material is a default Principled BSDF (scene/shader.cpp
# ShaderManager::add_default).
DEFAULT_GREY = 0.8

_DISTRIBUTIONS = {"MULTI_GGX": "multi_ggx", "GGX": "ggx", "BECKMANN": "beckmann",
                  "ASHIKHMIN_SHIRLEY": "ggx", "SHARP": "ggx"}


@dataclass
class SurfaceTerms:
    """A weighted list of BSDF nodes and the emitted radiance (W/(m^2 sr), both faces).
    bindings: (node index, field, register) of inputs a surface program drives
    (surface_programs.py); program: that program's compiler, or None (constants only).
    emission_regs: registers (3 each) of emission driven by nodes, already weighted, added to
    the constant `emission`; emission_estimate: their size for light selection, as Cycles'
    Shader::estimate_emission (a linked colour or strength counts 1)."""

    nodes: list = field(default_factory=list)
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bindings: list = field(default_factory=list)
    program: object = None
    emission_regs: list = field(default_factory=list)
    emission_estimate: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def scaled(self, w: float) -> "SurfaceTerms":
        regs = self.emission_regs
        if regs and w != 1.0:
            factor = self.program.const(float(w))
            regs = [self.program.scale3(r, factor) for r in regs]
        return SurfaceTerms([_reweighted(n, n.weight * w) for n in self.nodes], self.emission * w,
                            scale_bound_weights(self.program, self.bindings, w), self.program, regs,
                            self.emission_estimate * w)

    def weighted_by(self, program, factor_reg: int) -> "SurfaceTerms":
        """Every node's weight and the emission times a register (a varying Mix Shader factor);
        the emission estimate stays unweighted (Cycles' estimate for a linked factor)."""
        regs = [program.scale3(r, factor_reg) for r in self.emission_regs]
        estimate = self.emission_estimate
        if np.any(self.emission > 0):
            regs.append(program.scale3(program.const(list(self.emission)), factor_reg))
            estimate = estimate + self.emission
        return SurfaceTerms(list(self.nodes), np.zeros(3), scale_weights(program, self.nodes, self.bindings,
                                                                         factor_reg), program, regs, estimate)

    def __add__(self, other: "SurfaceTerms") -> "SurfaceTerms":
        shift = len(self.nodes)
        return SurfaceTerms(self.nodes + other.nodes, self.emission + other.emission,
                            self.bindings + [(i + shift, f, r) for i, f, r in other.bindings],
                            self.program or other.program, self.emission_regs + other.emission_regs,
                            self.emission_estimate + other.emission_estimate)

    def emitted_estimate(self) -> np.ndarray:
        """What weighs this material's mesh lights: the constant emission plus the estimate."""
        return self.emission + self.emission_estimate


def _reweighted(node: SurfaceNode, weight: float) -> SurfaceNode:
    copy = node.copy()
    copy.weight = weight
    return copy


def _distribution(reader, node, allowed=("multi_ggx", "ggx", "beckmann")) -> str:
    name = getattr(node, "distribution", "GGX")
    value = _DISTRIBUTIONS.get(name)
    if value is None or value not in allowed:
        value = "ggx"
        reader.warn(node, f"microfacet distribution {name} is not supported; rendered as GGX")
    if name in ("ASHIKHMIN_SHIRLEY", "SHARP"):
        reader.warn(node, f"microfacet distribution {name} is rendered as GGX")
    return value


def _emission_terms(reader, node, color: str, strength: str, alpha: str = "") -> SurfaceTerms:
    """An emitting node's radiance color x strength (x alpha): constant, or a program's when any
    input varies (Cycles' output_estimate_emission for the estimate)."""
    program = getattr(reader, "program", None)
    sockets = [node.inputs.get(name) for name in (color, strength, alpha) if name]
    if program is None or not any(program.is_varying(s) for s in sockets if s is not None):
        value = reader.rgb(node, color) * reader.scalar(node, strength)
        if alpha:
            value = value * float(np.clip(reader.scalar(node, alpha), 0.0, 1.0))
        return SurfaceTerms(emission=value)
    color_varies, strength_varies = program.is_varying(node.inputs[color]), program.is_varying(node.inputs[strength])
    if (not strength_varies and reader.scalar(node, strength) == 0.0) or \
            (not color_varies and not np.any(reader.rgb(node, color) != 0.0)):
        return SurfaceTerms()  # emits nothing wherever the other inputs vary
    estimate = np.ones(3) if color_varies else reader.rgb(node, color)
    if not program.is_varying(node.inputs[strength]):
        estimate = estimate * reader.scalar(node, strength)
    try:
        reg = program.emission_of(node, color, strength, alpha)
    except (KeyError, ValueError, TypeError, AttributeError) as error:
        reader.warn(node, f"its emission could not be compiled ({error}); the inputs' own values are used")
        return SurfaceTerms(emission=reader.rgb(node, color) * reader.scalar(node, strength))
    return SurfaceTerms(program=program, emission_regs=[reg], emission_estimate=np.maximum(estimate, 0.0))


def _warn_linked(reader, node, names):
    program = getattr(reader, "program", None)
    for name in names:
        socket = node.inputs.get(name)
        if name == "Normal" and program is not None and program.bind_normal(node, name):
            continue  # compiled: the closures' normal (surface_programs.py)
        if socket is not None and socket.is_linked:
            reader.warn(node, f"input '{name}' is linked; VolPath does not evaluate normal/tangent "
                              "inputs yet and uses the interpolated normal")


def _anisotropy(reader, node, name) -> float:
    """The node's anisotropy; when it may be non-zero, the material's program computes the
    tangent (Tangent input, else Cycles' radial default: SurfaceProgramCompiler.bind_tangent)."""
    socket = node.inputs.get(name)
    value = reader.scalar(node, socket) if socket is not None else 0.0
    program = getattr(reader, "program", None)
    varying = program is not None and program.is_varying(socket)
    if value == 0.0 and not varying:
        return 0.0
    if program is None:
        reader.warn(node, f"{name} {value:g}: anisotropy needs the material's tangents, rendered isotropic")
        return 0.0
    try:
        program.bind_tangent(node)
    except (KeyError, ValueError, TypeError, AttributeError) as error:
        reader.warn(node, f"its Tangent could not be compiled ({error}); rendered isotropic")
        return 0.0
    return value


def _rotation(reader, node, name) -> float:
    socket = node.inputs.get(name)
    return reader.scalar(node, socket) if socket is not None else 0.0


def surface_terms(reader, shader_node_of, socket) -> SurfaceTerms:
    """The surface closures feeding `socket`; black (no terms) if nothing is connected.
    shader_node_of(socket) -> the unmuted node feeding it, or None (shading._shader_node)."""
    node = shader_node_of(socket)
    if node is None:
        return SurfaceTerms()
    kind = node.type
    if kind == "ADD_SHADER":
        return (surface_terms(reader, shader_node_of, node.inputs[0])
                + surface_terms(reader, shader_node_of, node.inputs[1]))
    if kind == "MIX_SHADER":
        program = getattr(reader, "program", None)
        if program is not None and program.is_varying(node.inputs[0]):
            # a varying factor: the node weights and emissions become program registers
            # (svm_node_mix_closure)
            a, b = program.mix_weights(node)
            first = surface_terms(reader, shader_node_of, node.inputs[1])
            second = surface_terms(reader, shader_node_of, node.inputs[2])
            return first.weighted_by(program, a) + second.weighted_by(program, b)
        f = float(np.clip(reader.scalar(node, node.inputs[0]), 0.0, 1.0))
        return (surface_terms(reader, shader_node_of, node.inputs[1]).scaled(1.0 - f)
                + surface_terms(reader, shader_node_of, node.inputs[2]).scaled(f))
    if kind == "EMISSION":
        # Emission closure radiance = colour x strength, both faces (kernel/closure/emissive.h).
        return _emission_terms(reader, node, "Color", "Strength")
    if kind == "HOLDOUT":
        reader.warn(node, "Holdout is rendered as a black surface (no alpha holdout in the film)")
        return SurfaceTerms()
    converter = _CONVERTERS.get(kind)
    if converter is None:
        reader.warn(node, f"unsupported surface shader; rendered as a {DEFAULT_GREY} grey diffuse surface")
        return SurfaceTerms([SurfaceNode.for_kind("diffuse", color=np.full(3, DEFAULT_GREY))])
    terms = converter(reader, node)
    program = getattr(reader, "program", None)
    if program is not None and len(terms.nodes) == 1:
        terms.program = program
        program.bind_inputs(node, terms)
    return terms


def _diffuse(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    return SurfaceTerms([SurfaceNode(kind="diffuse", color=reader.rgb(node, "Color"),
                                     roughness=reader.scalar(node, "Roughness"))])


def _glossy(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    return SurfaceTerms([SurfaceNode(kind="glossy", color=reader.rgb(node, "Color"),
                                     roughness=reader.scalar(node, "Roughness"),
                                     anisotropic=_anisotropy(reader, node, "Anisotropy"),
                                     anisotropic_rotation=_rotation(reader, node, "Rotation"),
                                     distribution=_distribution(reader, node))])


def _glass(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    _thin_film(reader, node)
    return SurfaceTerms([SurfaceNode(kind="glass", color=reader.rgb(node, "Color"),
                                     roughness=reader.scalar(node, "Roughness"), ior=reader.scalar(node, "IOR"),
                                     distribution=_distribution(reader, node))])


def _refraction(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    return SurfaceTerms([SurfaceNode(kind="refraction", color=reader.rgb(node, "Color"),
                                     roughness=reader.scalar(node, "Roughness"), ior=reader.scalar(node, "IOR"),
                                     distribution=_distribution(reader, node, ("ggx", "beckmann")))])


def _metallic(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    _thin_film(reader, node)
    physical = getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR"
    values = dict(kind="metallic", roughness=reader.scalar(node, "Roughness"),
                  anisotropic=_anisotropy(reader, node, "Anisotropy"),
                  anisotropic_rotation=_rotation(reader, node, "Rotation"),
                  fresnel="physical" if physical else "f82", distribution=_distribution(reader, node))
    # the evaluated node only has the sockets of its Fresnel mode
    if physical:
        values.update(conductor_n=reader.rgb(node, "IOR"), conductor_k=reader.rgb(node, "Extinction"))
    else:
        values.update(color=reader.rgb(node, "Base Color"), edge_tint=reader.rgb(node, "Edge Tint"))
    return SurfaceTerms([SurfaceNode(**values)])


def _transparent(reader, node) -> SurfaceTerms:
    return SurfaceTerms([SurfaceNode.for_kind("transparent", color=reader.rgb(node, "Color"))])


def _translucent(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    return SurfaceTerms([SurfaceNode.for_kind("translucent", color=reader.rgb(node, "Color"))])


def _sheen(reader, node) -> SurfaceTerms:
    _warn_linked(reader, node, ("Normal",))
    if node.inputs.get("Roughness") is None:  # Blender 3.x Velvet BSDF: Sigma plays the roughness
        reader.warn(node, "Velvet BSDF is rendered as Cycles 4's Sheen BSDF with roughness = Sigma")
        roughness = reader.scalar(node, "Sigma")
    else:
        roughness = reader.scalar(node, "Roughness")
    return SurfaceTerms([SurfaceNode(kind="sheen", color=reader.rgb(node, "Color"), roughness=roughness)])


def _thin_film(reader, node):
    socket = node.inputs.get("Thin Film Thickness")
    if socket is not None and reader.scalar(node, socket) > 0.1:
        reader.warn(node, "thin-film interference is not supported; rendered without it")


def _principled(reader, node) -> SurfaceTerms:
    """Principled BSDF inputs as Blender 4+ names them (Blender 3.x's v1 node is mapped onto them:
    Specular -> Specular IOR Level, Clearcoat -> Coat, Sheen -> Sheen weight, warned)."""
    def value(key, default):
        socket = compat.principled_socket(node, key)
        if socket is None:
            return default
        return reader.rgb(node, socket) if isinstance(default, np.ndarray) else reader.scalar(node, socket)

    _warn_linked(reader, node, ("Normal", "Coat Normal", "Clearcoat Normal"))
    _thin_film(reader, node)
    if node.inputs.get("Specular IOR Level") is None:
        reader.warn(node, "Principled BSDF v1 (Blender < 4.0) is mapped onto the v2 layers "
                          "(Specular -> IOR Level, Clearcoat -> Coat); Cycles of this Blender differs")
    subsurface = value("subsurface", 0.0)
    if subsurface > 0.0:
        reader.warn(node, f"Subsurface Weight {subsurface:g}: subsurface scattering is rendered as diffuse")
    white = np.ones(3)
    specular_tint = value("specular_tint", white)
    if node.inputs.get("Specular IOR Level") is None:
        specular_tint = white  # v1's Specular Tint is a float blend toward the base colour
    sheen_tint = value("sheen_tint", white)
    if node.inputs.get("Sheen Weight") is None:
        sheen_tint = white
    terms = SurfaceNode(
        kind="principled", color=value("base_color", np.full(3, 0.8)), metallic=value("metallic", 0.0),
        roughness=value("roughness", 0.5), ior=value("ior", 1.5), alpha=value("alpha", 1.0),
        diffuse_roughness=value("diffuse_roughness", 0.0), specular_ior_level=value("specular", 0.5),
        specular_tint=specular_tint, transmission=value("transmission", 0.0),
        coat_weight=value("coat", 0.0), coat_roughness=value("coat_roughness", 0.03), coat_ior=value("coat_ior", 1.5),
        coat_tint=value("coat_tint", white), sheen_weight=value("sheen", 0.0),
        sheen_roughness=value("sheen_roughness", 0.5), sheen_tint=sheen_tint,
        anisotropic=_anisotropy(reader, node, "Anisotropic"),
        anisotropic_rotation=_rotation(reader, node, "Anisotropic Rotation"), subsurface_weight=subsurface,
        distribution=_distribution(reader, node, ("multi_ggx", "ggx")))
    # Emission is added with the weight left after alpha (svm/closure.h principled emission);
    # Cycles also attenuates it by the sheen and coat albedo seen from the viewer, which VolPath
    # does not (the light sampler needs a view-independent emitter): README, knowingly differs.
    color_socket = compat.principled_socket(node, "emission_color")
    strength_socket = compat.principled_socket(node, "emission_strength")
    alpha_socket = compat.principled_socket(node, "alpha")
    if color_socket is None or strength_socket is None:
        emitted = SurfaceTerms()
    else:
        emitted = _emission_terms(reader, node, color_socket.name, strength_socket.name,
                                  alpha_socket.name if alpha_socket is not None else "")
    if (np.any(emitted.emitted_estimate() > 0)) and (terms.coat_weight > 0 or terms.sheen_weight > 0):
        reader.warn(node, "emission under coat or sheen is not attenuated by them (Cycles attenuates it)")
    return SurfaceTerms([terms], emitted.emission, emission_regs=emitted.emission_regs,
                        emission_estimate=emitted.emission_estimate, program=emitted.program)


_CONVERTERS = {
    "BSDF_PRINCIPLED": _principled, "BSDF_DIFFUSE": _diffuse, "BSDF_GLOSSY": _glossy,
    "BSDF_ANISOTROPIC": _glossy, "BSDF_GLASS": _glass, "BSDF_REFRACTION": _refraction,
    "BSDF_METALLIC": _metallic, "BSDF_TRANSPARENT": _transparent, "BSDF_TRANSLUCENT": _translucent,
    "BSDF_SHEEN": _sheen, "BSDF_VELVET": _sheen,
}
