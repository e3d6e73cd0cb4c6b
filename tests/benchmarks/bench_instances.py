"""Benchmark: memory and build time of instancing (not collected by pytest).

One 31k-triangle prototype (a wavy 125 x 125 grid, smooth normals) placed K times (default 400)
as Mesh.instances, against the same scene flattened into world-space copies (Mesh.world_copies;
a smaller K, the cost grows linearly with it). For each: the Accelerator build (per-triangle
tables + Embree BVH) time and resident memory growth, and closest-hit rays/s (one thread, CPU
time) on random rays through the instance field.

    python tests/benchmarks/bench_instances.py [--instances 400] [--flattened 40]
"""
from __future__ import annotations

import argparse
import resource
import sys
import time

import numpy as np


def rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize()


def prototype(n=125):
    from volpath_native import Mesh
    x, y = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    z = 0.1 * np.sin(6 * x) * np.cos(5 * y)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    index = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, 1:].ravel(), index[1:, :-1].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    normals = np.tile(np.float32([0, 0, 1]), (len(triangles), 3, 1))
    return Mesh("grid", vertices, triangles, np.zeros(len(triangles), np.int32), corner_normals=normals)


def placements(k, seed=1):
    rng = np.random.default_rng(seed)
    out = np.zeros((k, 3, 4))
    side = int(np.ceil(np.sqrt(k)))
    for i in range(k):
        angle = rng.random() * 2 * np.pi
        c, s = np.cos(angle), np.sin(angle)
        out[i, :, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) * (0.8 + 0.4 * rng.random())
        out[i, :, 3] = [3.0 * (i % side), 3.0 * (i // side), rng.random()]
    return out


def measure(meshes, label, rays):
    from volpath_native.accel import Accelerator
    from volpath_native.scene import Material
    before, start = rss(), time.perf_counter()
    accel = Accelerator(meshes, [Material("grey")])
    accel.intersect_raw(*[r[:1] for r in rays])
    seconds, grown = time.perf_counter() - start, rss() - before
    best = np.inf
    for _ in range(3):
        t0 = time.process_time()
        hits = accel.intersect_raw(*rays)
        best = min(best, time.process_time() - t0)
    triangles = sum(len(m.triangles) * m.instance_count for m in meshes)
    print(f"  {label}: {triangles / 1e6:.2f}M triangles placed, {accel.triangle_count / 1e3:.0f}k stored, "
          f"build {seconds:.2f} s, +{grown / 1e6:.0f} MB resident ({grown / triangles:.1f} B per placed triangle), "
          f"{len(rays[0]) / best / 1e6:.2f} M rays/s, hit fraction {np.mean(hits.prim >= 0):.2f}")
    return accel


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances", type=int, default=400)
    parser.add_argument("--flattened", type=int, default=40)
    args = parser.parse_args(argv)
    proto = prototype()
    rng = np.random.default_rng(2)
    extent = 3.0 * np.ceil(np.sqrt(args.flattened))
    n = 200000
    o = np.concatenate([rng.random((n, 2)) * extent, np.full((n, 1), 3.0)], axis=1).astype(np.float32)
    d = rng.normal(size=(n, 3)) * [0.3, 0.3, 0] + [0, 0, -1]
    d = (d / np.linalg.norm(d, axis=1)[:, None]).astype(np.float32)
    rays = (o, d, np.full(n, 1e30, np.float32))
    print(f"prototype: {len(proto.triangles)} triangles")
    warm = prototype(4)
    warm.instances = placements(1)
    kept = [measure([warm], "warm-up (device, threads, compiled loops)", rays)]  # kept alive: no reuse of freed memory
    for k in (args.flattened, args.instances):
        mesh = prototype()
        mesh.instances = placements(k)
        kept.append(measure([mesh], f"{k} instances", rays))
    mesh = prototype()
    mesh.instances = placements(args.flattened)
    kept.append(measure(mesh.world_copies(), f"{args.flattened} flattened copies", rays))
    return 0


if __name__ == "__main__":
    sys.exit(main())
