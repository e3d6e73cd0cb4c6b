"""Pixel filters sampled by importance, as Cycles does (scene/film.cpp builds a 1D filter table
and the kernel inverts it for x and y separately): every sample lands in exactly one pixel with
weight 1, so pixels stay statistically independent (needed for per-pixel z-tests)."""
from __future__ import annotations

import numpy as np

from .jit import kernel
from .scene import Film, SceneError

_TABLE_SIZE = 1024
_INVERSE_SIZE = 16384  # Cycles uses 1024; test_film shows that biases the Gaussian tails


def _blackman_harris(x, width):
    v = 2.0 * np.pi * (x / width + 0.5)
    return 0.35875 - 0.48829 * np.cos(v) + 0.14128 * np.cos(2 * v) - 0.01168 * np.cos(3 * v)


def _gaussian(x, width):
    v = x * 6.0 / width
    return np.exp(-2.0 * v * v)


class PixelFilter:
    """Inverse-CDF sampler of a separable pixel filter; offsets are relative to the pixel centre."""

    def __init__(self, film: Film):
        width = float(film.filter_width)
        if not np.isfinite(width) or width <= 0:
            raise SceneError(f"pixel filter width {film.filter_width} must be positive")
        kind = film.filter
        # Cycles widens the filters internally (scene/film.cpp filter_table()).
        if kind == "blackman-harris":
            width *= 2.0
            func = _blackman_harris
        elif kind == "gaussian":
            width *= 3.0
            func = _gaussian
        elif kind == "box":
            func = None
        else:
            raise SceneError(f"unknown pixel filter '{kind}'")
        self.support = 0.5 * width
        xs = np.linspace(-self.support, self.support, _TABLE_SIZE + 1)
        if func is None:
            cdf = np.linspace(0.0, 1.0, _TABLE_SIZE + 1)
        else:
            mid = 0.5 * (xs[1:] + xs[:-1])
            w = np.maximum(func(mid, width), 0.0)
            cdf = np.concatenate([[0.0], np.cumsum(w)])
            cdf /= cdf[-1]
        self._xs, self._cdf = xs, cdf
        # The inverse CDF tabulated on a uniform grid of u, read with linear interpolation (as
        # Cycles' filter_table_sample / lookup_table_read): O(1) per sample where inverting the
        # CDF needs a binary search, and every camera ray draws two.
        self.inverse = np.interp(np.linspace(0.0, 1.0, _INVERSE_SIZE + 1), cdf, xs)

    def sample(self, u: np.ndarray) -> np.ndarray:
        """Offsets distributed as the 1D filter profile for uniform u in [0, 1)."""
        u = np.ascontiguousarray(u, dtype=np.float64)
        out = np.empty(u.shape)
        _filter_offsets_many(self.inverse, u.reshape(-1), out.reshape(-1))
        return out

    def pdf(self, x: np.ndarray) -> np.ndarray:
        """Normalised 1D density of offsets (for tests)."""
        dens = np.diff(self._cdf) / np.diff(self._xs)
        idx = np.clip(np.searchsorted(self._xs, x, side="right") - 1, 0, len(dens) - 1)
        return np.where(np.abs(x) <= self.support, dens[idx], 0.0)


@kernel
def filter_offset1(inverse, u):
    """Offset from the pixel centre for uniform u in [0, 1): the inverse CDF table read with
    linear interpolation."""
    size = inverse.shape[0] - 1
    position = u * size
    index = min(np.int64(position), size - 1)
    fraction = position - index
    return inverse[index] * (1.0 - fraction) + inverse[index + 1] * fraction


@kernel
def _filter_offsets_many(inverse, u, out):
    for i in range(u.shape[0]):
        out[i] = filter_offset1(inverse, u[i])
