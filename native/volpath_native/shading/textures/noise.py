"""Noise Texture node (Cycles src/kernel/svm/noisetex.h `svm_node_tex_noise`, fractals from
src/kernel/svm/fractal_noise.h), 1D-4D, all five types.

One implementation for every dimension: coordinates travel as four float32 (x, y, z, w), of which
the first `dimensions` are used (1D: its coordinate is W, carried in x). Coordinate arithmetic
(scale, octave frequency, seed offsets, distortion) is float32 as in Cycles, so lattice cells and
the 1e5 wrap match; the accumulation of octaves runs in float64.
"""
from __future__ import annotations

import math

import numpy as np

from ...jit import stage_kernel
from .hash import hash_float_to_float, hash_float2_to_float
from .perlin import snoise, snoise_3d_inline

#: Blender's node enum order (DNA NodeNoiseType, Cycles svm/types.h NODE_NOISE_*)
NOISE_MULTIFRACTAL, NOISE_FBM, NOISE_HYBRID_MULTIFRACTAL, NOISE_RIDGED_MULTIFRACTAL, NOISE_HETERO_TERRAIN = range(5)
NOISE_TYPES = {"MULTIFRACTAL": NOISE_MULTIFRACTAL, "FBM": NOISE_FBM, "HYBRID_MULTIFRACTAL": NOISE_HYBRID_MULTIFRACTAL,
               "RIDGED_MULTIFRACTAL": NOISE_RIDGED_MULTIFRACTAL, "HETERO_TERRAIN": NOISE_HETERO_TERRAIN}


def _hashed_random_offset(dimensions, seed, component):
    """noisetex.h `random_float{,2,3,4}_offset`: 100 + 100 hash, a float32 in [100, 200]; 1D hashes
    the seed alone, 2D-4D hash (seed, component)."""
    if component >= dimensions:
        return np.float32(0.0)
    if dimensions == 1:
        h = hash_float_to_float(seed)
    else:
        h = hash_float2_to_float(seed, float(component))
    return np.float32(100.0) + np.float32(h) * np.float32(100.0)


#: every offset the node uses (seeds 0-3 distortion, 1-5 colour): constants, looked up instead of
#: hashed on every evaluation (1.5 % of a noise cloud's render). [dimensions, seed, component]
RANDOM_OFFSETS = np.array([[[_hashed_random_offset(d, float(s), c) if d > 0 else 0.0 for c in range(4)]
                            for s in range(6)] for d in range(5)], dtype=np.float32)


@stage_kernel
def random_offset(dimensions, seed, component):
    """_hashed_random_offset(dimensions, seed, component) for the node's integral seeds 0..5."""
    return RANDOM_OFFSETS[dimensions, int(seed), component]


@stage_kernel
def fbm(dimensions, x, y, z, w, detail, roughness, lacunarity, normalize):
    """fractal_noise.h `noise_fbm`: octave i at fscale * p, fscale = lacunarity^i (float32). 3D
    octaves go four at a time as straight-line code: their Perlin cells are independent and the
    compiler interleaves them (a loop of calls runs them one after the other; measured: 4 octaves
    110 -> 97 ns), summed in the loop's order -- the same value bit for bit."""
    fscale = np.float32(1.0)
    amp = 1.0
    maxamp = 0.0
    total = 0.0
    octaves = int(detail) + 1
    done = 0
    while dimensions == 3 and done + 4 <= octaves:
        f1 = fscale * lacunarity
        f2 = f1 * lacunarity
        f3 = f2 * lacunarity
        t0 = snoise_3d_inline(fscale * x, fscale * y, fscale * z)
        t1 = snoise_3d_inline(f1 * x, f1 * y, f1 * z)
        t2 = snoise_3d_inline(f2 * x, f2 * y, f2 * z)
        t3 = snoise_3d_inline(f3 * x, f3 * y, f3 * z)
        for t in (t0, t1, t2, t3):
            total += t * amp
            maxamp += amp
            amp *= roughness
        fscale = f3 * lacunarity
        done += 4
    for _ in range(done, octaves):
        t = snoise(dimensions, fscale * x, fscale * y, fscale * z, fscale * w)
        total += t * amp
        maxamp += amp
        amp *= roughness
        fscale = fscale * lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        t = snoise(dimensions, fscale * x, fscale * y, fscale * z, fscale * w)
        total2 = total + t * amp
        if normalize:
            a = 0.5 * total / maxamp + 0.5
            return a + rmd * ((0.5 * total2 / (maxamp + amp) + 0.5) - a)
        return total + rmd * (total2 - total)
    return 0.5 * total / maxamp + 0.5 if normalize else total


