"""Texture-node opcodes (100-199 of program.py) and their execution.

run_texture_op(op, code, at, regs, tables) executes one texture instruction whose operands start at
code[at]; program.py documents the operand conventions. Each opcode is registered with
program.define(name, code, *operands) at import. Enumerations (dimensions#, type#, ...) are the
Cycles svm/types.h values the family modules name (NOISE_TYPES, VORONOI_FEATURES, ...). Every
output register is written; the `color#` flags skip work Cycles skips when an output is unlinked
(the colour is then 0, as unused outputs are never read).
"""
from __future__ import annotations

from ..program import define
from ...jit import inline_stage_kernel
from .gradient import gradient_texture
from .magic import magic_texture
from .noise import noise_texture
from .voronoi import voronoi_texture
from .wave import wave_texture
from .white_noise import white_noise_texture

# Noise Texture (svm/noisetex.h svm_node_tex_noise); color# 0 skips the G and B noises
OP_TEX_NOISE = define("TEX_NOISE", 100, "dimensions#", "type#", "normalize#", "color#", "vector3", "w", "scale",
                      "detail", "roughness", "lacunarity", "offset", "gain", "distortion", "out_fac", "out_color3")
# Voronoi Texture (svm/voronoi.h svm_node_tex_voronoi)
OP_TEX_VORONOI = define("TEX_VORONOI", 101, "dimensions#", "feature#", "metric#", "normalize#", "vector3", "w",
                        "scale", "detail", "roughness", "lacunarity", "smoothness", "exponent", "randomness",
                        "out_distance", "out_color3", "out_position3", "out_w", "out_radius")
# Gradient Texture (svm/gradient.h svm_node_tex_gradient)
OP_TEX_GRADIENT = define("TEX_GRADIENT", 102, "type#", "vector3", "out_fac", "out_color3")
# Wave Texture (svm/wave.h svm_node_tex_wave); direction# is the bands or rings direction of type#
OP_TEX_WAVE = define("TEX_WAVE", 103, "type#", "direction#", "profile#", "vector3", "scale", "distortion", "detail",
                     "detail_scale", "detail_roughness", "phase", "out_fac", "out_color3")
# Magic Texture (svm/magic.h svm_node_tex_magic)
OP_TEX_MAGIC = define("TEX_MAGIC", 104, "depth#", "vector3", "scale", "distortion", "out_fac", "out_color3")
# White Noise Texture (svm/white_noise.h svm_node_tex_white_noise); color# 0 skips the colour hashes
OP_TEX_WHITE_NOISE = define("TEX_WHITE_NOISE", 105, "dimensions#", "color#", "vector3", "w", "out_value",
                            "out_color3")


@inline_stage_kernel
def _store3(regs, at, r, g, b):
    regs[at] = r
    regs[at + 1] = g
    regs[at + 2] = b


@inline_stage_kernel
def run_texture_op(op, code, at, regs, tables):
    """Execute texture opcode `op` with operands code[at], code[at + 1], ..."""
    if op == OP_TEX_NOISE:
        v = code[at + 4]
        fac, r, g, b = noise_texture(int(code[at]), int(code[at + 1]), code[at + 2] != 0, code[at + 3] != 0,
                                     regs[v], regs[v + 1], regs[v + 2], regs[code[at + 5]], regs[code[at + 6]],
                                     regs[code[at + 7]], regs[code[at + 8]], regs[code[at + 9]],
                                     regs[code[at + 10]], regs[code[at + 11]], regs[code[at + 12]])
        regs[code[at + 13]] = fac
        _store3(regs, code[at + 14], r, g, b)
    elif op == OP_TEX_VORONOI:
        v = code[at + 4]
        d, r, g, b, px, py, pz, w, radius = voronoi_texture(
            int(code[at]), int(code[at + 1]), int(code[at + 2]), code[at + 3] != 0, regs[v], regs[v + 1], regs[v + 2],
            regs[code[at + 5]], regs[code[at + 6]], regs[code[at + 7]], regs[code[at + 8]], regs[code[at + 9]],
            regs[code[at + 10]], regs[code[at + 11]], regs[code[at + 12]])
        regs[code[at + 13]] = d
        _store3(regs, code[at + 14], r, g, b)
        _store3(regs, code[at + 15], px, py, pz)
        regs[code[at + 16]] = w
        regs[code[at + 17]] = radius
    elif op == OP_TEX_GRADIENT:
        v = code[at + 1]
        f = gradient_texture(int(code[at]), regs[v], regs[v + 1], regs[v + 2])
        regs[code[at + 2]] = f
        _store3(regs, code[at + 3], f, f, f)
    elif op == OP_TEX_WAVE:
        v = code[at + 3]
        f = wave_texture(int(code[at]), int(code[at + 1]), int(code[at + 2]), regs[v], regs[v + 1], regs[v + 2],
                         regs[code[at + 4]], regs[code[at + 5]], regs[code[at + 6]], regs[code[at + 7]],
                         regs[code[at + 8]], regs[code[at + 9]])
        regs[code[at + 10]] = f
        _store3(regs, code[at + 11], f, f, f)
    elif op == OP_TEX_MAGIC:
        v = code[at + 1]
        fac, r, g, b = magic_texture(int(code[at]), regs[v], regs[v + 1], regs[v + 2], regs[code[at + 2]],
                                     regs[code[at + 3]])
        regs[code[at + 4]] = fac
        _store3(regs, code[at + 5], r, g, b)
    elif op == OP_TEX_WHITE_NOISE:
        v = code[at + 2]
        value, r, g, b = white_noise_texture(int(code[at]), code[at + 1] != 0, regs[v], regs[v + 1], regs[v + 2],
                                             regs[code[at + 3]])
        regs[code[at + 4]] = value
        _store3(regs, code[at + 5], r, g, b)
