"""Benchmark: the cost of object motion blur against the same static render (not collected by
pytest). The Cornell fog scene of bench_integrator with a small emissive panel under the ceiling,
rendered still, then with object motion (3 steps: the two blocks sliding and turning -- Embree
motion instances), with the emissive panel moving too (a deforming world copy sampled at each
ray's time), and with the fog box drifting as well (per-path volume stacks at each ray's time).
Then bench_cloud's 128^3 cloud (a grid medium in its bounds box, sun and sky), still and moving
(sliding and turning: its lookups, majorant DDA and box placed at each path's time,
medium_motion.py), the moving cloud's time as a ratio to the still cloud's.
Each render repeated, the best time kept. Cycles' aim: motion blur within 1.5x of a static render.
Usage: python tests/benchmarks/bench_object_motion.py [--resolution N] [--spp N] [--repeats N]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from volpath_native import Camera, Film, Material, Mesh, RenderSettings, Scene, SunLight, World, render
from volpath_native.grid_medium import GridMedium, principled_volume_coefficients

from bench_cloud import CLOUD_SIZE, cloud_density
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


def cloud_variant(moving: bool, resolution, spp):
    """bench_cloud's cloud as a grid medium (white, g = 0.5, density x 6) lit by a sun and a sky,
    seen from the side; moving: 3 steps sliding 0.3 m and turning 0.3 rad over the shutter."""
    sigma_s, sigma_a = principled_volume_coefficients(0.95, 6.0)
    index_to_object = np.diag([CLOUD_SIZE / 128] * 3 + [1.0])
    index_to_object[:3, 3] = -CLOUD_SIZE / 2
    steps = np.stack([np.vstack([_placed(a * 0.3, [a * 0.3, 0, 0]), [0, 0, 0, 1]]) for a in (-1.0, 0.0, 1.0)])
    cloud = GridMedium("cloud", cloud_density(), steps[1] @ index_to_object, sigma_s, sigma_a, g=0.5)
    if moving:
        cloud.set_motion(steps, steps[1])
    look = np.array([[1.0, 0, 0, 0], [0, 0, 1, -5.0], [0, -1, 0, 0.6], [0, 0, 0, 1]])  # from -y towards +y
    look[:3, :3] = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).T
    return Scene(camera=Camera(look, fov=2 * np.arctan(18 / 40)), film=Film(resolution, resolution),
                 meshes=[cloud.boundary_mesh(0)], materials=[Material("cloud bounds", surface="null", medium=0)],
                 media=[cloud], lights=[SunLight("sun", [-0.4, 0.5, -0.75], 4.0, angle=np.radians(1.0))],
                 world=World(background=[0.21, 0.3, 0.48]),
                 settings=RenderSettings(samples=spp, seed=1, threads=1))


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
    for label in ("cloud still", "cloud moving"):
        scene = cloud_variant(label == "cloud moving", args.resolution, args.spp)
        render(scene)
        best = min(_timed(scene) for _ in range(args.repeats))
        times[label] = best
        print(f"{label:>22}: {best:.3f} s  ({args.resolution}^2 x {args.spp} spp, 1 thread)  "
              f"{best / times['cloud still']:.3f}x the still cloud", flush=True)


def _timed(scene):
    start = time.perf_counter()
    render(scene)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
