"""Benchmark: the cost of object motion blur against the same static render (not collected by
pytest). The Cornell fog scene of bench_integrator with a small emissive panel under the ceiling,
rendered still, then with object motion (3 steps: the two blocks sliding and turning -- Embree
motion instances), with the emissive panel moving too (a deforming world copy sampled at each
ray's time), and with the fog box drifting as well (per-path volume stacks at each ray's time).
Each render repeated, the best time kept. Cycles' aim: motion blur within 1.5x of a static render.
Usage: python tests/benchmarks/bench_object_motion.py [--resolution N] [--spp N] [--repeats N]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from volpath_native import Material, Mesh, render

from bench_integrator import cornell_fog_scene


def _placed(angle, shift):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, shift[0]], [s, c, 0, shift[1]], [0, 0, 1, shift[2]]])


def _moving(mesh: Mesh, angle, shift, pivot) -> Mesh:
    """The mesh as an instance about `pivot` with 3 steps turning by +-angle and sliding by +-shift."""
    local = mesh.vertices.astype(np.float64) - pivot
    steps = np.stack([_placed(a * angle, pivot + a * np.asarray(shift)) for a in (-1.0, 0.0, 1.0)])
    return Mesh(mesh.name, local, mesh.triangles, mesh.material_ids, instances=steps[1][None], motion=steps[None])


def scene_variant(label, resolution, spp):
    scene = cornell_fog_scene(resolution=resolution, spp=spp, threads=1)
    scene.materials.append(Material("glow", base_color=0.0, emission=[30.0, 25.0, 20.0]))
    panel = Mesh("panel", np.float64([[2.2, 2.2, 5.2], [3.3, 2.2, 5.2], [3.3, 3.3, 5.2], [2.2, 3.3, 5.2]]),
                 np.int32([[0, 2, 1], [0, 3, 2]]), np.int32([4, 4]))
    scene.meshes.append(panel)
    moves = {"tall": (0.15, [0.3, 0, 0]), "short": (-0.2, [0, 0.3, 0])}
    if label in ("blocks", "blocks + panel", "blocks + panel + fog"):
        scene.meshes = [_moving(m, *moves[m.name], m.vertices.mean(axis=0)) if m.name in moves else m
                        for m in scene.meshes]
    if label in ("blocks + panel", "blocks + panel + fog"):
        scene.meshes = [_moving(m, 0.3, [0.4, 0, 0], m.vertices.mean(axis=0)) if m.name == "panel" else m
                        for m in scene.meshes]
    if label == "blocks + panel + fog":
        scene.meshes = [_moving(m, 0.0, [0.05, 0, 0], np.zeros(3)) if m.name == "fog" else m for m in scene.meshes]
    return scene


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--resolution", type=int, default=96)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    times = {}
    for label in ("still", "blocks", "blocks + panel", "blocks + panel + fog"):
        scene = scene_variant(label, args.resolution, args.spp)
        render(scene)  # kernels loaded, buffers warm
        best = min(_timed(scene) for _ in range(args.repeats))
        times[label] = best
        print(f"{label:>22}: {best:.3f} s  ({args.resolution}^2 x {args.spp} spp, 1 thread)  "
              f"{best / times['still']:.3f}x the still render", flush=True)


def _timed(scene):
    start = time.perf_counter()
    render(scene)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
