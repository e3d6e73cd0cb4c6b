"""Benchmark: the equal-time table over scene classes -- VolPath, Cycles and Mitsuba 3 on the same
.blend scenes (not collected by pytest; issue 12's measure).

Each row: every engine renders for the same wall time (Cycles' scene sync, Mitsuba's scene load
and JIT, VolPath's kernel warm-up left out); relMSE against a high-sample reference, and the time
each engine needs for Cycles' error ("x Cycles' time", relMSE x time being constant for unbiased
Monte Carlo). VolPath and Cycles are measured against a Cycles reference (equal_time.py); Mitsuba,
whose film filter and bounce limits differ (mitsuba_peer.py), against its own reference, with its
image mean against Cycles' reference printed as a check. Rows Mitsuba cannot render as Cycles
does show the reason instead. Default: the homogeneous rows; `--rows all` adds the heterogeneous
ones (height fog, noise cloud, procedural fire, smoke plume, 128^3 cloud). The Quick Smoke fire
(a Mantaflow bake: Debian's Blender) stays in bench_fire.py.

    python tests/benchmarks/bench_equal_time_table.py [--seconds 10] [--reference-spp 1024] [--resolution 64]
        [--rows cornell_point,...|all] [--no-mitsuba] [--quick] [--seeds N] [--reference-factor 4]
    python tests/benchmarks/bench_equal_time_table.py --cpu-per-sample 128 [--rows ...] [--resolution 48]
        (VolPath only: CPU time per camera sample of each row, one thread, the default batch size as
        the equal-time runs' Time Limit rounds use; insensitive to other jobs on the machine)
"""
from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

import mitsuba_peer  # noqa: E402
from equal_time import equal_time_row  # noqa: E402


def _spot_hard_edge(scene):
    # Mitsuba's spot falloff is linear in angle, Blender's a smoothstep: compare with blend 0
    for obj in scene.objects:
        if obj.type == "LIGHT" and obj.data.type == "SPOT":
            obj.data.spot_blend = 0.0


def _lights_visible(scene):
    # Mitsuba cannot hide an emitter from camera rays: the lamp is in view for every engine
    for obj in scene.objects:
        if obj.type == "LIGHT":
            obj.visible_camera = True


def _sun_sharp(scene):
    # Mitsuba's directional light has no angular diameter: a delta sun for every engine
    for obj in scene.objects:
        if obj.type == "LIGHT" and obj.data.type == "SUN":
            obj.data.angle = 0.0


def _example(module: str, **kwargs):
    """A row built by examples/<module>.py at the table's resolution."""
    def build(resolution: int, folder: Path):
        return importlib.import_module(f"examples.{module}").build(resolution=(resolution,) * 2, samples=16, **kwargs)
    return build


def _smoke_plume(resolution: int, folder: Path):
    from examples import smoke_plume  # a Volume object from a .vdb written here
    return smoke_plume.build(resolution=(resolution,) * 2, samples=16, vdb_path=folder / "plume.vdb")


def _cloud_128(resolution: int, folder: Path):
    import bench_cloud  # the 128^3 cloud, sun + sky
    return bench_cloud.build_scene(folder / "cloud.vdb", resolution)


