"""Benchmark: a 128^3 cloud (Volume object from a .vdb) at 256x256, VolPath vs Cycles (not collected by pytest).

One run prints, for the same Blender scene:
- VolPath samples/s (and paths/s) rendering the cloud;
- equal render-time relMSE of each engine against a reference, a high-sample Cycles render (Cycles 5.0's
  default null-scattering volume path, `volume_biased` off), and their ratio; the reference is
  Cycles' own converged estimate, so VolPath's error also holds any difference between the engines;
- the memory of a 256^3 grid medium (arrays and the peak while building it), to show it is bounded.

    python tests/benchmarks/bench_cloud.py [--seconds 30] [--reference-spp 768] [--quick]

Default: 30 s of render time per engine, reference 768 spp (~2 minutes of Cycles on 2 cores, plus
~8 s of scene sync per Cycles render); about 4 minutes in all.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native"), str(Path(__file__).resolve().parent)):
    if path not in sys.path:
        sys.path.insert(0, path)

import numpy as np  # noqa: E402

from equal_time import equal_time_row  # noqa: E402

CLOUD_SHAPE = (128, 128, 128)
CLOUD_SIZE = 2.0  # m, edge of the grid's box


def cloud_density(shape=CLOUD_SHAPE, seed=3) -> np.ndarray:
    """A cumulus-like density in [0, 1]: a few overlapping ellipsoids with a flat base, eroded by
    random-phase sine octaves (deterministic for a seed)."""
    rng = np.random.default_rng(seed)
    axes = [np.linspace(-1.0, 1.0, n, dtype=np.float32) for n in shape]
    x, y, z = np.meshgrid(*axes, indexing="ij", sparse=True)
    shape_field = np.zeros(shape, np.float32)
    for cx, cy, cz, r in ((0.0, 0.0, -0.1, 0.55), (0.35, 0.1, 0.05, 0.4), (-0.35, -0.1, 0.0, 0.42),
                          (0.05, 0.2, 0.3, 0.35)):
        shape_field = np.maximum(shape_field, 1.0 - ((x - cx) ** 2 + (y - cy) ** 2 + 1.6 * (z - cz) ** 2) / r ** 2)
    shape_field *= np.clip((z + 0.45) * 8.0, 0.0, 1.0)  # flat base
    noise = np.zeros(shape, np.float32)
    for octave in range(5):
        k = 4.0 * 2.0 ** octave
        p = rng.uniform(0, 2 * np.pi, 3).astype(np.float32)
        noise += 0.5 ** octave * (np.sin(k * x + p[0]) * np.sin(k * y + p[1]) * np.sin(k * z + p[2]))
    density = np.clip(shape_field + 0.35 * noise, 0.0, 1.0)
    density[density < 0.02] = 0.0
    return density.astype(np.float32)


def build_scene(vdb_path: Path, resolution: int, density_scale: float = 6.0):
    """Blender scene: the cloud as a Volume object (Principled Volume, white, g = 0.5), lit by a
    sun and a sky-blue world, seen from the side."""
    import bpy

    from examples import scene_builder as sb
    from examples.smoke_plume import import_openvdb

    openvdb = import_openvdb()
    grid = openvdb.FloatGrid()
    grid.name = "density"
    grid.copyFromArray(cloud_density(), ijk=(0, 0, 0))
    grid.transform = openvdb.createLinearTransform(voxelSize=CLOUD_SIZE / CLOUD_SHAPE[0])
    openvdb.write(str(vdb_path), grids=[grid])

    scene = sb.new_scene((resolution, resolution), 16)
    volume = bpy.data.volumes.new("Cloud")
    volume.filepath = str(vdb_path)
    volume.materials.append(sb.principled_volume_material("Cloud", density=density_scale, color=(0.95, 0.95, 0.95),
                                                          anisotropy=0.5))
    cloud = bpy.data.objects.new("Cloud", volume)
    scene.collection.objects.link(cloud)
    cloud.location = (-CLOUD_SIZE / 2, -CLOUD_SIZE / 2, -CLOUD_SIZE / 2)
    sb.add_sun_light(scene, direction=(-0.4, 0.5, -0.75), strength=4.0, angle_deg=1.0)
    sb.set_world_background(scene, (0.35, 0.5, 0.8), 0.6)
    sb.add_camera(scene, (0.0, -5.0, 0.6), (0.0, 0.0, 0.0), lens_mm=40.0)
    return scene


def grid_memory(size: int = 256) -> tuple:
    """(arrays MB, peak traced MB while building) of a GridMedium over a size^3 density grid."""
    from volpath_native.grid_medium import GridMedium, principled_volume_coefficients

    density = np.random.default_rng(0).random((size, size, size), dtype=np.float32)
    sigma_s, sigma_a = principled_volume_coefficients(0.9, 5.0)
    tracemalloc.start()
    tracemalloc.reset_peak()
    medium = GridMedium("memory", density, np.diag([0.01, 0.01, 0.01, 1.0]), sigma_s, sigma_a)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return medium.memory_bytes() / 2 ** 20, peak / 2 ** 20, density.nbytes / 2 ** 20


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="equal render-time budget per engine")
    parser.add_argument("--reference-spp", type=int, default=768)
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--quick", action="store_true", help="64x64, 5 s, reference 64 spp (smoke test)")
    args = parser.parse_args(argv)
    if args.quick:
        args.seconds, args.reference_spp, args.resolution = 5.0, 64, 64

    import addon

    addon.register()
    from addon.compare import volpath_engine

    with tempfile.TemporaryDirectory(prefix="volpath_bench_cloud_") as tmp:
        tmp = Path(tmp)
        start = time.perf_counter()
        scene = build_scene(tmp / "cloud.vdb", args.resolution)
        native_scene, warnings = volpath_engine.export(scene)
        export_seconds = time.perf_counter() - start
        if warnings:
            print("export warnings:", *warnings, sep="\n  ")
        cloud = next(m for m in native_scene.media if not getattr(m, "is_homogeneous", True))
        print(f"cloud: {CLOUD_SHAPE[0]}^3 voxels ({np.count_nonzero(cloud.density)} non-zero), majorant grid "
              f"{tuple(cloud.majorant_shape)}, medium arrays {cloud.memory_bytes() / 2 ** 20:.1f} MB; "
              f"{args.resolution}x{args.resolution} px; .vdb + scene + VolPath export {export_seconds:.1f} s")

        row = equal_time_row("cloud", scene, native_scene, args.seconds, args.reference_spp, tmp)
        print(*row.lines(args.resolution ** 2), sep="\n")

    arrays_mb, peak_mb, input_mb = grid_memory(256)
    print(f"memory, 256^3 grid medium: arrays {arrays_mb:.1f} MB, peak while building {peak_mb:.1f} MB "
          f"(input density {input_mb:.1f} MB; dense float32 + padding + majorant grids, no per-ray growth)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
