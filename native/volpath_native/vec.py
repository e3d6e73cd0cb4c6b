"""Row-wise helpers for (N, 3) float arrays on the numpy side of the renderer (camera rays, scene
tables); the per-path stages use scalar tuples instead."""
from __future__ import annotations

import numpy as np


def norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def any_positive(a: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2]) > 0