# name: (scene builder (resolution, scratch folder), tweak applied to the Blender scene for all engines)
ROWS = {
    "cornell_point": (_example("cornell_fog"), None),
    "cornell_spot": (_example("spot_godrays"), _spot_hard_edge),
    "cornell_area": (_example("area_light"), _lights_visible),
    "sun_godrays": (_example("sun_window", world_volume=False), None),
    "chromatic_absorber": (_example("absorbing_medium"), None),
    "dense_fog": (_example("heavy_density"), None),
    "glass_of_liquid": (_example("glass_of_liquid"), None),
    # heterogeneous media (Mitsuba's column: density grids only, mitsuba_peer.py)
    "height_fog": (_example("height_fog"), None),
    "noise_cloud": (_example("noise_cloud"), None),
    "procedural_fire": (_example("procedural_fire"), None),
    "smoke_plume": (_smoke_plume, _sun_sharp),
    "cloud_128": (_cloud_128, _sun_sharp),
}
HOMOGENEOUS_ROWS = ("cornell_point", "cornell_spot", "cornell_area", "sun_godrays", "chromatic_absorber",
                    "dense_fog", "glass_of_liquid")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="equal render-time budget per engine")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--reference-factor", type=float, default=4.0,
                        help="a row's reference has at least this many times the samples Cycles renders in the "
                             "budget (a larger one is rendered and cached; 0: --reference-spp always)")
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--rows", default=",".join(HOMOGENEOUS_ROWS),
                        help=f"comma-separated row names, or 'all' (of {', '.join(ROWS)})")
    parser.add_argument("--no-mitsuba", action="store_true")
    parser.add_argument("--seeds", type=int, default=1,
                        help="equal-time runs per row with seeds 1..N (VolPath and Cycles); the table shows "
                             "the median, the pooled ratio (pooled_time_ratio) and each run")
    parser.add_argument("--quick", action="store_true", help="32x32, 2 s, reference 128 spp (smoke test)")
    parser.add_argument("--cpu-per-sample", type=int, default=0, metavar="SPP",
                        help="only VolPath's CPU time per camera sample at SPP samples per pixel, one thread")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.reference_spp, args.resolution, args.reference_factor = 2.0, 128, 32, 0.0
    with_mitsuba = not args.no_mitsuba and mitsuba_peer.available()
    if not args.no_mitsuba and not with_mitsuba:
        print("Mitsuba 3 is not installed (pip install mitsuba): its column is left out")

    import addon

    addon.register()
    from addon.compare import metrics, volpath_engine
    import volpath_native

    print(f"kernel warm-up {volpath_native.warm_up():.1f} s (not counted)")
    if args.cpu_per_sample:
        return cpu_per_sample(args, volpath_engine)
    pixels = args.resolution ** 2
    table = []
    for name, scene, native_scene, tmp in row_scenes(args, volpath_engine):
        ratios, rows = [], []
        budget = 0  # Cycles' samples in the budget: the first seed's pilot sizes it for the row
        for seed in range(1, args.seeds + 1):
            row = equal_time_row(name, scene, native_scene, args.seconds, args.reference_spp, tmp, seed=seed,
                                 reference_factor=args.reference_factor, cycles_samples=budget)
            budget = row.cycles_spp
            print(*row.lines(pixels), sep="\n", flush=True)
            ratios.append(row.time_ratio)
            rows.append(row)
        volpath_cell = f"{np.median(ratios):.3g}x" + (
            f" (pooled {pooled_time_ratio(rows):.3g}x; runs {', '.join(f'{r:.3g}x' for r in ratios)})"
            if len(ratios) > 1 else "")
        mitsuba_cell = "-"
        if with_mitsuba:
            try:
                # its reference as large as the row's Cycles one (at least --reference-factor x Cycles' run)
                run, reference = mitsuba_peer.render_equal_time(native_scene, args.seconds,
                                                                max(args.reference_spp, row.reference_spp))
            except mitsuba_peer.Unsupported as exc:
                mitsuba_cell = f"n/a ({exc})"
                print(f"  Mitsuba: not rendered: {exc}")
            else:
                raw = metrics.relmse(run.image, reference.image)
                # E[raw] = e (1 + n / n_ref) for an independent reference of the same estimator: remove its share
                relmse = raw * reference.samples / (run.samples + reference.samples)
                ratio = relmse * run.render_seconds / (row.relmse_cycles * row.cycles_seconds)
                mean = run.image.mean(axis=(0, 1)) / np.maximum(row.reference_mean, 1e-30)
                print(f"  Mitsuba 3 ({mitsuba_peer.VARIANT}): {run.samples} spp in {run.render_seconds:.1f} s "
                      f"({run.samples * pixels / run.render_seconds / 1e3:.1f} k samples/s), relMSE vs its own "
                      f"{reference.samples}-spp reference {relmse:.4g}; needs {ratio:.3g}x Cycles' time; "
                      "image mean / Cycles reference R/G/B " + " ".join(f"{m:.4f}" for m in mean), flush=True)
                mitsuba_cell = f"{ratio:.3g}x"
        table.append((name, volpath_cell, mitsuba_cell))
    print("\n| row | VolPath: x Cycles' time | Mitsuba 3: x Cycles' time |\n|---|---|---|")
    for name, volpath_cell, mitsuba_cell in table:
        print(f"| {name} | {volpath_cell} | {mitsuba_cell} |")
    return 0


def pooled_time_ratio(rows) -> float:
    """Mean of VolPath's relMSE x time over the runs / the same for Cycles: the runs' errors pooled
    before the ratio is taken (each run's ratio divides two noisy relMSEs; the median of three of
    them swings more than the means do)."""
    return (sum(r.relmse_volpath * r.volpath_seconds for r in rows)
            / sum(r.relmse_cycles * r.cycles_seconds for r in rows))


def row_scenes(args, volpath_engine):
    """(name, Blender scene, exported scene, scratch folder) of each row asked for, the folder
    alive until the next row."""
    for name in (list(ROWS) if args.rows == "all" else args.rows.split(",")):
        build, tweak = ROWS[name]
        with tempfile.TemporaryDirectory(prefix=f"volpath_bench_{name}_") as tmp:
            scene = build(args.resolution, Path(tmp))
            if tweak:
                tweak(scene)
            native_scene, _ = volpath_engine.export(scene)
            yield name, scene, native_scene, Path(tmp)


def cpu_per_sample(args, volpath_engine) -> int:
    import time
    from volpath_native.render import render

    for name, _, native_scene, _ in row_scenes(args, volpath_engine):
        settings = native_scene.settings
        pixels = native_scene.film.width * native_scene.film.height
        settings.samples, settings.threads, settings.seed = args.cpu_per_sample, 1, 1
        render(native_scene)  # first-call costs
        start = time.process_time()
        result = render(native_scene)
        cpu = time.process_time() - start
        samples = args.cpu_per_sample * pixels
        print(f"{name}: {cpu / samples * 1e6:.3f} us CPU per camera sample ({samples} samples, one thread; "
              f"{result.stats['rays'] / samples:.2f} rays and {result.stats['shadow_rays'] / samples:.2f} shadow "
              "rays per sample)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
