"""Benchmark: shader-program media with other majorant grids, paired at equal time against the same
Cycles run (not collected by pytest; session 20's measure of program_medium.DEFAULT_MAJORANT_RESOLUTION).

Each seed renders Cycles once and VolPath once per majorant resolution, every run for the same wall
time, against the table's cached Cycles reference (bench_equal_time_table rows). Printed per run: the
majorant build time (set-up, outside the equal-time budget), then equal_time's lines (x Cycles'
time, error per sample, lookups per sample).

    python tests/benchmarks/bench_majorant_resolution.py [--rows noise_cloud,height_fog,procedural_fire]
        [--resolutions 24,32,40] [--seeds 3] [--seconds 4] [--resolution 48]
"""
from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

import bench_equal_time_table as table  # noqa: E402
from equal_time import equal_time_rows  # noqa: E402


def with_majorant_resolution(native_scene, resolution: int):
    """A shallow copy of the scene whose mesh-bounded program media are rebuilt on `resolution`^3 cells."""
    from volpath_native.program_medium import ProgramMedium

    scene = copy.copy(native_scene)
    media = []
    for medium in native_scene.media:
        if isinstance(medium, ProgramMedium) and medium.grid_index_to_world is None:
            start = time.perf_counter()
            medium = ProgramMedium(medium.name, medium.program, medium.object_to_world, medium.object_bounds,
                                   medium.frame[1], g=medium.g, attributes=medium.attributes,
                                   majorant_resolution=resolution)
            print(f"  build '{medium.name}' on {resolution}^3 cells: {time.perf_counter() - start:.2f} s", flush=True)
        media.append(medium)
    scene.media = media
    return scene


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="noise_cloud,height_fog,procedural_fire")
    parser.add_argument("--resolutions", default="24,32,40", help="majorant cells per axis, comma-separated")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--resolution", type=int, default=48, help="image width and height")
    parser.add_argument("--reference-spp", type=int, default=4096)
    args = parser.parse_args(argv)
    import addon
    import volpath_native
    from addon.compare import volpath_engine

    addon.register()
    volpath_native.warm_up()
    resolutions = [int(r) for r in args.resolutions.split(",")]
    for name, scene, native_scene, scratch in table.row_scenes(args, volpath_engine):
        variants = {f"{r}^3": with_majorant_resolution(native_scene, r) for r in resolutions}
        cycles_samples = 0
        for seed in range(1, args.seeds + 1):
            rows = equal_time_rows(name, scene, variants, args.seconds, args.reference_spp, scratch,
                                   seed=seed, reference_factor=4.0,
                                   cycles_samples=cycles_samples)
            for row in rows.values():
                cycles_samples = row.cycles_spp
                print(*row.lines(args.resolution ** 2), sep="\n", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
