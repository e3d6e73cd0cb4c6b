"""Varying BSDF inputs of one material -> a volpath_native SurfaceProgram.

surfaces.py reads every BSDF node's inputs as constants; for a material with this compiler, an
input linked to anything that is not a constant (an Image Texture, a Noise Texture, a Color
Attribute, Math between them...) is compiled instead, with the one shader compiler of the
volumes (shader_compiler.ShaderCompiler plus the surface nodes of shader_nodes_surface.py), and
*bound* to the SurfaceNode field it drives: the kernel overwrites that field at every hit
(volpath_native.surface_programs). Mix Shader factors become bound node weights, a linked Normal
the closures' normal. Cycles does the same work in one SVM program per material
(scene/shader_graph.cpp, kernel/svm/svm.h).
"""
from __future__ import annotations

import numpy as np

from volpath_native.shading import program as P
from volpath_native.surface_programs import ACTIVE_UV, SurfaceProgram

from .shader_compiler import ShaderCompiler, _socket

# BSDF node type -> {socket name: SurfaceNode field} of the inputs a program may drive
# (Blender 4+/5 socket names; C5 scene/shader_nodes.cpp for what each closure reads)
BOUND_SOCKETS = {
    "BSDF_PRINCIPLED": {
        "Base Color": "color", "Metallic": "metallic", "Roughness": "roughness", "IOR": "ior", "Alpha": "alpha",
        "Diffuse Roughness": "diffuse_roughness", "Specular IOR Level": "specular_ior_level",
        "Specular Tint": "specular_tint", "Transmission Weight": "transmission", "Coat Weight": "coat_weight",
        "Coat Roughness": "coat_roughness", "Coat IOR": "coat_ior", "Coat Tint": "coat_tint",
        "Sheen Weight": "sheen_weight", "Sheen Roughness": "sheen_roughness", "Sheen Tint": "sheen_tint",
        "Subsurface Weight": "subsurface_weight", "Anisotropic": "anisotropic",
        "Anisotropic Rotation": "anisotropic_rotation"},
    "BSDF_DIFFUSE": {"Color": "color", "Roughness": "roughness"},
    "BSDF_GLOSSY": {"Color": "color", "Roughness": "roughness", "Anisotropy": "anisotropic",
                    "Rotation": "anisotropic_rotation"},
    "BSDF_ANISOTROPIC": {"Color": "color", "Roughness": "roughness", "Anisotropy": "anisotropic",
                         "Rotation": "anisotropic_rotation"},
    "BSDF_GLASS": {"Color": "color", "Roughness": "roughness", "IOR": "ior"},
    "BSDF_REFRACTION": {"Color": "color", "Roughness": "roughness", "IOR": "ior"},
    "BSDF_METALLIC": {"Base Color": "color", "Edge Tint": "edge_tint", "Roughness": "roughness",
                      "IOR": "conductor_n", "Extinction": "conductor_k", "Anisotropy": "anisotropic",
                      "Rotation": "anisotropic_rotation"},
    "BSDF_TRANSPARENT": {"Color": "color"},
    "BSDF_TRANSLUCENT": {"Color": "color"},
    "BSDF_SHEEN": {"Color": "color", "Roughness": "roughness"},
}
_COLOR_FIELDS = {"color", "specular_tint", "coat_tint", "sheen_tint", "edge_tint", "conductor_n", "conductor_k"}
# sockets whose variation VolPath cannot follow: warned, the socket's own value is used
_UNSUPPORTED = ("Thin Film Thickness", "Thin Film IOR", "Subsurface Radius", "Subsurface Scale")
# emission inputs compiled into the material's emission (surfaces.py emission_terms)
EMISSION_SOCKETS = {"EMISSION": ("Color", "Strength"), "BSDF_PRINCIPLED": ("Emission Color", "Emission Strength")}
# the anisotropy input of each BSDF with a Tangent input (closures read the tangent only when it is > 0)
ANISOTROPY_SOCKETS = {"BSDF_PRINCIPLED": "Anisotropic", "BSDF_GLOSSY": "Anisotropy", "BSDF_ANISOTROPIC": "Anisotropy",
                      "BSDF_METALLIC": "Anisotropy"}


