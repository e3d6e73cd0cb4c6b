"""Blender node trees -> shader programs (volpath_native.shading), as Cycles' SVM compiler does.

    compiler = ShaderCompiler("material 'Fog'", reporter)
    program = compiler.compile_volume(output.inputs["Volume"])

Each node reached from the output is compiled once (its outputs' registers cached); node groups are
compiled inline with their Group Input bound to the group node's inputs; reroutes and muted nodes
are followed as Blender does (a muted node passes its first matching input through). Sockets are
converted between float, vector and colour as Cycles' ShaderGraph conversion nodes do
(scene/shader_graph.cpp: colour -> float is luminance, vector -> float the average, float ->
vector/colour a splat). Nodes without an opcode are named in a warning and read as their output
sockets' default values (0 / black).

Texture nodes come from shader_nodes_textures.TEXTURE_NODE_COMPILERS (the textures/ package of the
renderer); everything else is here.
"""
from __future__ import annotations

import numpy as np

from volpath_native.shading import program as P
from volpath_native.shading.builder import ProgramBuilder

# Luminance weights of Blender's scene-linear space, Cycles' rgb_to_y (C5 scene/shader.cpp
# ShaderManager::init_xyz_transforms): the Y row of inverse(xyz_to_rgb), where xyz_to_rgb =
# (Blender 5.0 config.ocio: Linear Rec.709 from XYZ D65) x (OCIO builtin ACES-AP0_to_CIE-XYZ-D65_BFD)
# x inverse(Cycles' 6-decimal copy of that builtin). Not Cycles' no-OCIO fallback (0.2126729,
# 0.7151522, 0.0721750), which differs by 3e-5; measured against Cycles in tests/shading.
LUMINANCE = (0.2126390946, 0.7151691213, 0.0721927524)
# Blender's own colour -> float conversion (IMB_colormanagement_get_luminance: config.ocio's luma),
# used where Blender, not Cycles, converts: values of unlinked group inputs written into the
# inlined group.
BLENDER_LUMA = (0.2126, 0.7152, 0.0722)

_FLOAT_TYPES = ("VALUE", "INT", "BOOLEAN")


