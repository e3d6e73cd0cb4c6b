"""Command line: render a saved .vpscene without Blender.

    python -m volpath_native render SCENE.vpscene -o out.exr [--spp N] [--seed S] [--png out.png]
        [--threads T] [--parallelism processes|threads] [--batch-size B] [--max-bounces N] [--diffuse-bounces N]
        [--volume-bounces N] [--transparent-bounces N] [--volume-sampling mis|distance|equiangular]

Errors are one line on stderr, never a traceback. Exit codes: 0 rendered; 1 failed unexpectedly (a
bug: please report); 2 unusable input (the file and field are named) or arguments; 130 interrupted
(Ctrl-C cancels the render and the samples done so far are still written).
"""
from __future__ import annotations

import argparse
import signal
import sys

from .render import render
from .scene import SceneError
from .scene_io import load_scene


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="volpath", description="VolPath volumetric path tracer")
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a .vpscene file to an EXR image")
    r.add_argument("scene", help="input .vpscene file")
    r.add_argument("-o", "--output", required=True, help="output OpenEXR file (scene-linear RGBA)")
    r.add_argument("--png", help="also write an sRGB 8-bit preview PNG")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    r.add_argument("--seed", type=int, help="random seed (default: the scene's)")
    r.add_argument("--threads", type=int, help="worker threads (0 = all cores)")
    r.add_argument("--batch-size", type=int, help="paths per wavefront batch")
    # Forked processes are the CLI default: they scaled 1.92x on 2 cores against 1.73x for threads
    # (tests/benchmarks/bench_integrator.py). Blender needs threads (forking Blender is unsafe).
    r.add_argument("--parallelism", choices=("processes", "threads"), default="processes",
                   help="forked worker processes (default; threads where fork is unavailable) or threads")
    r.add_argument("--processes", action="store_const", const="processes", dest="parallelism",
                   help="same as --parallelism processes (kept for old scripts)")
    for name in ("max", "diffuse", "volume", "transparent"):
        r.add_argument(f"--{name}-bounces", type=int)
    r.add_argument("--volume-sampling", choices=("mis", "distance", "equiangular"))
    r.add_argument("--quiet", action="store_true", help="no progress output")
    return parser


EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        return _render(args)
    except SceneError as exc:
        print(f"\nerror: {exc}" if _progress_shown else f"error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # noqa: BLE001 - one line, not a traceback, even for a bug
        print(f"\nerror: {args.scene}: VolPath failed: {type(exc).__name__}: {exc} (please report)", file=sys.stderr)
        return EXIT_FAILED


_progress_shown = False


def _render(args) -> int:
    global _progress_shown
    try:
        scene = load_scene(args.scene)
    except OSError as exc:
        print(f"error: cannot read {args.scene}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT
    s = scene.settings
    overrides = dict(samples=args.spp, seed=args.seed, threads=args.threads, batch_size=args.batch_size,
                     max_bounces=args.max_bounces, diffuse_bounces=args.diffuse_bounces,
                     volume_bounces=args.volume_bounces, transparent_bounces=args.transparent_bounces,
                     volume_sampling=args.volume_sampling,
                     parallelism=args.parallelism)
    for key, value in overrides.items():
        if value is not None:
            setattr(s, key, value)

    def progress(done, total, stats):
        global _progress_shown
        if not args.quiet:
            _progress_shown = True
            print(f"\r{done}/{total} spp  {stats['seconds']:.1f} s  "
                  f"{stats['samples_per_second'] / 1e3:.0f} k samples/s  "
                  f"{stats['rays_per_second'] / 1e6:.2f} M rays/s", end="", file=sys.stderr, flush=True)

    # Ctrl-C cancels the render (polled like Esc in Blender); the partial image is still written.
    interrupted = []
    previous = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, lambda *_: interrupted.append(True))
    except ValueError:  # not the main thread: leave Ctrl-C alone
        previous = None
    try:
        result = render(scene, progress=progress, cancel=lambda: bool(interrupted))
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if _progress_shown:
        print(file=sys.stderr)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    from .imageio import write_exr, write_png
    write_exr(args.output, result.image)
    if args.png:
        write_png(args.png, result.image)
    st = result.stats
    print(f"rendered {result.samples} spp in {result.seconds:.2f} s: "
          f"{st.get('samples_per_second', 0) / 1e3:.1f} k samples/s, "
          f"{st.get('vertices_per_second', 0) / 1e6:.2f} M vertices/s, "
          f"{st.get('rays_per_second', 0) / 1e6:.2f} M rays/s -> {args.output}")
    if result.cancelled:
        print(f"interrupted: {result.samples} of {s.samples} spp written", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK
