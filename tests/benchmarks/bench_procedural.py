"""Benchmark: procedural media (height fog, noise cloud: densities computed by shader nodes) at equal
render time against Cycles (not collected by pytest); the same rows as bench_surfaces.py.

    python tests/benchmarks/bench_procedural.py [--seconds 20] [--reference-spp 1024] [--resolution 128] [--quick]
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_surfaces import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main(scenes=("height_fog", "noise_cloud"), description=__doc__))