class ShaderCompiler:
    """Compiles one material's (or world's) node tree; warnings go to reporter.warn(message)."""

    def __init__(self, owner: str, reporter, attributes=frozenset()):
        self.owner = owner
        self.reporter = reporter
        self.available_attributes = frozenset(attributes)  # grid names the evaluating object has
        self.builder = ProgramBuilder(owner)
        self._outputs: dict = {}  # (group path, node name) -> {output identifier: register}
        self._group_stack: list = []  # group nodes being compiled (innermost last)
        self._lobes = 0

    # ------------------------------------------------------------------------------------------
    # Builder access for node compile functions (shader_nodes_textures uses these)
    # ------------------------------------------------------------------------------------------
    def alloc(self, n: int = 1) -> int:
        return self.builder.alloc(n)

    def const(self, value) -> int:
        return self.builder.const(value)

    def emit(self, name: str, *operands: int):
        self.builder.emit(name, *operands)

    def table(self, values) -> int:
        return self.builder.table(values)

    def warn(self, node, message: str):
        self.reporter.warn(f"{self.owner}: node '{node.name}' ({node.bl_idname}): {message}")

    # ------------------------------------------------------------------------------------------
    # Sockets
    # ------------------------------------------------------------------------------------------
    def float_input(self, node, key) -> int:
        return self._input(node, key, "float")

    def vector_input(self, node, key) -> int:
        return self._input(node, key, "vector")

    def color_input(self, node, key) -> int:
        return self._input(node, key, "color")

    def texture_vector(self, node, key="Vector", default=P.TEXCO_GENERATED) -> int:
        """A texture node's vector: the linked value, else the `default` texture coordinate
        (Generated: Cycles' LINK_TEXTURE_GENERATED), through the node's hidden texture mapping if
        it is not identity."""
        socket = _socket(node.inputs, key)
        if socket is not None and self._source(socket) is not None:
            vector = self.vector_input(node, key)
        else:
            vector = self.alloc(3)
            self.emit("TEXCO", default, vector)
        mapping = getattr(node, "texture_mapping", None)
        if mapping is not None and not _identity_mapping(mapping):
            out = self.alloc(3)
            kinds = {"POINT": 0, "TEXTURE": 1, "VECTOR": 2, "NORMAL": 3}
            self.emit("MAPPING", kinds.get(mapping.vector_type, 0), vector, self.const(list(mapping.translation)),
                      self.const(list(mapping.rotation)), self.const(list(mapping.scale)), out)
            vector = out
        return vector

    def _input(self, node, key, kind: str) -> int:
        socket = _socket(node.inputs, key)
        if socket is None:
            raise KeyError(f"node '{node.name}' has no input {key!r}")
        source = self._source(socket)
        if source is None:
            return self._constant(node, socket, kind)
        if isinstance(source, tuple) and source[0] == "constant":
            # an unlinked group-node input: Blender inlines the group and writes the value into the
            # inner socket with its own conversion (colour -> float by the config's luma)
            _, group, outer, _ = source
            return self._constant(group, outer, kind, BLENDER_LUMA)
        reg, source_kind = self.output(source)
        return self._convert(reg, source_kind, kind)

    def _constant(self, node, socket, kind: str, luminance=LUMINANCE) -> int:
        value = getattr(socket, "default_value", 0.0)
        try:
            values = np.array(value[:], dtype=np.float64).reshape(-1)
        except TypeError:
            values = np.array([float(value)])
        if not np.all(np.isfinite(values)):
            self.warn(node, f"input '{socket.name}' is not finite ({values.tolist()}); read as 0")
            values = np.nan_to_num(values, nan=0.0, posinf=3.4028234663852886e38, neginf=-3.4028234663852886e38)
        source_kind = "float" if values.size == 1 else ("color" if socket.type == "RGBA" else "vector")
        if source_kind == "color" and kind == "float":
            return self.const(float(np.dot(values[:3], luminance)))
        return self._convert(self.const(values[:3] if values.size >= 3 else values[:1]), source_kind, kind)

    def _convert(self, reg: int, source: str, target: str) -> int:
        if source == target or (source != "float" and target != "float"):
            return reg
        out = self.alloc(3 if target != "float" else 1)
        if target != "float":
            self.emit("FLOAT_TO_VECTOR", reg, out)
        elif source == "color":
            self.emit("COLOR_TO_FLOAT", reg, self.const(LUMINANCE), out)
        else:
            self.emit("VECTOR_TO_FLOAT", reg, out)
        return out

    def _source(self, socket):
        """What feeds an input: None (unlinked: the input's own value), an output socket of a node
        in the current group context, or a tuple for a source elsewhere --
          ("constant", group node, its input socket, stack): an unlinked group-node input;
          ("bound", socket, stack): an output socket in an enclosing group context.
        Reroutes and muted nodes are followed as Blender 5.0 inlines them before Cycles' sync
        (measured against Cycles in tests/shading/test_core_graph.py): a muted node's output is
        whatever feeds the input its internal link names, converted once from that source's type
        to this input's; an unlinked passed input or an output without an internal link leaves
        this input unlinked (its own value), as does an unlinked reroute."""
        for link in socket.links:
            if link.is_muted or not link.is_valid:
                continue
            source = link.from_socket
            node = source.node
            if node.type == "REROUTE":
                return self._source(node.inputs[0]) if node.inputs and node.inputs[0].is_linked else None
            if node.mute and node.type not in ("GROUP_INPUT", "GROUP_OUTPUT"):
                passed = next((internal.from_socket for internal in node.internal_links
                               if internal.to_socket.identifier == source.identifier), None)
                return self._source(passed) if passed is not None else None
            if node.type == "GROUP_INPUT":  # bound to the enclosing group node's input
                if not self._group_stack:
                    return None
                group = self._group_stack[-1]
                outer = _socket(group.inputs, source.identifier)
                if outer is None:
                    return None
                self._group_stack.pop()
                try:
                    found = self._source(outer)
                    if found is None:
                        return ("constant", group, outer, tuple(self._group_stack))
                    if isinstance(found, tuple):
                        return found
                    return ("bound", found, tuple(self._group_stack))
                finally:
                    self._group_stack.append(group)
            return source
        return None

    def output(self, source):
        """(register, kind) of what _source returned (compiling each node once per group context)."""
        if isinstance(source, tuple):
            saved = self._group_stack
            self._group_stack = list(source[-1])
            try:
                if source[0] == "constant":  # an unlinked group-node input
                    _, group, socket, _ = source
                    kind = _kind(socket)
                    return self._constant(group, socket, kind), kind
                return self.output(source[1])  # bound
            finally:
                self._group_stack = saved
        node = source.node
        key = (tuple(g.name for g in self._group_stack), node.name)
        if key not in self._outputs:
            self._outputs[key] = self._compile_node(node)
        outputs = self._outputs[key]
        kind = _kind(source)
        if source.identifier in outputs:
            return outputs[source.identifier], kind
        self.warn(node, f"output '{source.name}' is not evaluated by VolPath; read as 0")
        return self.const([0.0, 0.0, 0.0] if kind != "float" else 0.0), kind

    def _compile_node(self, node) -> dict:
        from .shader_nodes import NODE_COMPILERS
        from .shader_nodes_textures import TEXTURE_NODE_COMPILERS

        if node.mute:
            return self._muted(node)
        if node.type == "GROUP":
            return self._group(node)
        compile_fn = NODE_COMPILERS.get(node.type) or TEXTURE_NODE_COMPILERS.get(node.type)
        if compile_fn is None:
            self.warn(node, "not supported by VolPath; its outputs read as their default values")
            return {o.identifier: self._constant(node, o, _kind(o)) for o in node.outputs
                    if o.type in _FLOAT_TYPES + ("RGBA", "VECTOR")}
        return compile_fn(self, node)

    def _muted(self, node) -> dict:
        """Outputs of a muted node asked for directly (links into it are resolved by _source): the
        inputs its internal links name, converted to the output's type; others read 0."""
        outputs = {}
        for out in node.outputs:
            passed = next((internal.from_socket for internal in node.internal_links
                           if internal.to_socket.identifier == out.identifier), None)
            if passed is not None:
                outputs[out.identifier] = self._input(node, passed.identifier, _kind(out))
            elif out.type in _FLOAT_TYPES + ("RGBA", "VECTOR"):
                outputs[out.identifier] = self.const([0.0, 0.0, 0.0] if _kind(out) != "float" else 0.0)
        return outputs

    def _group(self, node) -> dict:
        tree = node.node_tree
        if tree is None or any(g.node_tree == tree for g in self._group_stack):
            self.warn(node, "empty or recursive node group; its outputs read as 0")
            return {}
        output = next((n for n in tree.nodes if n.type == "GROUP_OUTPUT" and n.is_active_output), None) \
            or next((n for n in tree.nodes if n.type == "GROUP_OUTPUT"), None)
        if output is None:
            return {}
        self._group_stack.append(node)
        try:
            outputs = {}
            for inner, outer in zip(output.inputs, node.outputs):
                if inner.type in _FLOAT_TYPES + ("RGBA", "VECTOR"):
                    outputs[outer.identifier] = self._input(output, inner.identifier, _kind(outer))
                elif inner.type == "SHADER":
                    outputs[outer.identifier] = ("shader", output, inner.identifier, tuple(self._group_stack))
            return outputs
        finally:
            self._group_stack.pop()

    # ------------------------------------------------------------------------------------------
    # Volume closures
    # ------------------------------------------------------------------------------------------
    def compile_volume(self, socket, weight: float = 1.0):
        """The program of the closures feeding a Volume output socket (ShaderProgram); weight scales
        every closure (Cycles' object_volume_density for Volume objects, 1 for meshes)."""
        self._volume(socket, self.const(float(weight)))
        return self.builder.build()

    def _volume(self, socket, weight: int):
        source = self._source(socket)
        if isinstance(source, tuple):
            if source[0] == "bound":
                saved = self._group_stack
                self._group_stack = list(source[-1])
                try:
                    self._volume_from(source[1], weight)
                finally:
                    self._group_stack = saved
            return
        if source is not None:
            self._volume_from(source, weight)

    def _volume_from(self, source, weight: int):
        node = source.node
        if node.type == "GROUP":
            key = (tuple(g.name for g in self._group_stack), node.name)
            if key not in self._outputs:
                self._outputs[key] = self._group(node)
            outputs = self._outputs[key]
            entry = outputs.get(source.identifier)
            if isinstance(entry, tuple) and entry[0] == "shader":
                _, output, identifier, stack = entry
                saved = self._group_stack
                self._group_stack = list(stack)
                try:
                    self._volume(_socket(output.inputs, identifier), weight)
                finally:
                    self._group_stack = saved
            return
        kind = node.type
        if kind == "ADD_SHADER":
            self._volume(node.inputs[0], weight)
            self._volume(node.inputs[1], weight)
        elif kind == "MIX_SHADER":
            a, b = self.alloc(), self.alloc()
            self.emit("MIX_WEIGHTS", weight, self.float_input(node, 0), a, b)
            self._volume(node.inputs[1], a)
            self._volume(node.inputs[2], b)
        elif kind == "PRINCIPLED_VOLUME":
            self._principled_volume(node, weight)
        elif kind == "VOLUME_SCATTER":
            self._check_phase(node)
            self.emit("VOLUME_SCATTER", self._lobe(node), weight, self.color_input(node, "Color"),
                      self.float_input(node, "Density"), self.float_input(node, "Anisotropy"))
        elif kind == "VOLUME_ABSORPTION":
            self.emit("VOLUME_ABSORPTION", weight, self.color_input(node, "Color"), self.float_input(node, "Density"))
        elif kind == "EMISSION":
            self.emit("VOLUME_EMISSION", weight, self.color_input(node, "Color"), self.float_input(node, "Strength"))
        elif kind == "VOLUME_COEFFICIENTS":
            self._check_phase(node)
            self.emit("VOLUME_COEFFICIENTS", self._lobe(node), weight, self.color_input(node, "Scatter Coefficients"),
                      self.color_input(node, "Absorption Coefficients"),
                      self.color_input(node, "Emission Coefficients"), self.float_input(node, "Anisotropy"))
        else:
            self.warn(node, "unsupported volume shader; it contributes no medium")

    def _lobe(self, node) -> int:
        if self._lobes >= P.MAX_LOBES:
            self.warn(node, f"more than {P.MAX_LOBES} scattering volume shaders; this one shares the last "
                            "one's phase function")
            return P.MAX_LOBES - 1
        self._lobes += 1
        return self._lobes - 1

    def _check_phase(self, node):
        phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
        if phase != "HENYEY_GREENSTEIN":
            self.warn(node, f"phase function {phase} is not supported; rendered as Henyey-Greenstein")

    def _principled_volume(self, node, weight: int):
        """svm_node_principled_volume (C5 kernel/svm/closure.h): Density x the density attribute,
        Color x the colour attribute and Temperature x max(temperature attribute, 0), each only if
        the object has that attribute (a mesh has none: the factors are 1)."""
        density = self.float_input(node, "Density")
        color = self.color_input(node, "Color")
        temperature = self.float_input(node, "Temperature")
        density_name = _attribute_name(node, "Density Attribute", "density")
        if density_name in self.available_attributes:
            attr = self._attribute(density_name, 1)
            product = self.alloc()
            self.emit("MATH", P.MATH["MULTIPLY"], density, attr, attr, product)
            density = product
        color_name = _attribute_name(node, "Color Attribute", "")
        if color_name and color_name in self.available_attributes:
            attr = self._attribute(color_name, 3)
            product = self.alloc(3)
            self.emit("VECTOR_MATH", P.VECTOR_MATH["MULTIPLY"], color, attr, attr, self.const(1.0), product,
                      self.alloc())
            color = product
        temperature_name = _attribute_name(node, "Temperature Attribute", "temperature")
        if temperature_name in self.available_attributes:
            attr = self._attribute(temperature_name, 1)
            clamped, product = self.alloc(), self.alloc()
            self.emit("MATH", P.MATH["MAXIMUM"], attr, self.const(0.0), attr, clamped)
            self.emit("MATH", P.MATH["MULTIPLY"], temperature, clamped, clamped, product)
            temperature = product
        self.emit("PRINCIPLED_VOLUME", self._lobe(node), weight, color, density, self.float_input(node, "Anisotropy"),
                  self.color_input(node, "Absorption Color"), self.float_input(node, "Emission Strength"),
                  self.color_input(node, "Emission Color"), self.float_input(node, "Blackbody Intensity"),
                  self.color_input(node, "Blackbody Tint"), temperature)

    def _attribute(self, name: str, width: int) -> int:
        out = self.alloc(3)
        self.emit("ATTRIBUTE", self.builder.attribute_channel(name, width), width, out)
        if width == 1:
            self.emit("COPY", 1, out, out + 1)
            self.emit("COPY", 1, out, out + 2)
        return out


