"""Agreement of a texture function with Cycles' values at the oracle's points."""
from __future__ import annotations

import numpy as np

#: float32 evaluation in Cycles (SSE/AVX order, FMA contraction) vs our float64 arithmetic on the
#: same float32 coordinates: a few ulps of the largest value involved
RELATIVE_TOLERANCE = 2e-5


def mismatches(ours: np.ndarray, cycles: np.ndarray, tolerance: float = RELATIVE_TOLERANCE):
    """(number of points where some channel differs by more than tolerance * max(1, max |cycles|
    of that channel), the largest difference). ours/cycles: (n,) or (n, channels)."""
    ours = np.asarray(ours, np.float64).reshape(len(ours), -1)
    cycles = np.asarray(cycles, np.float64).reshape(len(cycles), -1)
    finite = np.where(np.isfinite(cycles), np.abs(cycles), 0.0)
    scale = np.maximum(1.0, finite.max(axis=0)) if len(cycles) else np.ones(cycles.shape[1])
    diff = np.abs(ours - cycles)
    diff[np.isnan(ours) & np.isnan(cycles)] = 0.0
    diff[np.isnan(diff)] = np.inf
    bad = (diff > tolerance * scale).any(axis=1)
    return int(bad.sum()), float(diff.max()) if diff.size else 0.0