@stage_kernel
def multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity):
    """fractal_noise.h `noise_multi_fractal`: p *= lacunarity per octave (float32)."""
    value = 1.0
    pwr = 1.0
    for _ in range(int(detail) + 1):
        value *= pwr * snoise(dimensions, x, y, z, w) + 1.0
        pwr *= roughness
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        value *= rmd * pwr * snoise(dimensions, x, y, z, w) + 1.0
    return value


@stage_kernel
def hetero_terrain(dimensions, x, y, z, w, detail, roughness, lacunarity, offset):
    """fractal_noise.h `noise_hetero_terrain`: first octave unscaled."""
    pwr = roughness
    value = offset + snoise(dimensions, x, y, z, w)
    x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
    for _ in range(1, int(detail) + 1):
        increment = (snoise(dimensions, x, y, z, w) + offset) * pwr * value
        value += increment
        pwr *= roughness
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        increment = (snoise(dimensions, x, y, z, w) + offset) * pwr * value
        value += rmd * increment
    return value


@stage_kernel
def hybrid_multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity, offset, gain):
    """fractal_noise.h `noise_hybrid_multi_fractal`: octaves continue while weight > 0.001."""
    pwr = 1.0
    value = 0.0
    weight = 1.0
    i = 0
    n = int(detail)
    while weight > 0.001 and i <= n:
        weight = min(weight, 1.0)
        signal = (snoise(dimensions, x, y, z, w) + offset) * pwr
        pwr *= roughness
        value += weight * signal
        weight *= gain * signal
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        i += 1
    rmd = detail - math.floor(detail)
    if rmd != 0.0 and weight > 0.001:
        weight = min(weight, 1.0)
        signal = (snoise(dimensions, x, y, z, w) + offset) * pwr
        value += rmd * weight * signal
    return value


@stage_kernel
def ridged_multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity, offset, gain):
    """fractal_noise.h `noise_ridged_multi_fractal`: (offset - |snoise|)^2, no fractional octave."""
    pwr = roughness
    signal = offset - abs(snoise(dimensions, x, y, z, w))
    signal *= signal
    value = signal
    for _ in range(1, int(detail) + 1):
        x, y, z, w = x * lacunarity, y * lacunarity, z * lacunarity, w * lacunarity
        weight = min(max(signal * gain, 0.0), 1.0)
        signal = offset - abs(snoise(dimensions, x, y, z, w))
        signal *= signal
        signal *= weight
        value += signal * pwr
        pwr *= roughness
    return value


@stage_kernel
def noise_select(noise_type, dimensions, x, y, z, w, detail, roughness, lacunarity, offset, gain, normalize):
    """noisetex.h `noise_select`."""
    if noise_type == NOISE_FBM:
        return fbm(dimensions, x, y, z, w, detail, roughness, lacunarity, normalize)
    if noise_type == NOISE_MULTIFRACTAL:
        return multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity)
    if noise_type == NOISE_HYBRID_MULTIFRACTAL:
        return hybrid_multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity, offset, gain)
    if noise_type == NOISE_RIDGED_MULTIFRACTAL:
        return ridged_multi_fractal(dimensions, x, y, z, w, detail, roughness, lacunarity, offset, gain)
    return hetero_terrain(dimensions, x, y, z, w, detail, roughness, lacunarity, offset)


