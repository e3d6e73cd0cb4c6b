"""Cycles' hashes, bit-exact (Cycles src/util/hash.h).

Integers are carried as int64 holding the uint32 (or int32) bit pattern and masked after every
operation, so the same code gives the same bits compiled (int64 wraps) and in plain Python
(unbounded ints): the planted-error tests run these functions uncompiled.

Hash -> float conversions return float64 holding exactly the float32 value Cycles computes:
(float)n rounds n to 24 bits, then a power-of-two factor scales it exactly.
"""
from __future__ import annotations

import math

import numpy as np

from ...jit import inline_stage_kernel, stage_kernel

MASK32 = 0xFFFFFFFF
#: 1/(float)0xFFFFFFFFu and 1/(float)0x7FFFFFFFu: the divisors round to 2^32 and 2^31 in float32
INV_UINT32_FLOAT = 2.0 ** -32
INV_INT31_FLOAT = 2.0 ** -31


@inline_stage_kernel
def rot(x, k):
    """hash.h `rot`: 32-bit left rotation."""
    x = x & MASK32
    return ((x << k) | (x >> (32 - k))) & MASK32


@inline_stage_kernel
def lookup3_final(a, b, c):
    """hash.h macro `final` (Jenkins lookup3): rotations 14, 11, 25, 16, 4, 14, 24."""
    c = (c ^ b) & MASK32
    c = (c - rot(b, 14)) & MASK32
    a = (a ^ c) & MASK32
    a = (a - rot(c, 11)) & MASK32
    b = (b ^ a) & MASK32
    b = (b - rot(a, 25)) & MASK32
    c = (c ^ b) & MASK32
    c = (c - rot(b, 16)) & MASK32
    a = (a ^ c) & MASK32
    a = (a - rot(c, 4)) & MASK32
    b = (b ^ a) & MASK32
    b = (b - rot(a, 14)) & MASK32
    c = (c ^ b) & MASK32
    c = (c - rot(b, 24)) & MASK32
    return a, b, c


@inline_stage_kernel
def lookup3_mix(a, b, c):
    """hash.h macro `mix` (Jenkins lookup3): rotations 4, 6, 8, 16, 19, 4."""
    a = (a - c) & MASK32
    a = (a ^ rot(c, 4)) & MASK32
    c = (c + b) & MASK32
    b = (b - a) & MASK32
    b = (b ^ rot(a, 6)) & MASK32
    a = (a + c) & MASK32
    c = (c - b) & MASK32
    c = (c ^ rot(b, 8)) & MASK32
    b = (b + a) & MASK32
    a = (a - c) & MASK32
    a = (a ^ rot(c, 16)) & MASK32
    c = (c + b) & MASK32
    b = (b - a) & MASK32
    b = (b ^ rot(a, 19)) & MASK32
    a = (a + c) & MASK32
    c = (c - b) & MASK32
    c = (c ^ rot(b, 4)) & MASK32
    b = (b + a) & MASK32
    return a, b, c


@inline_stage_kernel
def hash_uint(kx):
    """hash.h `hash_uint`."""
    a = (0xDEADBEEF + (1 << 2) + 13) & MASK32
    a = (a + kx) & MASK32
    b = c = (0xDEADBEEF + (1 << 2) + 13) & MASK32
    a, b, c = lookup3_final(a, b, c)
    return c


@inline_stage_kernel
def hash_uint2(kx, ky):
    """hash.h `hash_uint2`."""
    init = (0xDEADBEEF + (2 << 2) + 13) & MASK32
    a, b, c = (init + kx) & MASK32, (init + ky) & MASK32, init
    a, b, c = lookup3_final(a, b, c)
    return c


@inline_stage_kernel
def hash_uint3(kx, ky, kz):
    """hash.h `hash_uint3`."""
    init = (0xDEADBEEF + (3 << 2) + 13) & MASK32
    a, b, c = (init + kx) & MASK32, (init + ky) & MASK32, (init + kz) & MASK32
    a, b, c = lookup3_final(a, b, c)
    return c


