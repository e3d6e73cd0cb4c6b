"""White Noise Texture node (Cycles src/kernel/svm/white_noise.h `svm_node_tex_white_noise`):
hashes of the inputs' float32 bit patterns, so bit-exact by construction."""
from __future__ import annotations

from ...jit import stage_kernel
from .hash import (hash_float2_to_float, hash_float2_to_float3, hash_float3_to_float, hash_float3_to_float3,
                   hash_float4_to_float, hash_float4_to_float3, hash_float_to_float, hash_float_to_float3)


@stage_kernel
def white_noise_texture(dimensions, color_needed, x, y, z, w):
    """(value, r, g, b): 1D hashes W, 2D (x, y), 3D (x, y, z), 4D (x, y, z, w); the colour only if
    color_needed (0 otherwise, as Cycles skips it when the output is unlinked)."""
    r = g = b = 0.0
    if dimensions == 1:
        value = hash_float_to_float(w)
        if color_needed:
            r, g, b = hash_float_to_float3(w)
    elif dimensions == 2:
        value = hash_float2_to_float(x, y)
        if color_needed:
            r, g, b = hash_float2_to_float3(x, y)
    elif dimensions == 3:
        value = hash_float3_to_float(x, y, z)
        if color_needed:
            r, g, b = hash_float3_to_float3(x, y, z)
    else:
        value = hash_float4_to_float(x, y, z, w)
        if color_needed:
            r, g, b = hash_float4_to_float3(x, y, z, w)
    return value, r, g, b
