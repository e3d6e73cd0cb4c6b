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
for path in (str(ROOT), str(ROOT / "native"), str(ROOT / "tests"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

from equal_time import equal_time_row  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="equal render-time budget per engine")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--quick", action="store_true", help="48x48, 4 s, reference 128 spp (smoke test)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.reference_spp, args.resolution = 4.0, 128, 48

    import fluid_runtime

    fluid_runtime.restore_mantaflow_bases()
    import addon

    addon.register()
    from addon.compare import volpath_engine

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

        row = equal_time_row("fire", scene, native_scene, args.seconds, args.reference_spp, tmp, resolution)
        print(*row.lines(args.resolution ** 2), sep="\n")
        fluid_runtime.free_blend_data()
        os.chdir(ROOT)
    return 0


if __name__ == "__main__":
    sys.exit(main())
