"""Benchmark: the surfaces scenes (glass of liquid in fog, metals on a glossy floor) at equal render
time against Cycles (not collected by pytest).

    python tests/benchmarks/bench_surfaces.py [--seconds 20] [--reference-spp 1024] [--resolution 128] [--quick]
"""
from __future__ import annotations

import argparse
import importlib
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

from equal_time import equal_time_row  # noqa: E402

SCENES = ("glass_of_liquid", "metals_glossy")


def main(argv=None, scenes=SCENES, description=__doc__) -> int:
    """Equal-time rows against Cycles for example scenes (bench_procedural.py reuses it)."""
    parser = argparse.ArgumentParser(description=description.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="equal render-time budget per engine")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--quick", action="store_true", help="48x48, 3 s, reference 128 spp (smoke test)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.reference_spp, args.resolution = 3.0, 128, 48

    import addon

    addon.register()
    from addon.compare import volpath_engine
    import volpath_native

    print(f"kernel warm-up {volpath_native.warm_up():.1f} s (not counted)")
    for name in scenes:
        scene = importlib.import_module(f"examples.{name}").build(resolution=(args.resolution,) * 2, samples=16)
        native_scene, _ = volpath_engine.export(scene)
        with tempfile.TemporaryDirectory(prefix=f"volpath_bench_{name}_") as tmp:
            row = equal_time_row(name, scene, native_scene, args.seconds, args.reference_spp, Path(tmp))
        print(*row.lines(args.resolution ** 2), sep="\n", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
