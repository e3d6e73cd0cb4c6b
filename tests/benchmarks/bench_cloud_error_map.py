"""Benchmark: where the noise cloud's error is (not collected by pytest).

The noise cloud (examples/noise_cloud.py) is rendered with each light alone (point, sun, sky) and
with all of them, by both engines at a fixed sample count, against a high-sample Cycles reference.
Pixels are classed by what the camera ray hits first (the cloud's box, the floor, nothing: sky);
per class it prints the error per sample (relMSE x spp, the reference's own noise removed as in
equal_time.py) of each engine, their ratio and the class's share of VolPath's error.

    python tests/benchmarks/bench_cloud_error_map.py [--resolution 48] [--spp 64] [--reference-spp 4096]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
for path in (str(ROOT), str(ROOT / "native")):
    if path not in sys.path:
        sys.path.insert(0, path)

LIGHTS = ("all", "point", "sun", "sky")


def _build(resolution: int, keep: str):
    """The noise cloud with only `keep`'s light(s)."""
    import bpy
    from examples import noise_cloud, scene_builder as sb

    scene = noise_cloud.build(resolution=(resolution, resolution), samples=16)
    if keep != "all":
        for obj in list(scene.objects):
            if obj.type == "LIGHT" and obj.data.type.lower() != keep:
                bpy.data.objects.remove(obj, do_unlink=True)
        if keep != "sky":
            sb.set_world_background(scene, (0.05, 0.07, 0.1), 0.0)
    return scene


def pixel_classes(scene, resolution: int) -> np.ndarray:
    """(H, W) int: 0 sky, 1 floor, 2 cloud, by the first object each pixel centre's camera ray hits
    (row 0 = top, as the engines' images); the objects' world bounding boxes, floor at z = 0."""
    scene.view_layers[0].update()  # matrix_world of objects placed since the last update
    cam = scene.camera
    frame = [np.array(cam.matrix_world @ v) for v in cam.data.view_frame(scene=scene)]  # tr, br, bl, tl
    origin = np.array(cam.matrix_world.translation)
    cloud = scene.objects["Cloud"]
    corners = np.array([cloud.matrix_world @ __import__("mathutils").Vector(c) for c in cloud.bound_box])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    classes = np.zeros((resolution, resolution), np.int64)
    for row in range(resolution):
        for col in range(resolution):
            u, v = (col + 0.5) / resolution, (row + 0.5) / resolution
            top, bottom = frame[3] + (frame[0] - frame[3]) * u, frame[2] + (frame[1] - frame[2]) * u
            d = top + (bottom - top) * v - origin
            with np.errstate(divide="ignore", invalid="ignore"):
                t0, t1 = (lo - origin) / d, (hi - origin) / d
            near, far = np.nanmax(np.minimum(t0, t1)), np.nanmin(np.maximum(t0, t1))
            if near <= far and far > 0:
                classes[row, col] = 2
            elif d[2] < 0 and np.all(np.abs((origin + d * (-origin[2] / d[2]))[:2]) <= 4.0):
                classes[row, col] = 1
    return classes


def per_pixel_error(image, reference, epsilon=None):
    from addon.compare import metrics

    x, y = metrics.rgb(image), metrics.rgb(reference)
    eps = metrics.RELMSE_EPSILON if epsilon is None else epsilon
    return ((x - y) ** 2 / (y ** 2 + eps)).mean(axis=2)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=48)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--reference-spp", type=int, default=4096)
    parser.add_argument("--lights", default=",".join(LIGHTS))
    parser.add_argument("--save", default="", help="folder for the per-pixel error maps (.npy)")
    parser.add_argument("--residual-scale", type=float, default=1.0,
                        help="x the residual ratio tracking rate of program media (shadow-ray variance / scale)")
    args = parser.parse_args(argv)

    import addon

    addon.register()
    from addon.compare import cycles_engine, volpath_engine
    import volpath_native

    volpath_native.warm_up()
    names = ("sky", "floor", "cloud")
    for keep in args.lights.split(","):
        scene = _build(args.resolution, keep)
        classes = pixel_classes(scene, args.resolution)
        native_scene, _ = volpath_engine.export(scene)
        for medium in native_scene.media:
            if hasattr(medium, "residual_rate"):
                medium.residual_rate *= args.residual_scale
        bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
        with tempfile.TemporaryDirectory(prefix="volpath_cloud_map_") as tmp, \
                cycles_engine.matched_settings(scene, bounces):
            reference = cycles_engine.render_once(scene, samples=args.reference_spp, seed=1000, scratch=Path(tmp))
            cycles = cycles_engine.render_once(scene, samples=args.spp, seed=1, scratch=Path(tmp))
        start = time.perf_counter()
        volpath = volpath_engine.render_runs(native_scene, runs=1, samples=args.spp, base_seed=1)[0]
        seconds_v = time.perf_counter() - start
        err_c = per_pixel_error(cycles.image, reference.image)
        err_v = per_pixel_error(volpath.image, reference.image)
        share = args.spp / (args.spp + args.reference_spp)  # E[raw] = e (1 + n / n_ref): remove the ref's part
        per_sample_c = (err_c.mean() - err_c.mean() * share) * args.spp
        print(f"[{keep}] {args.resolution}^2 at {args.spp} spp: Cycles {cycles.render_seconds:.2f} s, VolPath "
              f"{volpath.render_seconds:.2f} s; relMSE x spp Cycles {per_sample_c:.4g}, VolPath "
              f"{(err_v.mean() - err_c.mean() * share) * args.spp:.4g}")
        for c, name in enumerate(names):
            mask = classes == c
            if not mask.any():
                continue
            ref_part = err_c[mask].mean() * share
            ec, ev = (err_c[mask].mean() - ref_part) * args.spp, (err_v[mask].mean() - ref_part) * args.spp
            print(f"  {name:5s} {mask.mean() * 100:5.1f} % of pixels: error per sample Cycles {ec:.4g}, VolPath "
                  f"{ev:.4g}, ratio {ev / max(ec, 1e-30):.3g}; share of VolPath's error "
                  f"{err_v[mask].sum() / err_v.sum() * 100:.1f} %, of Cycles' {err_c[mask].sum() / err_c.sum() * 100:.1f} %")
        if args.save:
            out = Path(args.save)
            out.mkdir(parents=True, exist_ok=True)
            np.save(out / f"{keep}_classes.npy", classes)
            np.save(out / f"{keep}_err_volpath.npy", err_v)
            np.save(out / f"{keep}_err_cycles.npy", err_c)
            np.save(out / f"{keep}_reference.npy", reference.image)
            np.save(out / f"{keep}_volpath.npy", volpath.image)
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
