"""Where an equal-time row's error comes from, pixel by pixel and path by path (not collected by
pytest; how session 17 found the spot row's fireflies).

    python tests/benchmarks/pixel_errors.py ROW [SPP] [SEEDS]
        both engines at SPP samples per pixel x SEEDS seeds against the row's cached Cycles reference
        (render the table first): each engine's share of its squared error per luminance decile, its
        worst pixels, and VolPath's largest samples in them (pixel index, sample index, seed)
    python tests/benchmarks/pixel_errors.py ROW --trace PIXEL SAMPLE SEED
        one VolPath path stage by stage (Integrator.render_paths(stepwise=True)): each iteration's
        ray, hit, throughput, the radiance it adds and the shadow rays it queues

Rows: bench_equal_time_table.ROWS at 48x48.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
for path in (str(HERE.parents[1]), str(HERE.parents[1] / "native"), str(HERE)):
    if path not in sys.path:
        sys.path.insert(0, path)

import bench_equal_time_table as table  # noqa: E402
import equal_time  # noqa: E402

RESOLUTION = 48


def _rows(row: str):
    """bench_equal_time_table.row_scenes for one row: keep the generator while its scene is used (its
    scratch folder goes when the generator does)."""
    import addon

    addon.register()
    from addon.compare import volpath_engine
    import volpath_native

    volpath_native.warm_up()
    return table.row_scenes(argparse.Namespace(rows=row, resolution=RESOLUTION), volpath_engine)


def _reference(scene, native_scene, scratch):
    for spp in (65536, 32768, 16384, 8192, 4096):
        if equal_time._reference_path(native_scene, spp, scratch).exists():
            return equal_time._cycles_reference(scene, native_scene, spp, scratch).image
    raise SystemExit("no cached Cycles reference for this row: run bench_equal_time_table.py on it first")


def errors(row: str, spp: int, seeds: int) -> None:
    from addon.compare import cycles_engine, metrics, volpath_engine
    from volpath_native.integrator import Integrator

    rows = _rows(row)
    name, scene, native_scene, scratch = next(rows)
    reference = metrics.rgb(_reference(scene, native_scene, scratch))
    with cycles_engine.matched_settings(scene, cycles_engine.BounceLimits.from_settings(native_scene.settings)):
        cycles = [cycles_engine.render_once(scene, samples=spp, seed=s, scratch=scratch).image
                  for s in range(1, seeds + 1)]
    volpath = [volpath_engine.render_runs(native_scene, runs=1, samples=spp, base_seed=s)[0].image
               for s in range(1, seeds + 1)]

    def squared(images):
        return np.mean([((metrics.rgb(i) - reference) ** 2 / (reference ** 2 + metrics.RELMSE_EPSILON)).mean(axis=2)
                        for i in images], axis=0)

    ev, ec = squared(volpath), squared(cycles)
    luminance = reference.mean(axis=2).ravel()
    print(f"{name}: relMSE x spp VolPath {ev.mean() * spp:.4g}, Cycles {ec.mean() * spp:.4g} "
          f"(ratio {ev.mean() / ec.mean():.3g}; {spp} spp x {seeds} seeds)")
    order = np.argsort(luminance)
    for q in range(10):
        idx = order[q * len(order) // 10:(q + 1) * len(order) // 10]
        v, c = ev.ravel()[idx].sum(), ec.ravel()[idx].sum()
        print(f"  luminance decile {q} (mean {luminance[idx].mean():.3g}): share of the error VolPath "
              f"{v / ev.sum():.3f}, Cycles {c / ec.sum():.3f}" + (f", ratio {v / c:.3g}" if c > 0 else ""))
    worst = np.argsort(ev.ravel())[::-1][:5]
    print("  worst VolPath pixels (share of its error): "
          + ", ".join(f"{int(p)} ({ev.ravel()[p] / ev.sum():.3f})" for p in worst)
          + f"; Cycles' worst pixel holds {ec.max() / ec.sum():.3f}")
    n_pix = RESOLUTION * RESOLUTION
    for seed in range(1, seeds + 1):
        native_scene.settings.seed = seed
        integrator = Integrator(native_scene)
        for pixel in worst[:3]:
            samples = np.arange(spp, dtype=np.int64)
            values = integrator.render_paths(np.full(spp, pixel, np.int64), samples)[0][:, :3].mean(axis=1)
            top = np.argsort(values)[::-1][:3]
            print(f"  seed {seed} pixel {int(pixel)} (of {n_pix}): mean {values.mean():.4g}, largest samples "
                  + ", ".join(f"#{int(s)} = {values[s]:.4g}" for s in top))


def trace(row: str, pixel: int, sample: int, seed: int) -> None:
    from volpath_native import integrator as integrator_module
    from volpath_native import path_kernels as pk

    rows = _rows(row)
    _, _, native_scene, _ = next(rows)
    shade, shadows = pk.shade, integrator_module.Integrator._trace_shadows

    def traced_shade(*args):
        # path_kernels.shade's arguments: tables (8), n, iteration, F, I, K, C, hit t/prim/inst/u/v, L, alive, Q, ...
        F, I, L, alive, queue = args[10], args[11], args[19], args[20], args[21]
        before = L[0, :3].copy()
        print(f"iteration {args[9]}: origin {F[0, pk.O:pk.O + 3].round(4)} direction {F[0, pk.D:pk.D + 3].round(4)} "
              f"throughput {F[0, pk.BETA:pk.BETA + 3].round(4)} hit t {args[14][0]:.4g} triangle {args[15][0]} "
              f"bounces {I[0].tolist()}")
        queued = shade(*args)
        print(f"  radiance {before.round(4)} -> {L[0, :3].round(4)}; throughput now "
              f"{F[0, pk.BETA:pk.BETA + 3].round(4)}; alive {bool(alive[0])}")
        for q in range(queued):
            print(f"  shadow ray {q} (purpose {queue.I[q, pk.SI_PURPOSE]}): origin "
                  f"{queue.F[q, pk.S_O:pk.S_O + 3].round(4)} direction {queue.F[q, pk.S_D:pk.S_D + 3].round(4)} "
                  f"contribution {queue.F[q, pk.S_CONTRIB:pk.S_CONTRIB + 3].round(4)}")
        return queued

    def traced_shadows(self, grid_tables, buffers, Q, m, margin, L, counts, iteration, cancel=None):
        before = L[0, :3].copy()
        shadows(self, grid_tables, buffers, Q, m, margin, L, counts, iteration, cancel)
        if m:
            print(f"  after its shadow rays: radiance {before.round(4)} -> {L[0, :3].round(4)}")

    pk.shade, integrator_module.Integrator._trace_shadows = traced_shade, traced_shadows
    try:
        native_scene.settings.seed = seed
        value = integrator_module.Integrator(native_scene).render_paths(
            np.array([pixel], np.int64), np.array([sample], np.int64), stepwise=True)[0][0, :3]
    finally:
        pk.shade, integrator_module.Integrator._trace_shadows = shade, shadows
    print(f"the path's value: {value}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("row")
    parser.add_argument("spp", nargs="?", type=int, default=1024)
    parser.add_argument("seeds", nargs="?", type=int, default=2)
    parser.add_argument("--trace", nargs=3, type=int, metavar=("PIXEL", "SAMPLE", "SEED"))
    args = parser.parse_args(argv)
    if args.trace:
        trace(args.row, *args.trace)
    else:
        errors(args.row, args.spp, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