class SurfaceShaderCompiler(ShaderCompiler):
    """ShaderCompiler at a surface hit: the surface nodes (images, UV maps, attributes, normal
    maps) and the surface meaning of Texture Coordinate / Geometry / Attribute."""

    context = "surface"

    def __init__(self, owner: str, reporter, images):
        super().__init__(owner, reporter)
        self.images = images
        self.inputs: list = []  # (attribute name, width, register)
        self.uses_uv = False  # reads the active-render UV map (R_UV)
        self.builder._varying.update(range(P.R_NG, P.R_NG + 3))
        self.builder._varying.add(P.R_BACKFACING)
        self.bump_offsets = -1  # registers of the bump offsets ex, ey (6), once a Bump node needs them
        self.shifts: dict = {}  # input name -> (input register, width, dx register, dy register)

    def emit(self, name: str, *operands: int):
        if name == "TEXCO" and operands[0] == P.TEXCO_UV:
            self.uses_uv = True
        super().emit(name, *operands)

    def attribute_input(self, name: str, width: int) -> int:
        """Registers the kernel fills with the hit's interpolated per-corner attribute `name`."""
        for existing, w, reg in self.inputs:
            if existing == name and w >= width:
                return reg
        reg = self.alloc(width)
        self.builder._varying.update(range(reg, reg + width))
        self.inputs.append((name, width, reg))
        return reg

    def shifted(self, compile_height, axis: int) -> int:
        """compile_height() (a register) compiled again with every hit input moved to P + ex
        (axis 0) or P + ey (axis 1): Cycles' SHADER_BUMP_DX / DY copies of the height subgraph
        (scene/shader_graph.cpp refine_bump_nodes). Inputs are swapped in around a fresh copy of
        the subgraph's nodes and swapped back after."""
        if self.bump_offsets < 0:
            self.bump_offsets = self.alloc(6)
            self.builder._varying.update(range(self.bump_offsets, self.bump_offsets + 6))
        rows = [("P", P.R_P, 3)] + ([("uv:", P.R_UV, 3)] if self.uses_uv else []) + \
            [(name, reg, width) for name, width, reg in self.inputs]
        swaps = []
        for name, reg, width in rows:
            if name not in self.shifts:
                dx, dy = self.alloc(width), self.alloc(width)
                self.builder._varying.update(range(dx, dx + width))
                self.builder._varying.update(range(dy, dy + width))
                self.shifts[name] = (reg, width, dx, dy)
            reg, width, dx, dy = self.shifts[name]
            swaps.append((width, reg, (dx, dy)[axis]))
        for width, reg, other in swaps:
            self.emit("SWAP", width, reg, other)
        saved, self._outputs = self._outputs, {}
        try:
            result = compile_height()
        finally:
            self._outputs = saved
            for width, reg, other in swaps:
                self.emit("SWAP", width, reg, other)
        return result

    def shift_list(self) -> list:
        return [(name, width, dx, dy) for name, (_, width, dx, dy) in self.shifts.items()]

    def _compile_node(self, node) -> dict:
        from .shader_nodes_surface import SURFACE_NODE_COMPILERS

        if not node.mute and node.type in SURFACE_NODE_COMPILERS:
            return SURFACE_NODE_COMPILERS[node.type](self, node)
        return super()._compile_node(node)

    def uv_vector(self, node, key="Vector") -> int:
        """An image node's vector: the linked value, else the active-render UV map (Cycles'
        ImageTextureNode attaches ATTR_STD_UV), through the node's hidden texture mapping."""
        return self.texture_vector(node, key, default=P.TEXCO_UV)


