"""Benchmark: shadow-ray transmittance estimators through the noise cloud (not collected by pytest).

Shadow rays from floor points of examples/noise_cloud.py, and from points inside the cloud drawn
proportionally to its extinction (where paths scatter), to its point light and to its sun, those
that cross the cloud; for each, many independent estimates by each estimator. Prints per
estimator and light: the aggregate relative variance sum(var) / sum(T^2) (what the floor's lit
pixels see), the median per-ray relative variance, lookups and microseconds per estimate, their
product with the relative variance (lower is better), and the largest bias z-score against a
4096-point midpoint optical depth.

    python tests/benchmarks/bench_shadow_transmittance.py [--rays 400] [--repeats 256]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native")):
    if path not in sys.path:
        sys.path.insert(0, path)


def cloud_medium():
    import addon

    addon.register()
    from addon.compare import volpath_engine
    from examples import noise_cloud

    native_scene, _ = volpath_engine.export(noise_cloud.build(resolution=(16, 16), samples=1))
    from volpath_native.program_medium import ProgramMedium

    return next(m for m in native_scene.media if isinstance(m, ProgramMedium))


def _floor_points(medium, count, rng):
    return np.column_stack([rng.uniform(-4, 4, count), rng.uniform(-4, 4, count), np.full(count, 1e-4)])


def _cloud_points(medium, count, rng):
    """Points in the cloud's box with probability proportional to sigma_t (rejection): where paths scatter."""
    lo, hi = medium.world_bounds()
    p = rng.uniform(lo, hi, (count * 8, 3))
    sigma = medium.coefficients(p)[1].max(axis=1)
    keep = rng.uniform(0, sigma.max(), len(p)) < sigma
    return p[keep][:count]


def shadow_rays(medium, origin: str, light: str, count: int, rng):
    """(origins, dirs, t_max) of rays from floor or cloud points to a light whose optical depth
    through the cloud is > 0.02."""
    origins, dirs, t_max = [], [], []
    while len(origins) < count:
        p = (_floor_points if origin == "floor" else _cloud_points)(medium, 4096, rng)
        if light == "point":
            to = np.array([-2.0, -1.5, 2.8]) - p
            dist = np.linalg.norm(to, axis=1)
            d = to / dist[:, None]
        else:
            d = np.tile(-np.array([0.5, 0.4, -1.0]) / np.linalg.norm([0.5, 0.4, -1.0]), (len(p), 1))
            dist = np.full(len(p), 100.0)
        tau = medium.optical_depth(p, d, dist, steps=64).max(axis=1)
        keep = tau > 0.02
        origins += list(p[keep])
        dirs += list(d[keep])
        t_max += list(dist[keep])
    return np.array(origins[:count]), np.array(dirs[:count]), np.array(t_max[:count])


def run(name, estimate, origins, dirs, t_max, repeats, medium, reference):
    from volpath_native.grid_kernels import FLAG_LOOKUPS

    n = len(origins)
    samples = np.empty((repeats, n, 3))
    tables = medium._call_tables()
    estimate(tables, origins, dirs, t_max, np.arange(n, dtype=np.uint64), samples[0])  # compile
    tables.flags[:] = 0
    start = time.perf_counter()
    for r in range(repeats):
        keys = (np.arange(n, dtype=np.uint64) + np.uint64((r + 1) * 1_000_003)) * np.uint64(0x9E3779B97F4A7C15)
        estimate(tables, origins, dirs, t_max, keys, samples[r])
    seconds = (time.perf_counter() - start) / (repeats * n)
    lookups = tables.flags[FLAG_LOOKUPS + 1] / (repeats * n)
    mean, var = samples.mean(axis=0), samples.var(axis=0, ddof=1)
    z = np.abs(mean - reference) / np.sqrt(var / repeats + 1e-30)
    aggregate = var.sum() / (reference ** 2).sum()
    per_ray = np.median(var.mean(axis=1) / np.maximum(reference.mean(axis=1) ** 2, 1e-12))
    print(f"  {name:28s} relvar {aggregate:8.4f} (median ray {per_ray:8.4f}), {lookups:6.2f} lookups, "
          f"{seconds * 1e6:7.2f} us; relvar x us {aggregate * seconds * 1e6:8.4f}; bias |z| max "
          f"{z.max():.2f} (mean T {reference.mean():.3f}, estimate {mean.mean():.3f})", flush=True)
    return aggregate, seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=400)
    parser.add_argument("--repeats", type=int, default=256)
    parser.add_argument("--estimators", default="residual,residual_x4,telescoping,telescoping_x4")
    args = parser.parse_args(argv)
    from volpath_native.grid_kernels import track_many
    from volpath_native import telescoping_transmittance as tt

    medium = cloud_medium()
    base_rate, base_extrema = medium.residual_rate.copy(), medium.extinction_extrema.copy()

    def residual(scale):
        def estimate(tables, o, d, tm, keys, out):
            n = len(o)
            medium.residual_rate[:] = base_rate * scale
            track_many(tables, o, d, np.zeros(n), tm, keys, 0, 1, np.ones((n, 3)), np.empty(n),
                       np.empty(n, np.bool_), out, np.empty((n, 3)))
        return estimate

    def telescoping(scale):
        def estimate(tables, o, d, tm, keys, out):
            medium.extinction_extrema[:] = base_extrema * scale  # range x scale: k x scale, shorter segments
            tt.telescoping_many(tables, o, d, tm, keys, 0, out)
        return estimate

    estimators = {"residual": residual(1.0), "residual_x4": residual(4.0), "residual_x16": residual(16.0),
                  "telescoping": telescoping(1.0), "telescoping_x4": telescoping(4.0),
                  "telescoping_x16": telescoping(16.0)}
    rng = np.random.default_rng(7)
    for origin, light in (("floor", "point"), ("floor", "sun"), ("cloud", "point"), ("cloud", "sun")):
        origins, dirs, t_max = shadow_rays(medium, origin, light, args.rays, rng)
        reference = np.exp(-medium.optical_depth(origins, dirs, t_max, steps=4096))
        print(f"{origin} -> {light}: {len(origins)} rays through the cloud, mean T {reference.mean():.3f}, "
              f"{args.repeats} estimates each")
        for name in args.estimators.split(","):
            run(name, estimators[name], origins, dirs, t_max, args.repeats, medium, reference)
        medium.residual_rate[:], medium.extinction_extrema[:] = base_rate, base_extrema
    return 0


if __name__ == "__main__":
    sys.exit(main())
