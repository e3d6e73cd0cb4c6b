"""Row-wise helpers for (N, 3) float arrays. numpy's reductions along a length-3 axis are several
times slower than three column operations, and they sit on every wavefront stage."""
from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def max3(a: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2])


def sum3(a: np.ndarray) -> np.ndarray:
    return a[:, 0] + a[:, 1] + a[:, 2]


def any_positive(a: np.ndarray) -> np.ndarray:
    return max3(a) > 0