class SurfaceProgramCompiler:
    """Collects the bindings of one material while surfaces.py reads its BSDF nodes."""

    def __init__(self, owner: str, reporter, images):
        self.owner = owner
        self.reporter = reporter
        self.compiler = SurfaceShaderCompiler(owner, reporter, images)
        self.normal = -1
        self._normal_source = None
        self.tangent = -1
        self._tangent_source = None
        self.emission = -1  # register of the material's varying emission (3), once there is one
        self.shading_normal = -1  # R_N once a Displacement bump sets the shading normal

    # -- what surfaces.py asks ------------------------------------------------------------------
    def is_varying(self, socket) -> bool:
        """Linked to something other than a constant (RGB / Value nodes are read as constants)."""
        if socket is None or not socket.is_linked:
            return False
        source = self.compiler._source(socket)
        if source is None or isinstance(source, tuple):
            return False
        return source.node.type not in ("RGB", "VALUE")

    def handles(self, node, socket) -> bool:
        """Whether reading this socket as a constant is right because the program drives it."""
        name = socket.name
        if name in BOUND_SOCKETS.get(node.type, {}) or name == "Normal" or name in EMISSION_SOCKETS.get(node.type, ()):
            return self.is_varying(socket)
        if node.type == "MIX_SHADER" and socket == node.inputs[0]:
            return self.is_varying(socket)
        return False

    def bind_inputs(self, node, terms) -> None:
        """Compile node's varying inputs into terms.bindings (terms holds this node at index 0)."""
        for name, field in BOUND_SOCKETS.get(node.type, {}).items():
            socket = node.inputs.get(name)
            if socket is None or not socket.enabled or not self.is_varying(socket):
                continue
            try:
                reg = (self.compiler.color_input(node, name) if field in _COLOR_FIELDS
                       else self.compiler.float_input(node, name))
            except (KeyError, ValueError, TypeError, AttributeError) as error:
                self.reporter.warn(f"{self.owner}: node '{node.name}': input '{name}' could not be compiled "
                                   f"({error}); its own value is used")
                continue
            terms.bindings.append((0, field, reg))
        for name in _UNSUPPORTED:
            socket = node.inputs.get(name)
            if socket is not None and socket.enabled and self.is_varying(socket):
                self.reporter.warn(f"{self.owner}: node '{node.name}' ({node.bl_idname}): input '{name}' is driven "
                                   "by nodes VolPath does not evaluate for it; the input's own value is used")

    def bind_displacement(self, output) -> None:
        """The Material Output's Displacement as Cycles' "Bump Only" (C5 scene/shader_graph.cpp
        ShaderGraph::bump_from_displacement): the displacement vector at the hit and at the two
        moved points (SurfaceShaderCompiler.shifted, the Bump node's machinery), each dotted with
        the shading normal into a height, a Bump of Distance 1 and Strength 1 on the shading
        normal, and that normal set as the material's (SetNormalNode): every later read of the
        shading normal (BSDFs' default, Geometry, Bump / Normal Map inputs) sees it."""
        c = self.compiler
        saved, c._outputs = c._outputs, {}  # Cycles copies the subgraph: the surface reads its own nodes
        try:
            centre = c.vector_input(output, "Displacement")
        finally:
            c._outputs = saved
        moved = [c.shifted(lambda: c.vector_input(output, "Displacement"), axis) for axis in (0, 1)]
        heights = []
        for vector in [centre] + moved:
            unused, height = c.alloc(3), c.alloc()
            c.emit("VECTOR_MATH", P.VECTOR_MATH["DOT_PRODUCT"], vector, P.R_N, P.R_N, c.const(1.0), unused, height)
            heights.append(height)
        normal = c.alloc(3)
        one = c.const(1.0)  # Distance 1 (set_distance), Strength and Filter Width BumpNode's defaults
        c.emit("BUMP", 0, P.R_N, one, one, c.const(0.1), *heights, c.bump_offsets, c.bump_offsets + 3, normal)
        c.emit("COPY", 3, normal, P.R_N)
        self.normal = normal
        self._normal_source = ("displacement",)
        self.shading_normal = P.R_N

    def bind_normal(self, node, name="Normal") -> bool:
        """Compile a linked Normal input as the material's closure normal (True if taken)."""
        socket = node.inputs.get(name)
        if socket is None or not self.is_varying(socket):
            return False
        source = self.compiler._source(socket)
        key = (source.node.name, source.identifier)
        if self._normal_source == ("displacement",):  # its default normal is the displaced one
            self.normal = -1
        if self.normal >= 0:
            if key != self._normal_source:
                self.reporter.warn(f"{self.owner}: node '{node.name}': input '{name}' differs from another BSDF's "
                                   "normal; VolPath uses one normal per material (the first)")
            return True
        self.normal = self.compiler.vector_input(node, name)
        self._normal_source = key
        return True

    def bind_tangent(self, node, name="Tangent") -> None:
        """The anisotropic closures' tangent: the linked Tangent input, else Cycles' default
        (scene/shader_graph.cpp default_inputs: Geometry > Tangent, the radial Z tangent of the
        Generated coordinates, geom/primitive.h primitive_tangent). One per material."""
        socket = node.inputs.get(name)
        linked = socket is not None and self.compiler._source(socket) is not None
        source = self.compiler._source(socket) if linked else None
        key = ("default",) if source is None else (repr(source),) if isinstance(source, tuple) else \
            (source.node.name, source.identifier)
        if self.tangent >= 0:
            if key != self._tangent_source:
                self.reporter.warn(f"{self.owner}: node '{node.name}': input '{name}' differs from another BSDF's "
                                   "tangent; VolPath uses one tangent per material (the first)")
            return
        if source is None:
            from .shader_nodes_surface import radial_tangent

            self.tangent = radial_tangent(self.compiler, P.TANGENT_RADIAL_Z)
        else:
            self.tangent = self.compiler.vector_input(node, name)
        self._tangent_source = key

    def add_emission(self, reg: int) -> None:
        """Add a varying emission (3 registers, radiance) to the material's."""
        if self.emission < 0:
            self.emission = reg
            return
        out, unused = self.compiler.alloc(3), self.compiler.alloc()
        self.compiler.emit("VECTOR_MATH", P.VECTOR_MATH["ADD"], self.emission, reg, reg, self.const(1.0), out, unused)
        self.emission = out

    def emission_of(self, node, color: str, strength: str, alpha: str = "") -> int:
        """Registers of color x strength (x saturate(alpha)) of an emitting node."""
        c = self.compiler
        out = self.scale3(c.color_input(node, color), c.float_input(node, strength))
        if alpha:
            clamped = c.alloc()
            c.emit("CLAMP", 0, c.float_input(node, alpha), c.const(0.0), c.const(1.0), clamped)
            out = self.scale3(out, clamped)
        return out

    def scale3(self, reg: int, factor_reg: int) -> int:
        out, unused = self.compiler.alloc(3), self.compiler.alloc()
        self.compiler.emit("VECTOR_MATH", P.VECTOR_MATH["SCALE"], reg, reg, reg, factor_reg, out, unused)
        return out

    def mix_weights(self, node) -> tuple:
        """Registers (1 - f, f) of a Mix Shader's varying factor, clamped as svm_node_mix_closure."""
        a, b = self.compiler.alloc(), self.compiler.alloc()
        self.compiler.emit("MIX_WEIGHTS", self.compiler.const(1.0), self.compiler.float_input(node, 0), a, b)
        return a, b

    def multiply(self, reg_a: int, reg_b: int) -> int:
        out = self.compiler.alloc()
        self.compiler.emit("MATH", P.MATH["MULTIPLY"], reg_a, reg_b, reg_b, out)
        return out

    def const(self, value) -> int:
        return self.compiler.const(value)

    # -- result -----------------------------------------------------------------------------------
    def program(self, nodes: list, bindings: list):
        """The SurfaceProgram of the material (None when nothing varies)."""
        if not bindings and self.normal < 0 and self.tangent < 0 and self.emission < 0:
            return None
        program = self.compiler.builder.build()
        return SurfaceProgram(program, list(bindings), list(self.compiler.inputs), self.normal, self.tangent,
                              self.emission, self.compiler.bump_offsets, self.compiler.shift_list(),
                              self.shading_normal)

    def requested_attributes(self) -> set:
        names = {name for name, _, _ in self.compiler.inputs} | {n for n in self.compiler.shifts if n != "P"}
        return names | {ACTIVE_UV} if self.compiler.uses_uv else names


def weight_register(program: SurfaceProgramCompiler, bindings: list, index: int, weight: float) -> int:
    """The register holding node `index`'s weight: its bound one, else the constant."""
    for i, field, reg in bindings:
        if i == index and field == "weight":
            return reg
    return program.const(float(weight))


def scale_weights(program, nodes: list, bindings: list, factor_reg: int) -> list:
    """Bindings with every node's weight multiplied by register factor_reg."""
    kept = [b for b in bindings if b[1] != "weight"]
    for index, node in enumerate(nodes):
        kept.append((index, "weight", program.multiply(weight_register(program, bindings, index, node.weight),
                                                       factor_reg)))
    return kept


def scale_bound_weights(program, bindings: list, w: float) -> list:
    """Bindings after a constant factor w on every node (bound weights scaled too)."""
    if program is None or not any(b[1] == "weight" for b in bindings):
        return list(bindings)
    c = program.const(float(w))
    return [(i, f, program.multiply(r, c)) if f == "weight" else (i, f, r) for i, f, r in bindings]


_ = np