# ----------------------------------------------------------------------------------------------
def _socket(sockets, key):
    """A socket by index, identifier or name (identifiers first: Mix nodes repeat names)."""
    if isinstance(key, int):
        return sockets[key] if key < len(sockets) else None
    for socket in sockets:
        if socket.identifier == key:
            return socket
    for socket in sockets:
        if socket.name == key and socket.enabled:
            return socket
    return sockets.get(key) if hasattr(sockets, "get") else None


def _kind(socket) -> str:
    if socket.type in _FLOAT_TYPES:
        return "float"
    return "color" if socket.type == "RGBA" else "vector"


def _attribute_name(node, socket_name: str, default: str) -> str:
    socket = node.inputs.get(socket_name)
    if socket is not None:
        return str(getattr(socket, "default_value", default) or "")
    return str(getattr(node, socket_name.lower().replace(" ", "_"), default) or "")


def _identity_mapping(mapping) -> bool:
    return (tuple(mapping.translation) == (0.0, 0.0, 0.0) and tuple(mapping.rotation) == (0.0, 0.0, 0.0)
            and tuple(mapping.scale) == (1.0, 1.0, 1.0) and getattr(mapping, "mapping_x", "X") == "X"
            and getattr(mapping, "mapping_y", "Y") == "Y" and getattr(mapping, "mapping_z", "Z") == "Z")
