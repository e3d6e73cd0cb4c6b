"""Benchmark: the cost of a lens and of camera motion blur against the same static pinhole render
(not collected by pytest). The Cornell fog scene of bench_integrator, rendered pinhole, with depth
of field, with camera motion blur (3 motion steps, the camera sliding and turning) and both; each
render repeated, the best time kept. Cycles' aim: motion blur within 1.5x of a static render.
Usage: python tests/benchmarks/bench_cameras.py [--resolution N] [--spp N] [--repeats N]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from volpath_native import render

from bench_integrator import cornell_fog_scene


def _turned(matrix, angle, shift):
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    out = turn @ matrix
    out[0, 3] += shift
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    variants = {"pinhole": {}, "depth of field": dict(aperture_size=0.1, focus_distance=8.0, aperture_blades=6),
                "motion blur": "motion", "both": "both"}
    times = {}
    for label, change in variants.items():
        scene = cornell_fog_scene(resolution=args.resolution, spp=args.spp, threads=1)
        cam = scene.camera
        if change in ("motion", "both"):
            m = cam.camera_to_world
            cam.motion_transforms = [_turned(m, -0.03, -0.2), m, _turned(m, 0.03, 0.2)]
        if change == "both":
            change = variants["depth of field"]
        if isinstance(change, dict):
            for key, value in change.items():
                setattr(cam, key, value)
        render(scene)  # kernels loaded, buffers warm
        best = min(_timed(scene) for _ in range(args.repeats))
        times[label] = best
        print(f"{label:>15}: {best:.3f} s  ({args.resolution}^2 x {args.spp} spp, 1 thread)  "
              f"{best / times['pinhole']:.3f}x the pinhole")


def _timed(scene):
    start = time.perf_counter()
    render(scene)
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
