"""Transmittance of shadow rays through shader-program media: a telescoping (power-series) estimator.

Cycles 5.0 estimates the transmittance of shadow rays through heterogeneous volumes with the
debiased estimator of Misso et al. 2022 ("Unbiased and consistent rendering using biased
estimators"; Cycles src/kernel/integrator/shade_volume.h, volume_transmittance and
volume_shadow_null_scattering; octree leaves merged until their extinction range x length reaches
1, volume_octree_advance_shadow). VolPath follows it on its majorant grid:

- the ray's majorant cells are walked with grid_kernels' DDA and merged into segments until
  (largest - smallest sampled extinction of the merged cells) x length >= 1;
- a segment of length L takes k = clamp(round(range x L), 1, 1024) lookups: T_k = exp(-tau_k),
  tau_k the optical depth estimated on a randomly shifted regular grid of k points (unbiased for
  tau; T_k is biased by Jensen's inequality, low-variance);
- the bias is removed by the telescoping sum T = E[T_k] + sum_{n>=1} E[T_(2^n k) - T_(2^(n-1) k)]:
  an order n is drawn with P(n) = (1 - q) q^n and one debiasing term is added, divided by P(n).
  All estimates of one segment share one grid of N k = 2^n k points (the finer grid's even and
  odd points and its N interleaved subgrids are themselves shifted grids, whose average has the
  same expectation as one shifted grid: Cycles' reuse of the samples).

The optical depth is estimated as integral(control) + h x sum(sigma_t - control), with the
majorant cells' piecewise-constant control extinction (program_medium: the middle of each cell's
sampled range) integrated exactly along the walk: a segment spanning cells of different density
then samples only the residual, which is smoother than sigma_t (Cycles samples sigma_t itself).

Bias: none up to the truncation of the order where N k would exceed the tracking budget (then the
last order takes the tail probability, as Cycles' cut_off = 4 does: shade_volume.h); with
k <= 1024 the truncated order is >= 4, so it is at most Cycles' bias (E[T] - E[T_(16 k)]).
Cycles draws q = 0.1 with a hard cut-off at order 4, which keeps its variance finite; without the
cut-off the debiasing terms' variance decays only as 4^-n (the shifted grid's error is O(1/N k)),
so q must exceed 1/4 and stay below 1/2 (expected lookups (1 - q) / (1 - 2 q) x k).

Not used by the path kernels (measured, native/README.md "Estimators"): on the noise cloud's shadow
rays residual ratio tracking (grid_kernels) reaches the same variance in less time, and the shadow
rays' variance is a small part of that scene's error. tests/benchmarks/bench_shadow_transmittance.py
compares the two.
"""
from __future__ import annotations

import numpy as np

from .grid_kernels import (FLAG_BUDGET, FLAG_LOOKUPS, TRACKING_BUDGET, _dda_start, _next_crossing, _step_cell,
                           grid_coefficients, majorant_cell)
from .jit import inline_stage_kernel, stage_kernel
from .sampling import uniform1

#: ratio of the geometric distribution of the debiasing order: P(n) = (1 - q) q^n
ORDER_RATIO = 0.35
#: lookups per unit of (extinction range x length) of a segment (Cycles: 1)
LOOKUPS_PER_RANGE = 1.0
#: most lookups of the biased estimate of one segment (Cycles' VOLUME_MAX_STEPS)
MAX_LOOKUPS = 1024
# the transmittance mode's lookups counter (grid_kernels: FLAG_LOOKUPS + mode 1)
_FLAG_SHADOW_LOOKUPS = FLAG_LOOKUPS + 1


@inline_stage_kernel
def _control_at(G, x, y, z):
    """The control extinction (rgb) of the majorant cell holding a world point."""
    i, j, k = majorant_cell(G, x, y, z)
    c = G.residual_cells
    return c[i, j, k, 1], c[i, j, k, 2], c[i, j, k, 3]


