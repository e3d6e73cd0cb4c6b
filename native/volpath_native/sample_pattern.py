"""The path sampler's random numbers: shuffled, Owen-scrambled Sobol' (0,2)-sequence pairs, as
Cycles' Sobol-Burley pattern (src/kernel/sample/pattern.h path_rng_1D/2D, sobol_burley.h;
Burley 2020, "Practical Hash-based Owen Scrambling", JCGT 9(4)).

- A path key (path_key1) holds a 40-bit hash of (render seed, pixel) above the 24-bit sample
  index: each pixel has its own scrambled sequence over its samples.
- Dimensions come in pairs: dimensions 2k and 2k + 1 are the two coordinates of one Sobol' pair
  (a (0,2)-sequence: the first 2^m samples of a pixel put one point in every elementary interval
  of area 2^-m), so a 2-D decision (a BSDF direction, a point on a lamp) is stratified in 2-D.
  Different pairs are decorrelated by shuffling the sample index with a pair-specific Owen
  scramble (Burley's padding; Cycles seeds it with hash(dimension)), and every pair's points are
  Owen-scrambled with a per-(pixel, pair) seed, so the estimate stays unbiased.
- The sample index is shuffled modulo 2^24 (Cycles' shuffled_index_mask): a pixel's first 2^24
  samples are distinct points; the 2^24 samples after them use another pixel hash.

Draws whose number per path is unbounded (delta and ratio tracking in grid media) keep the
independent generator (sampling.uniform1, fed the same key).
"""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .sampling import _mix64

SAMPLE_INDEX_BITS = 24
_SAMPLE_MASK = np.uint64((1 << SAMPLE_INDEX_BITS) - 1)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX2 = np.uint64(0x94D049BB133111EB)
_M32 = np.uint64(0xFFFFFFFF)
# Owen-scramble seeds of the two coordinates of a pair (any distinct constants: Cycles xors its
# own per-coordinate constants into the seed, sobol_burley_sample_2D).
_COORDINATE_SALT = np.array([0x2F6A1C3B, 0xE0AAAF76], np.uint64)


def _reverse32_py(x: int) -> int:
    return int(f"{x & 0xFFFFFFFF:032b}"[::-1], 2)


def _byte_tables() -> np.ndarray:
    """(2, 3, 256) uint64: the XOR of the bit-reversed Sobol' direction numbers of coordinate c
    over the index bits 8b..8b+7 that the bit-reversed byte w selects (bit 7 - j of w is index
    bit 8b + j). Three lookups replace Cycles' loop over the index bits (sobol_burley): a short
    routine the compiler does not unroll into every caller."""
    # Coordinate 0: van der Corput (direction j is 2^-(j+1)); coordinate 1: Sobol's second
    # dimension (primitive polynomial x + 1: v_j = v_{j-1} xor v_{j-1} / 2). Both bit-reversed, so
    # that the scramble below is Laine-Karras' reversed-bit hash.
    van_der_corput = [1 << j for j in range(SAMPLE_INDEX_BITS)]
    sobol2, v = [], 1 << 31
    for _ in range(SAMPLE_INDEX_BITS):
        sobol2.append(_reverse32_py(v))
        v ^= v >> 1
    tables = np.zeros((2, 3, 256), np.uint64)
    for c, directions in enumerate((van_der_corput, sobol2)):
        for b in range(3):
            for w in range(256):
                x = 0
                for j in range(8):
                    if (w >> (7 - j)) & 1:
                        x ^= directions[8 * b + j]
                tables[c, b, w] = x
    return tables


SOBOL_BYTE_TABLES = _byte_tables()


@kernel
def reverse_bits32(x):
    """The 32 low bits of a uint64 in reverse order."""
    x = ((x >> np.uint64(1)) & np.uint64(0x55555555)) | ((x & np.uint64(0x55555555)) << np.uint64(1))
    x = ((x >> np.uint64(2)) & np.uint64(0x33333333)) | ((x & np.uint64(0x33333333)) << np.uint64(2))
    x = ((x >> np.uint64(4)) & np.uint64(0x0F0F0F0F)) | ((x & np.uint64(0x0F0F0F0F)) << np.uint64(4))
    x = ((x >> np.uint64(8)) & np.uint64(0x00FF00FF)) | ((x & np.uint64(0x00FF00FF)) << np.uint64(8))
    return ((x >> np.uint64(16)) | (x << np.uint64(16))) & _M32


@kernel
def owen_scramble_reversed(n, seed):
    """Base-2 nested uniform (Owen) scramble of a bit-reversed 32-bit integer: every bit is
    flipped by a hash of the bits below it (Cycles kernel/sample/util.h reversed_bit_owen, the
    improved Laine-Karras hash of psychopath.io 2021)."""
    n ^= (n * np.uint64(0x3D20ADEA)) & _M32
    n = (n + seed) & _M32
    n = (n * ((seed >> np.uint64(16)) | np.uint64(1))) & _M32
    n ^= (n * np.uint64(0x05526C56)) & _M32
    n ^= (n * np.uint64(0x53A22864)) & _M32
    return n


@kernel
def path_key1(seed_key, pixel, sample):
    """The 64-bit key of one path from (seed key, full-frame pixel index, sample index): a hash of
    the seed, the pixel and the sample's block of 2^24 above the sample index's 24 low bits."""
    s = np.uint64(sample)
    pixel_hash = _mix64(_mix64(seed_key ^ np.uint64(pixel)) ^ ((s >> np.uint64(SAMPLE_INDEX_BITS)) * _GOLDEN))
    return (pixel_hash & ~_SAMPLE_MASK) | (s & _SAMPLE_MASK)


@kernel
def _pair_seeds_index(key, pair):
    """The Owen-scramble seeds of a pair and the pixel's sample index shuffled for it
    (pair-specific: decorrelates pairs; its 24 low bits)."""
    seeds = _mix64((key >> np.uint64(SAMPLE_INDEX_BITS)) ^ (pair * _MIX2))
    return seeds, owen_scramble_reversed(reverse_bits32(key & _SAMPLE_MASK), seeds & _M32)


@kernel
def _coordinate(seeds, index, coordinate):
    """Coordinate 0 or 1 of the Owen-scrambled Sobol' point at the shuffled index."""
    x = np.uint64(0)
    for b in range(3):
        x ^= SOBOL_BYTE_TABLES[coordinate, b, (index >> np.uint64(24 - 8 * b)) & np.uint64(255)]
    x = owen_scramble_reversed(x, (seeds >> np.uint64(32)) ^ _COORDINATE_SALT[coordinate])
    return np.float64(reverse_bits32(x)) * (1.0 / 4294967296.0)


@kernel
def sample1(key, dimension):
    """Float64 in [0, 1) for one path key at one dimension: coordinate dimension % 2 of the
    Owen-scrambled Sobol' pair dimension // 2 (sobol_burley_sample_2D), at the pixel's shuffled
    sample index."""
    d = np.uint64(dimension)
    seeds, index = _pair_seeds_index(key, d >> np.uint64(1))
    return _coordinate(seeds, index, d & np.uint64(1))


@kernel
def sample2(key, dimension):
    """(sample1(key, dimension), sample1(key, dimension + 1)) for an even dimension: both
    coordinates of one pair from one shuffle of the sample index (a 2-D decision's two numbers
    for half the hashing)."""
    seeds, index = _pair_seeds_index(key, np.uint64(dimension) >> np.uint64(1))
    return _coordinate(seeds, index, np.uint64(0)), _coordinate(seeds, index, np.uint64(1))
