"""Compile functions of the procedural texture nodes: node.type -> fn(c, node) -> {output identifier:
register}. `c` is the ShaderCompiler (shader_compiler.py); the opcodes and their operands are
volpath_native.shading.textures.ops, the arithmetic Cycles' SVM nodes (cited there).

As Cycles' TextureNode::compile (scene/shader_nodes.cpp): the vector of Noise, Voronoi, Gradient,
Wave and Magic is the Generated coordinate when unlinked (LINK_TEXTURE_GENERATED) through the
node's hidden texture mapping (c.texture_vector); White Noise has no such default (0, 0, 0).
Inputs a mode does not use (the vector of a 1D node, W of a 2D/3D one) are not compiled.
"""
from __future__ import annotations

from volpath_native.shading.textures.gradient import GRADIENT_TYPES
from volpath_native.shading.textures.noise import NOISE_TYPES
from volpath_native.shading.textures.voronoi import VORONOI_FEATURES, VORONOI_METRICS
from volpath_native.shading.textures.wave import BANDS_DIRECTIONS, RINGS_DIRECTIONS, WAVE_PROFILES, WAVE_TYPES

_DIMENSIONS = {"1D": 1, "2D": 2, "3D": 3, "4D": 4}


def _enum(c, node, table: dict, value: str, fallback: str) -> int:
    """table[value]; an unknown value (a newer Blender) is warned about and read as fallback."""
    if value in table:
        return table[value]
    c.warn(node, f"'{value}' is not supported; rendered as '{fallback}'")
    return table[fallback]


def _output_linked(node, identifier: str) -> bool:
    return any(o.identifier == identifier and o.is_linked for o in node.outputs)


def _vector_and_w(c, node, dimensions: int):
    """The (vector, W) registers a 1D-4D node reads: 1D reads only W, 2D/3D only the vector."""
    vector = c.texture_vector(node) if dimensions >= 2 else c.const([0.0, 0.0, 0.0])
    w = c.float_input(node, "W") if dimensions in (1, 4) else c.const(0.0)
    return vector, w


def compile_noise(c, node) -> dict:
    """Noise Texture (Cycles NoiseTextureNode::compile, svm/noisetex.h)."""
    dimensions = _enum(c, node, _DIMENSIONS, node.noise_dimensions, "3D")
    noise_type = _enum(c, node, NOISE_TYPES, node.noise_type, "FBM")
    vector, w = _vector_and_w(c, node, dimensions)
    inputs = [c.float_input(node, key) for key in
              ("Scale", "Detail", "Roughness", "Lacunarity", "Offset", "Gain", "Distortion")]
    fac, color = c.alloc(1), c.alloc(3)
    c.emit("TEX_NOISE", dimensions, noise_type, int(bool(node.normalize)), int(_output_linked(node, "Color")),
           vector, w, *inputs, fac, color)
    return {"Fac": fac, "Color": color}


def compile_voronoi(c, node) -> dict:
    """Voronoi Texture (Cycles VoronoiTextureNode::compile, svm/voronoi.h)."""
    dimensions = _enum(c, node, _DIMENSIONS, node.voronoi_dimensions, "3D")
    feature = _enum(c, node, VORONOI_FEATURES, node.feature, "F1")
    metric = _enum(c, node, VORONOI_METRICS, node.distance, "EUCLIDEAN")
    vector, w = _vector_and_w(c, node, dimensions)
    inputs = [c.float_input(node, key) for key in
              ("Scale", "Detail", "Roughness", "Lacunarity", "Smoothness", "Exponent", "Randomness")]
    distance, color, position, w_out, radius = c.alloc(1), c.alloc(3), c.alloc(3), c.alloc(1), c.alloc(1)
    c.emit("TEX_VORONOI", dimensions, feature, metric, int(bool(node.normalize)), vector, w, *inputs,
           distance, color, position, w_out, radius)
    return {"Distance": distance, "Color": color, "Position": position, "W": w_out, "Radius": radius}


def compile_gradient(c, node) -> dict:
    """Gradient Texture (Cycles GradientTextureNode::compile, svm/gradient.h)."""
    kind = _enum(c, node, GRADIENT_TYPES, node.gradient_type, "LINEAR")
    fac, color = c.alloc(1), c.alloc(3)
    c.emit("TEX_GRADIENT", kind, c.texture_vector(node), fac, color)
    return {"Fac": fac, "Color": color}


def compile_wave(c, node) -> dict:
    """Wave Texture (Cycles WaveTextureNode::compile, svm/wave.h)."""
    kind = _enum(c, node, WAVE_TYPES, node.wave_type, "BANDS")
    if kind == WAVE_TYPES["BANDS"]:
        direction = _enum(c, node, BANDS_DIRECTIONS, node.bands_direction, "X")
    else:
        direction = _enum(c, node, RINGS_DIRECTIONS, node.rings_direction, "X")
    profile = _enum(c, node, WAVE_PROFILES, node.wave_profile, "SIN")
    inputs = [c.float_input(node, key) for key in
              ("Scale", "Distortion", "Detail", "Detail Scale", "Detail Roughness", "Phase Offset")]
    fac, color = c.alloc(1), c.alloc(3)
    c.emit("TEX_WAVE", kind, direction, profile, c.texture_vector(node), *inputs, fac, color)
    return {"Fac": fac, "Color": color}


def compile_magic(c, node) -> dict:
    """Magic Texture (Cycles MagicTextureNode::compile, svm/magic.h); depth is Blender's 0..10."""
    depth = min(max(int(node.turbulence_depth), 0), 10)
    fac, color = c.alloc(1), c.alloc(3)
    c.emit("TEX_MAGIC", depth, c.texture_vector(node), c.float_input(node, "Scale"), c.float_input(node, "Distortion"),
           fac, color)
    return {"Fac": fac, "Color": color}


def compile_white_noise(c, node) -> dict:
    """White Noise Texture (Cycles WhiteNoiseTextureNode::compile, svm/white_noise.h): no texture
    coordinate default, the unlinked vector is its value."""
    dimensions = _enum(c, node, _DIMENSIONS, node.noise_dimensions, "3D")
    vector = c.vector_input(node, "Vector") if dimensions >= 2 else c.const([0.0, 0.0, 0.0])
    w = c.float_input(node, "W") if dimensions in (1, 4) else c.const(0.0)
    value, color = c.alloc(1), c.alloc(3)
    c.emit("TEX_WHITE_NOISE", dimensions, int(_output_linked(node, "Color")), vector, w, value, color)
    return {"Value": value, "Color": color}


TEXTURE_NODE_COMPILERS: dict = {
    "TEX_NOISE": compile_noise,
    "TEX_VORONOI": compile_voronoi,
    "TEX_GRADIENT": compile_gradient,
    "TEX_WAVE": compile_wave,
    "TEX_MAGIC": compile_magic,
    "TEX_WHITE_NOISE": compile_white_noise,
}
