"""Benchmark: Blender's Quick Smoke "Smoke + Fire" (baked Mantaflow domain, frame 30, noise upres
x2: 32 x 32 x 48 voxels), VolPath vs Cycles at equal render time (not collected by pytest).

Prints VolPath's and Cycles' samples/s and each engine's relMSE against a high-sample Cycles
reference at equal render time, and their ratio. Cycles renders the real domain: the bpy wheel's
Mantaflow gets its base classes back (tests/fluid_runtime.py); VolPath reads the cache files.

    python tests/benchmarks/bench_fire.py [--seconds 20] [--reference-spp 1024] [--resolution 128] [--quick]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(ROOT / "tests")):
    if path not in sys.path:
        sys.path.insert(0, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="equal render-time budget per engine")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--quick", action="store_true", help="48x48, 4 s, reference 128 spp (smoke test)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.reference_spp, args.resolution = 4.0, 128, 48

    import numpy as np

    import fluid_runtime

    fluid_runtime.restore_mantaflow_bases()
    import addon

    addon.register()
    from addon.compare import cycles_engine, metrics, volpath_engine

    resolution = (args.resolution, args.resolution)
    with tempfile.TemporaryDirectory(prefix="volpath_bench_fire_") as tmp:
        tmp = Path(tmp)
        os.chdir(tmp)  # Mantaflow writes its noise tile into the working directory
        folder = fluid_runtime.copy_data(tmp / "data")
        scene, _ = fluid_runtime.open_domain(folder, "fire", 30)
        start = time.perf_counter()
        native_scene, warnings = volpath_engine.export(scene, resolution)
        print(f"export {time.perf_counter() - start:.2f} s" + (f", warnings: {warnings}" if warnings else ""))
        fire = next(m for m in native_scene.media if not getattr(m, "is_homogeneous", True))
        print(f"fire: grid {tuple(int(n) - 3 for n in fire.shape)} voxels (cropped), majorant grid "
              f"{tuple(fire.majorant_shape)}; {args.resolution}x{args.resolution} px")

        bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
        with cycles_engine.matched_settings(scene, bounces, resolution):
            reference = cycles_engine.render_once(scene, samples=args.reference_spp, seed=1000, scratch=tmp)
            per_sample = reference.render_seconds / args.reference_spp
            cycles_run = cycles_engine.render_once(scene, samples=max(1, int(args.seconds / per_sample)), seed=1,
                                                   scratch=tmp)
        print(f"reference: Cycles {args.reference_spp} spp, render {reference.render_seconds:.1f} s "
              f"(+ {reference.seconds - reference.render_seconds:.1f} s scene sync, excluded)")
        volpath_run = volpath_engine.render_runs(native_scene, runs=1, samples=1, base_seed=1,
                                                 time_limit=args.seconds)[0]
        pixels = args.resolution ** 2
        for name, run in (("VolPath", volpath_run), ("Cycles", cycles_run)):
            rate = run.samples / max(run.render_seconds, 1e-9)
            print(f"{name:8s} {run.samples} spp in {run.render_seconds:.1f} s = {rate * pixels / 1e3:.1f} k samples/s")
        # Remove the reference's own noise share (as bench_cloud.py does).
        raw_v = metrics.relmse(volpath_run.image, reference.image)
        raw_c = metrics.relmse(cycles_run.image, reference.image)
        share = raw_c * cycles_run.samples / (cycles_run.samples + args.reference_spp)
        err_v, err_c = raw_v - share, raw_c - share
        print(f"equal render time, relMSE vs reference: VolPath {err_v:.4g}, Cycles {err_c:.4g} "
              f"(raw {raw_v:.4g} / {raw_c:.4g}); relMSE x seconds: VolPath needs "
              f"{err_v * volpath_run.render_seconds / (err_c * cycles_run.render_seconds):.3g}x Cycles' time")
        means_v = metrics.rgb(volpath_run.image).mean(axis=(0, 1))
        means_r = metrics.rgb(reference.image).mean(axis=(0, 1))
        print("image mean ratio VolPath/reference R/G/B: " + " ".join(f"{a / b:.4f}" for a, b in zip(means_v, means_r)))
        fluid_runtime.free_blend_data()
        os.chdir(ROOT)
    return 0


if __name__ == "__main__":
    sys.exit(main())
