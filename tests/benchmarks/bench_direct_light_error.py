"""Benchmark: a table row's error per sample, VolPath / Cycles, with all bounces and with direct
light only (max bounces 0), by reference-brightness class of pixels (not collected by pytest).
Separates the next-event estimators' error from the paths' (the spot row's MIS gap, session 10).

    python tests/benchmarks/bench_direct_light_error.py [--row cornell_spot] [--resolution 48] [--spp 128]
        [--seeds 3] [--reference-spp 4096] [--variants full,direct]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--row", default="cornell_spot")
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--variants", default="full,direct")
    args = parser.parse_args(argv)

    import addon

    addon.register()
    from addon.compare import cycles_engine, metrics, volpath_engine
    import volpath_native
    from bench_cloud_error_map import per_pixel_error
    from bench_equal_time_table import ROWS

    volpath_native.warm_up()
    build, tweak = ROWS[args.row]
    for variant in args.variants.split(","):
        with tempfile.TemporaryDirectory(prefix="volpath_direct_error_") as tmp:
            scene = build(args.resolution, Path(tmp))
            if tweak:
                tweak(scene)
            if variant == "direct":
                scene.volpath.max_bounces = 0
            native, _ = volpath_engine.export(scene)
            bounces = cycles_engine.BounceLimits.from_settings(native.settings)
            with cycles_engine.matched_settings(scene, bounces):
                reference = cycles_engine.render_once(scene, samples=args.reference_spp, seed=1000, scratch=Path(tmp))
                cycles = [cycles_engine.render_once(scene, samples=args.spp, seed=1 + k, scratch=Path(tmp))
                          for k in range(args.seeds)]
        volpath = volpath_engine.render_runs(native, runs=args.seeds, samples=args.spp, base_seed=1)
        raw_c = np.mean([per_pixel_error(c.image, reference.image) for c in cycles], axis=0)
        raw_v = np.mean([per_pixel_error(v.image, reference.image) for v in volpath], axis=0)
        reference_part = raw_c * args.spp / (args.spp + args.reference_spp)  # as equal_time.py
        err_c, err_v = (raw_c - reference_part) * args.spp, (raw_v - reference_part) * args.spp
        print(f"[{args.row} {variant}] error per sample Cycles {err_c.mean():.4g}, VolPath {err_v.mean():.4g}, "
              f"ratio {err_v.mean() / err_c.mean():.3g}", flush=True)
        brightness = metrics.rgb(reference.image).mean(axis=2)
        classes = np.digitize(brightness, np.unique(np.quantile(brightness, [0.5, 0.9, 0.99])))
        for c in np.unique(classes):
            mask = classes == c
            print(f"  pixels of brightness {brightness[mask].min():.3g}-{brightness[mask].max():.3g} "
                  f"({mask.mean() * 100:.0f} %): Cycles {err_c[mask].mean():.4g}, VolPath {err_v[mask].mean():.4g}; "
                  f"share of VolPath's error {err_v[mask].sum() / err_v.sum() * 100:.0f} %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
