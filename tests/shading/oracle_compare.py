"""Agreement of a texture function with Cycles' values at the oracle's points."""
from __future__ import annotations

import numpy as np

#: float32 evaluation in Cycles (SSE/AVX order, FMA contraction) vs our float64 arithmetic on the
#: same float32 coordinates: a few ulps of the largest value involved
RELATIVE_TOLERANCE = 2e-5


def mismatches(ours: np.ndarray, cycles: np.ndarray, tolerance: float = RELATIVE_TOLERANCE):
    """(number of points whose value differs by more than tolerance * max(1, max |cycles|), the
    largest difference). ours/cycles: (n,) or (n, k); a point counts once if any channel differs."""
    ours = np.asarray(ours, np.float64).reshape(len(ours), -1)
    cycles = np.asarray(cycles, np.float64).reshape(len(cycles), -1)
    scale = max(1.0, float(np.nanmax(np.abs(cycles))) if np.isfinite(cycles).any() else 1.0)
    diff = np.abs(ours - cycles)
    diff[np.isnan(ours) & np.isnan(cycles)] = 0.0
    diff[np.isnan(diff)] = np.inf
    bad = (diff > tolerance * scale).any(axis=1)
    return int(bad.sum()), float(diff.max()) if diff.size else 0.0