@inline_stage_kernel
def hash_uint4(kx, ky, kz, kw):
    """hash.h `hash_uint4`: mix after x, y, z, then w joins a before final."""
    init = (0xDEADBEEF + (4 << 2) + 13) & MASK32
    a, b, c = (init + kx) & MASK32, (init + ky) & MASK32, (init + kz) & MASK32
    a, b, c = lookup3_mix(a, b, c)
    a = (a + kw) & MASK32
    a, b, c = lookup3_final(a, b, c)
    return c


@inline_stage_kernel
def uint_to_float_incl(n):
    """hash.h `uint_to_float_incl`: (float)n * (1/(float)0xFFFFFFFF), i.e. n rounded to float32
    (24 bits) times 2^-32, as float64 (exact)."""
    return float(np.float32(n)) * INV_UINT32_FLOAT


@stage_kernel
def float32_bits(f):
    """__float_as_uint of float32(f): the IEEE bit pattern, sign of zero kept (NaN -> quiet NaN)."""
    f32 = float(np.float32(f))
    sign = 0x80000000 if math.copysign(1.0, f32) < 0.0 else 0
    a = abs(f32)
    if a == 0.0:
        return sign
    if a != a:
        return 0x7FC00000
    if a == math.inf:
        return sign | 0x7F800000
    m, e = math.frexp(a)  # a = m 2^e, m in [0.5, 1)
    biased = e + 126
    if biased <= 0:  # subnormal: mantissa counts units of 2^-149
        return sign | int(a * 2.0 ** 149)
    return sign | (biased << 23) | int((m * 2.0 - 1.0) * 8388608.0)


@stage_kernel
def hash_float_to_float(k):
    """hash.h `hash_float_to_float` (hashes the float32 bit pattern)."""
    return uint_to_float_incl(hash_uint(float32_bits(k)))


@stage_kernel
def hash_float2_to_float(kx, ky):
    """hash.h `hash_float2_to_float`."""
    return uint_to_float_incl(hash_uint2(float32_bits(kx), float32_bits(ky)))


@stage_kernel
def hash_float3_to_float(kx, ky, kz):
    """hash.h `hash_float3_to_float`."""
    return uint_to_float_incl(hash_uint3(float32_bits(kx), float32_bits(ky), float32_bits(kz)))


@stage_kernel
def hash_float4_to_float(kx, ky, kz, kw):
    """hash.h `hash_float4_to_float`."""
    return uint_to_float_incl(hash_uint4(float32_bits(kx), float32_bits(ky), float32_bits(kz), float32_bits(kw)))


@stage_kernel
def hash_float_to_float3(k):
    """hash.h `hash_float_to_float3`: (h(k), h(k, 1), h(k, 2))."""
    return hash_float_to_float(k), hash_float2_to_float(k, 1.0), hash_float2_to_float(k, 2.0)


@stage_kernel
def hash_float2_to_float3(kx, ky):
    """hash.h `hash_float2_to_float3`: (h(x, y), h(x, y, 1), h(x, y, 2))."""
    return (hash_float2_to_float(kx, ky), hash_float3_to_float(kx, ky, 1.0), hash_float3_to_float(kx, ky, 2.0))


@stage_kernel
def hash_float3_to_float3(kx, ky, kz):
    """hash.h `hash_float3_to_float3`: (h(x, y, z), h(x, y, z, 1), h(x, y, z, 2))."""
    return (hash_float3_to_float(kx, ky, kz), hash_float4_to_float(kx, ky, kz, 1.0),
            hash_float4_to_float(kx, ky, kz, 2.0))


@stage_kernel
def hash_float4_to_float3(kx, ky, kz, kw):
    """hash.h `hash_float4_to_float3`: (h(x, y, z, w), h(z, x, w, y), h(w, z, y, x))."""
    return (hash_float4_to_float(kx, ky, kz, kw), hash_float4_to_float(kz, kx, kw, ky),
            hash_float4_to_float(kw, kz, ky, kx))


