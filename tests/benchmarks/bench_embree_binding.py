"""Benchmark: raw ray queries, embreex's EmbreeScene.run against the direct binding
(volpath_native.embree) on the same mesh and rays (not collected by pytest).

A subdivided sphere with noise (~330k triangles by default) and incoherent rays from inside a box
around it; closest hits and occlusion, one thread (CPU time, insensitive to other processes), then
two threads (wall time) to show the GIL is released. Also the build time and the memory Embree
holds beyond the mesh arrays (peak RSS growth of a build).

    python tests/benchmarks/bench_embree_binding.py [--subdivisions 7] [--rays 200000]
"""
from __future__ import annotations

import argparse
import resource
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "native"))


def sphere(subdivisions: int, seed=1):
    from native_helpers import icosphere
    mesh = icosphere("s", subdivisions=subdivisions)
    rng = np.random.default_rng(seed)
    vertices = mesh.vertices * (1 + 0.05 * rng.random((len(mesh.vertices), 1))).astype(np.float32)
    return vertices.astype(np.float32), mesh.triangles


def rays(n, seed=2):
    rng = np.random.default_rng(seed)
    origins = (rng.random((n, 3)) * 3 - 1.5).astype(np.float32)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    return origins, directions.astype(np.float32), np.full(n, 1e30, np.float32)


def cpu_rate(function, n, repeat=3):
    best = np.inf
    for _ in range(repeat):
        start = time.process_time()
        function()
        best = min(best, time.process_time() - start)
    return n / best


def wall_rate_threads(function, n, threads):
    workers = [threading.Thread(target=function) for _ in range(threads)]
    start = time.perf_counter()
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    return threads * n / (time.perf_counter() - start)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdivisions", type=int, default=7)
    parser.add_argument("--rays", type=int, default=200000)
    args = parser.parse_args(argv)
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from volpath_native.embree import TriangleScene
    vertices, triangles = sphere(args.subdivisions)
    o, d, far = rays(args.rays)
    print(f"{len(triangles) / 1e3:.0f}k triangles, {args.rays / 1e3:.0f}k rays")

    def rss():  # resident now (the BVH stays allocated after the build)
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * resource.getpagesize()

    # devices, thread pools and compiled loops first, so the builds below count only themselves
    tiny_v, tiny_t = np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.int32([[0, 1, 2]])
    warm = TriangleScene()
    warm.add_triangles(tiny_v, tiny_t, 0)
    warm.commit().intersect(o[:1], d[:1], far[:1])
    warm_reference = rtcore_scene.EmbreeScene()
    TriangleMesh(warm_reference, tiny_v, tiny_t)
    warm_reference.run(o[:1], d[:1], dists=far[:1].copy(), output=1)
    before, start = rss(), time.perf_counter()
    binding = TriangleScene()
    binding.add_triangles(vertices, triangles, 0)
    binding.commit()
    binding.intersect(o[:1], d[:1], far[:1])
    build_binding, grown_binding = time.perf_counter() - start, rss() - before
    before, start = rss(), time.perf_counter()
    reference = rtcore_scene.EmbreeScene()
    TriangleMesh(reference, vertices, triangles)
    reference.run(o[:1], d[:1], dists=far[:1].copy(), output=1)
    build_embreex, grown_embreex = time.perf_counter() - start, rss() - before
    n = len(triangles)
    print(f"build: binding {build_binding:.2f} s, +{grown_binding / n:.0f} B/triangle resident; "
          f"embreex {build_embreex:.2f} s, +{grown_embreex / n:.0f} B/triangle (the mesh arrays, "
          f"{(vertices.nbytes + triangles.nbytes) / n:.0f} B/triangle, exist before both)")
    cases = {
        "closest, embreex": lambda: reference.run(o, d, dists=far.copy(), output=1),
        "closest, binding": lambda: binding.intersect(o, d, far),
        "occluded, embreex": lambda: reference.run(o, d, dists=far.copy(), query="OCCLUDED"),
        "occluded, binding": lambda: binding.occluded(o, d, far),
    }
    for name, function in cases.items():
        function()
        one = cpu_rate(function, args.rays)
        two = wall_rate_threads(function, args.rays, 2)
        print(f"  {name:18s}: {one / 1e6:.2f} M rays/s one thread (CPU time), {two / 1e6:.2f} M rays/s with 2 threads")
    return 0


if __name__ == "__main__":
    sys.exit(main())
