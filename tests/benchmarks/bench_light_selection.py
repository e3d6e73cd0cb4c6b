"""Benchmark: per-point light selection (the light tree, RenderSettings.light_tree) against the
static selection by power, both against Cycles at equal render time in the same run (not collected
by pytest): the multi-light procedural media (height fog: sun + spot; noise cloud: sun + point +
sky) and the one-light Cornell-style fog scenes (point, spot, area light).

    python tests/benchmarks/bench_light_selection.py [--seconds 8] [--reference-spp 512] [--resolution 48]
        [--scenes height_fog,noise_cloud,cornell_fog,spot_godrays,area_light]
"""
from __future__ import annotations

import argparse
import copy
import importlib
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

from equal_time import equal_time_rows  # noqa: E402

SCENES = "height_fog,noise_cloud,cornell_fog,spot_godrays,area_light"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--reference-spp", type=int, default=512)
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--scenes", default=SCENES)
    args = parser.parse_args(argv)

    import addon

    addon.register()
    from addon.compare import volpath_engine
    import volpath_native

    print(f"kernel warm-up {volpath_native.warm_up():.1f} s (not counted)")
    for name in args.scenes.split(","):
        scene = importlib.import_module(f"examples.{name}").build(resolution=(args.resolution,) * 2, samples=16)
        tree, _ = volpath_engine.export(scene)
        static = copy.copy(tree)
        static.settings = copy.replace(tree.settings, light_tree=False) if hasattr(copy, "replace") else \
            type(tree.settings)(**{**tree.settings.__dict__, "light_tree": False})
        assert tree.settings.light_tree and not static.settings.light_tree
        with tempfile.TemporaryDirectory(prefix=f"volpath_bench_{name}_") as tmp:
            rows = equal_time_rows(name, scene, {"light tree": tree, "static selection": static}, args.seconds,
                                   args.reference_spp, Path(tmp))
        for row in rows.values():
            print(*row.lines(args.resolution ** 2), sep="\n", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