# ---------------------------------------------------------------------------------------------
# PCG hashes on signed int32 (hash.h hash_pcg{2,3,4}d_i), used by Voronoi 2D-4D
# ---------------------------------------------------------------------------------------------
@inline_stage_kernel
def wrap_int32(v):
    """The int32 value of the low 32 bits of v (two's complement wrap)."""
    v = v & MASK32
    return v - 0x100000000 if v >= 0x80000000 else v


@stage_kernel
def hash_pcg2d_i(x, y):
    """hash.h `hash_pcg2d_i`: int32 arithmetic with wraparound, arithmetic >> 16."""
    x = wrap_int32(x * 1664525 + 1013904223)
    y = wrap_int32(y * 1664525 + 1013904223)
    x = wrap_int32(x + y * 1664525)
    y = wrap_int32(y + x * 1664525)
    x = wrap_int32(x ^ (x >> 16))
    y = wrap_int32(y ^ (y >> 16))
    x = wrap_int32(x + y * 1664525)
    y = wrap_int32(y + x * 1664525)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF


@stage_kernel
def hash_pcg3d_i(x, y, z):
    """hash.h `hash_pcg3d_i`."""
    x = wrap_int32(x * 1664525 + 1013904223)
    y = wrap_int32(y * 1664525 + 1013904223)
    z = wrap_int32(z * 1664525 + 1013904223)
    x = wrap_int32(x + y * z)
    y = wrap_int32(y + z * x)
    z = wrap_int32(z + x * y)
    x = wrap_int32(x ^ (x >> 16))
    y = wrap_int32(y ^ (y >> 16))
    z = wrap_int32(z ^ (z >> 16))
    x = wrap_int32(x + y * z)
    y = wrap_int32(y + z * x)
    z = wrap_int32(z + x * y)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF


@stage_kernel
def hash_pcg4d_i(x, y, z, w):
    """hash.h `hash_pcg4d_i`."""
    x = wrap_int32(x * 1664525 + 1013904223)
    y = wrap_int32(y * 1664525 + 1013904223)
    z = wrap_int32(z * 1664525 + 1013904223)
    w = wrap_int32(w * 1664525 + 1013904223)
    x = wrap_int32(x + y * w)
    y = wrap_int32(y + z * x)
    z = wrap_int32(z + x * y)
    w = wrap_int32(w + y * z)
    x = wrap_int32(x ^ (x >> 16))
    y = wrap_int32(y ^ (y >> 16))
    z = wrap_int32(z ^ (z >> 16))
    w = wrap_int32(w ^ (w >> 16))
    x = wrap_int32(x + y * w)
    y = wrap_int32(y + z * x)
    z = wrap_int32(z + x * y)
    w = wrap_int32(w + y * z)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF, w & 0x7FFFFFFF


@inline_stage_kernel
def int31_to_float(h):
    """(float)h * (1/(float)0x7FFFFFFF) of hash.h `hash_int*_to_float*`: h rounded to float32 times
    2^-31, as float64 (exact)."""
    return float(np.float32(h)) * INV_INT31_FLOAT


@stage_kernel
def hash_int2_to_float2(x, y):
    """hash.h `hash_int2_to_float2`."""
    hx, hy = hash_pcg2d_i(x, y)
    return int31_to_float(hx), int31_to_float(hy)


@stage_kernel
def hash_int3_to_float3(x, y, z):
    """hash.h `hash_int3_to_float3` (also `hash_int2_to_float3` with z = 0)."""
    hx, hy, hz = hash_pcg3d_i(x, y, z)
    return int31_to_float(hx), int31_to_float(hy), int31_to_float(hz)


@stage_kernel
def hash_int4_to_float4(x, y, z, w):
    """hash.h `hash_int4_to_float4` (its first three: `hash_int4_to_float3`)."""
    hx, hy, hz, hw = hash_pcg4d_i(x, y, z, w)
    return int31_to_float(hx), int31_to_float(hy), int31_to_float(hz), int31_to_float(hw)