@stage_kernel
def noise_texture(dimensions, noise_type, normalize, color_needed, vx, vy, vz, vw, scale, detail, roughness,
                  lacunarity, offset, gain, distortion):
    """noisetex.h `svm_node_tex_noise` + `noise_texture_{1,2,3,4}d`: (fac, r, g, b). The vector
    (vx, vy, vz) and W are the node's inputs; r = fac, g and b are computed only if color_needed
    (Cycles computes them only when the Color output is linked; they are 0 otherwise)."""
    scale32 = np.float32(scale)
    lac = np.float32(lacunarity)
    detail_ = min(max(float(np.float32(detail)), 0.0), 15.0)
    roughness_ = max(float(np.float32(roughness)), 0.0)
    offset_ = float(np.float32(offset))
    gain_ = float(np.float32(gain))
    distortion32 = np.float32(distortion)
    zero = np.float32(0.0)
    if dimensions == 1:
        x, y, z, w = np.float32(vw) * scale32, zero, zero, zero
    else:
        x, y, z, w = np.float32(vx) * scale32, np.float32(vy) * scale32, np.float32(vz) * scale32, np.float32(vw) * scale32
        if dimensions == 2:
            z, w = zero, zero
        elif dimensions == 3:
            w = zero
    if distortion32 != zero:
        # seeds 0..dimensions-1, one per axis, each offsetting all axes (component c)
        dx = snoise(dimensions, x + random_offset(dimensions, 0.0, 0), y + random_offset(dimensions, 0.0, 1),
                    z + random_offset(dimensions, 0.0, 2), w + random_offset(dimensions, 0.0, 3))
        dy = zero
        dz = zero
        dw = zero
        if dimensions >= 2:
            dy = np.float32(snoise(dimensions, x + random_offset(dimensions, 1.0, 0), y + random_offset(dimensions, 1.0, 1),
                                   z + random_offset(dimensions, 1.0, 2), w + random_offset(dimensions, 1.0, 3)))
        if dimensions >= 3:
            dz = np.float32(snoise(dimensions, x + random_offset(dimensions, 2.0, 0), y + random_offset(dimensions, 2.0, 1),
                                   z + random_offset(dimensions, 2.0, 2), w + random_offset(dimensions, 2.0, 3)))
        if dimensions >= 4:
            dw = np.float32(snoise(dimensions, x + random_offset(dimensions, 3.0, 0), y + random_offset(dimensions, 3.0, 1),
                                   z + random_offset(dimensions, 3.0, 2), w + random_offset(dimensions, 3.0, 3)))
        x = x + np.float32(dx) * distortion32
        if dimensions >= 2:
            y = y + dy * distortion32
        if dimensions >= 3:
            z = z + dz * distortion32
        if dimensions >= 4:
            w = w + dw * distortion32
    fac = noise_select(noise_type, dimensions, x, y, z, w, detail_, roughness_, lac, offset_, gain_, normalize)
    g = 0.0
    b = 0.0
    if color_needed:
        # colour seeds follow the distortion seeds: 1D/2D/3D/4D use (1, 2) / (2, 3) / (3, 4) / (4, 5)
        sg = 1.0 if dimensions == 1 else float(dimensions)
        sb = sg + 1.0
        g = noise_select(noise_type, dimensions, x + random_offset(dimensions, sg, 0), y + random_offset(dimensions, sg, 1),
                         z + random_offset(dimensions, sg, 2), w + random_offset(dimensions, sg, 3),
                         detail_, roughness_, lac, offset_, gain_, normalize)
        b = noise_select(noise_type, dimensions, x + random_offset(dimensions, sb, 0), y + random_offset(dimensions, sb, 1),
                         z + random_offset(dimensions, sb, 2), w + random_offset(dimensions, sb, 3),
                         detail_, roughness_, lac, offset_, gain_, normalize)
    return fac, fac, g, b