@stage_kernel
def _residual_sum(G, ox, oy, oz, dx, dy, dz, a, h, offset, first, stride, count):
    """sum over s = first, first + stride, ... (count points) of (sigma_t - control) at
    t = a + (offset + s) h: three floats."""
    r0 = r1 = r2 = 0.0
    for i in range(count):
        t = a + (offset + first + i * stride) * h
        x, y, z = ox + dx * t, oy + dy * t, oz + dz * t
        c = grid_coefficients(G, x, y, z)
        m0, m1, m2 = _control_at(G, x, y, z)
        r0 += c[3] - m0
        r1 += c[4] - m1
        r2 += c[5] - m2
    return r0, r1, r2


@stage_kernel
def order_count(k):
    """Largest debiasing order whose 2^n k lookups fit the tracking budget."""
    n = 0
    while (k << (n + 1)) <= TRACKING_BUDGET and n < 30:
        n += 1
    return n


@stage_kernel
def _segment(G, ox, oy, oz, dx, dy, dz, a, b, extinction_range, control_depth, u_order, u_offset, debias):
    """Unbiased transmittance estimate (rgb) of [a, b] given the exact control optical depth (rgb)
    of the segment; returns (T rgb, lookups). debias False: the biased T_k alone (tests)."""
    length = b - a
    k = min(max(int(np.round(LOOKUPS_PER_RANGE * extinction_range * length)), 1), MAX_LOOKUPS)
    n_max = order_count(k)
    # order n with P(n) = (1 - q) q^n, the last order taking the tail q^n_max
    n = int(np.floor(np.log1p(-u_order) / np.log(ORDER_RATIO))) if u_order > 0.0 else 0
    if n >= n_max:
        n = n_max
        pmf = ORDER_RATIO ** n
    else:
        pmf = (1.0 - ORDER_RATIO) * ORDER_RATIO ** n
    c0, c1, c2 = control_depth
    if n == 0 or not debias:
        h = length / k
        r0, r1, r2 = _residual_sum(G, ox, oy, oz, dx, dy, dz, a, h, u_offset, 0, 1, k)
        return np.exp(-(c0 + h * r0)), np.exp(-(c1 + h * r1)), np.exp(-(c2 + h * r2)), k
    groups = 1 << n  # N interleaved subgrids of k points each; together the finest grid of N k points
    h = length / (groups * k)
    tk0 = tk1 = tk2 = 0.0  # mean over the subgrids of T_k
    even0 = even1 = even2 = odd0 = odd1 = odd2 = 0.0  # residual sums of the even and odd points
    for g in range(groups):
        r0, r1, r2 = _residual_sum(G, ox, oy, oz, dx, dy, dz, a, h, u_offset, g, groups, k)
        tk0 += np.exp(-(c0 + groups * h * r0))
        tk1 += np.exp(-(c1 + groups * h * r1))
        tk2 += np.exp(-(c2 + groups * h * r2))
        if g % 2 == 0:  # the subgrid's points are all even (groups is even)
            even0, even1, even2 = even0 + r0, even1 + r1, even2 + r2
        else:
            odd0, odd1, odd2 = odd0 + r0, odd1 + r1, odd2 + r2
    inv = 1.0 / groups
    fine0 = np.exp(-(c0 + h * (even0 + odd0)))
    fine1 = np.exp(-(c1 + h * (even1 + odd1)))
    fine2 = np.exp(-(c2 + h * (even2 + odd2)))
    half0 = 0.5 * (np.exp(-(c0 + 2.0 * h * even0)) + np.exp(-(c0 + 2.0 * h * odd0)))
    half1 = 0.5 * (np.exp(-(c1 + 2.0 * h * even1)) + np.exp(-(c1 + 2.0 * h * odd1)))
    half2 = 0.5 * (np.exp(-(c2 + 2.0 * h * even2)) + np.exp(-(c2 + 2.0 * h * odd2)))
    return (tk0 * inv + (fine0 - half0) / pmf, tk1 * inv + (fine1 - half1) / pmf,
            tk2 * inv + (fine2 - half2) / pmf, groups * k)


