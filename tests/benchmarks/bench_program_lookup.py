"""Benchmark: what one lookup of a shader-program medium costs, against the Noise Texture it
evaluates (not collected by pytest).

The procedural rows of the equal-time table (noise cloud, fire) spend most of their CPU in program
lookups; this splits a lookup into the Noise Texture itself (4 octaves, the rows' Detail 3, Fac only)
and everything around it (the interpreter's dispatch and register file, the other nodes, the
Principled Volume closure), for the full program and for the tracker's reduced one
(shading/extinction_slice.py), as ratios to the noise in the same run (the machine is noisy).
Lookups run through GridMedium.coefficients (grid_coefficients: the whole closure), a little more
than the trackers' program_extinction does with the reduced program.

    python tests/benchmarks/bench_program_lookup.py [--rows noise_cloud,procedural_fire] [--points 400000]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
for path in (str(ROOT), str(ROOT / "native"), str(HERE)):
    if path not in sys.path:
        sys.path.insert(0, path)


def _best_seconds(run, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def _noise_seconds(points: np.ndarray) -> float:
    """Seconds for the rows' Noise Texture (3D fBm, Scale 2.5, Detail 3, Fac only) at every point."""
    import numba

    from volpath_native.shading.textures.noise import noise_texture

    @numba.njit(nogil=True)
    def run(pts, settings, out):
        # the node's settings read at run time, as the interpreter reads them from its registers
        # (constants here would let the compiler fold the octave loop)
        dimensions, noise_type, scale, detail, roughness, lacunarity = (
            int(settings[0]), int(settings[1]), settings[2], settings[3], settings[4], settings[5])
        for n in range(pts.shape[0]):
            out[n] = noise_texture(dimensions, noise_type, True, False, pts[n, 0], pts[n, 1], pts[n, 2], 0.0, scale,
                                   detail, roughness, lacunarity, 0.0, 1.0, 0.0)[0]

    settings = np.array([3.0, 1.0, 2.5, 3.0, 0.5, 2.0])
    out = np.zeros(len(points))
    run(points[:8], settings, out[:8])  # compile
    return _best_seconds(lambda: run(points, settings, out))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="noise_cloud,procedural_fire")
    parser.add_argument("--points", type=int, default=400_000)
    args = parser.parse_args(argv)
    import addon
    import bench_equal_time_table as table
    import volpath_native
    from addon.compare import volpath_engine

    addon.register()
    volpath_native.warm_up()
    rng = np.random.default_rng(1)
    noise_ns = _noise_seconds(rng.uniform(-1.0, 1.0, (args.points, 3))) / args.points * 1e9
    print(f"Noise Texture (4 octaves, Fac): {noise_ns:.0f} ns per point")
    for name, _, scene, _ in table.row_scenes(argparse.Namespace(rows=args.rows, resolution=48), volpath_engine):
        for medium in scene.media:
            if not hasattr(medium, "program"):
                continue
            index = rng.uniform(0.0, 1.0, (args.points, 3)) * (medium.shape - 1)
            points = index @ medium.index_to_world[:3, :3].T + medium.index_to_world[:3, 3]
            reduced = medium.tables._replace(program_code=medium.extinction.code,
                                             program_init=medium.extinction.init)
            for label, tables in (("full", medium.tables), ("reduced", reduced)):
                medium.coefficients(points[:8], tables)
                ns = _best_seconds(lambda: medium.coefficients(points, tables)) / args.points * 1e9
                print(f"{name} {label} program: {ns:.0f} ns per lookup = {ns / noise_ns:.2f}x the noise "
                      f"({len(tables.program_init)} registers)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