@stage_kernel
def telescoping_transmittance(G, ox, oy, oz, dx, dy, dz, t_max, key, stream):
    """Unbiased (up to the truncation in the module docstring) transmittance estimate (rgb) over
    [0, t_max] along a unit ray through a program medium: cells merged into segments of extinction
    range x length >= 1, each estimated by _segment. Draws 2 numbers per segment from the stream."""
    return _transmittance(G, ox, oy, oz, dx, dy, dz, t_max, key, stream, True)


@stage_kernel
def _transmittance(G, ox, oy, oz, dx, dy, dz, t_max, key, stream, debias):
    wr = wg = wb = 1.0
    active, t, t_exit, cx, cy, cz, nx, ny, nz, ex, ey, ez, sx, sy, sz = _dda_start(
        G, ox, oy, oz, dx, dy, dz, 0.0, t_max)
    if not active:
        return wr, wg, wb
    if G.stop[0] != 0:
        return 0.0, 0.0, 0.0
    rx, ry, rz = G.cell_shape[0], G.cell_shape[1], G.cell_shape[2]
    draws = np.int64(0)
    lookups = np.int64(0)
    seg_start = t
    lo, hi = np.inf, 0.0
    d0 = d1 = d2 = 0.0  # control optical depth of the open segment
    while active:
        axis, crossing = _next_crossing(nx, ny, nz)
        cell_end = min(crossing, t_exit)
        c = G.residual_cells
        span = cell_end - t
        d0 += c[cx, cy, cz, 1] * span
        d1 += c[cx, cy, cz, 2] * span
        d2 += c[cx, cy, cz, 3] * span
        lo = min(lo, G.extrema[cx, cy, cz, 0])
        hi = max(hi, G.extrema[cx, cy, cz, 1])
        t = cell_end
        cx, cy, cz, nx, ny, nz, left = _step_cell(axis, cx, cy, cz, nx, ny, nz, sx, sy, sz, ex, ey, ez,
                                                    rx, ry, rz)
        active = not (left or crossing >= t_exit)
        extinction_range = max(hi - lo, 0.0)
        if active and extinction_range * (t - seg_start) < 1.0:
            continue  # merge the next cell (Cycles volume_octree_advance_shadow)
        if not extinction_range * (t - seg_start) <= TRACKING_BUDGET:  # inf / NaN extinction: opaque
            G.flags[FLAG_BUDGET] += 1
            return 0.0, 0.0, 0.0
        u_order = uniform1(key, np.uint64(stream) + np.uint64(draws))
        u_offset = uniform1(key, np.uint64(stream) + np.uint64(draws + 1))
        draws += 2
        s0, s1, s2, m = _segment(G, ox, oy, oz, dx, dy, dz, seg_start, t, extinction_range, (d0, d1, d2),
                                 u_order, u_offset, debias)
        lookups += m
        wr, wg, wb = wr * s0, wg * s1, wb * s2
        if wr == 0.0 and wg == 0.0 and wb == 0.0:
            break
        if G.stop[0] != 0:
            return 0.0, 0.0, 0.0
        seg_start = t
        lo, hi = np.inf, 0.0
        d0 = d1 = d2 = 0.0
    G.flags[_FLAG_SHADOW_LOOKUPS] += lookups
    return wr, wg, wb


@stage_kernel
def telescoping_many(G, origins, dirs, t_max, keys, stream, weight, debias=True):
    """telescoping_transmittance per ray into weight (N,3) (tests and benchmarks); debias False
    leaves out the debiasing term (the biased T_k: a planted error for the tests)."""
    for n in range(len(origins)):
        o, d = origins[n], dirs[n]
        weight[n, 0], weight[n, 1], weight[n, 2] = _transmittance(
            G, o[0], o[1], o[2], d[0], d[1], d[2], t_max[n], keys[n], stream, debias)
