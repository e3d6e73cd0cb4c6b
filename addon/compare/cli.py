"""Headless comparison: `python -m addon.compare run FILE.blend --out DIR` and `... demo --out DIR`.

Runs with the `bpy` module (Blender as a Python module) from the repository root.
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path

# The demo: small enough for < 5 min on 2 cores including Blender start-up, big enough to see.
DEMO_RESOLUTION = (128, 128)
DEMO_SAMPLES = 128
DEMO_RUNS = 8
DEMO_EXAMPLE = "glass_of_liquid"  # the headline scene: coloured liquid in glass, in fog, under a spot


def _parse_resolution(text: str) -> tuple:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must look like 64x48, got '{text}'") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError("resolution must be positive")
    return width, height


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m addon.compare",
                                     description="Render a scene with VolPath and Cycles and compare them.")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="compare one .blend file")
    run.add_argument("blend", type=Path, help="the .blend file (its active scene is rendered)")
    demo = sub.add_parser("demo", help="build an example scene (default: the glass of liquid in fog) and compare it")
    for p in (run, demo):
        p.add_argument("--out", type=Path, required=True, help="output folder")
        p.add_argument("--mode", choices=("equal-samples", "equal-time"), default="equal-samples")
        p.add_argument("--runs", type=int, default=DEMO_RUNS, help="independent runs per engine (>= 2)")
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--alpha", type=float, default=0.01, help="family-wise significance of the tests")
        p.add_argument("--seconds", type=float, default=10.0, help="equal-time budget per engine")
        p.add_argument("--reference", type=Path, help="high-sample reference EXR")
        p.add_argument("--resolution", type=_parse_resolution, help="override, e.g. 64x64")
        p.add_argument("--cycles-motion-as-stills", type=int, default=0, metavar="N",
                       help="Cycles' motion blur as N stills per run over the shutter (its blur of moving "
                            "volumes is biased); equal-samples only")
    run.add_argument("--spp", type=int, default=64, help="equal-samples: total samples per pixel per engine")
    demo.add_argument("--spp", type=int, default=DEMO_SAMPLES)
    demo.add_argument("--example", default=DEMO_EXAMPLE,
                      help="a module of examples/ with a build(resolution, samples) function, e.g. cornell_fog")
    ref = sub.add_parser("reference", help="render a high-sample Cycles reference EXR of a .blend "
                                           "(matched settings, for --reference)")
    ref.add_argument("blend", type=Path)
    ref.add_argument("--out", type=Path, required=True, help="the EXR to write")
    ref.add_argument("--spp", type=int, default=4096)
    ref.add_argument("--seed", type=int, default=1000, help="keep it apart from the compared runs' seeds")
    ref.add_argument("--resolution", type=_parse_resolution, help="override, e.g. 64x64")
    return parser


class TextProgress:
    """A one-line progress bar on stderr."""

    def __init__(self, stream=sys.stderr, width: int = 30, interval: float = 0.25):
        self.stream, self.width, self.start = stream, width, time.perf_counter()
        self.interval, self.last_write, self.last_message = interval, -1.0, None

    def __call__(self, fraction: float, message: str) -> None:
        now = time.perf_counter()
        if fraction < 1.0 and message == self.last_message and now - self.last_write < self.interval:
            return  # renderer rounds can be much faster than anyone reads
        self.last_write, self.last_message = now, message
        filled = int(round(fraction * self.width))
        elapsed = time.perf_counter() - self.start
        self.stream.write(f"\r[{'#' * filled}{'.' * (self.width - filled)}] {100 * fraction:5.1f}% "
                          f"{elapsed:6.1f}s  {message:<28}")
        if fraction >= 1.0:
            self.stream.write("\n")
        self.stream.flush()


@contextlib.contextmanager
def quiet_stdout():
    """Silence C-level stdout (Cycles prints a status line per sample) so the progress bar on
    stderr stays readable; Python's own prints after the block are unaffected."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no real stdout (embedded): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


def _register_addon():
    """Register the add-on (engine, settings at scene.volpath, exporter) in this bpy session."""
    import bpy

    if "volpath" in bpy.types.Scene.bl_rna.properties:
        return  # already registered
    import addon

    addon.register()


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        import bpy  # noqa: F401  (Blender as a module)
    except ImportError:
        print("error: the bpy module is not installed (run `make venv` and use .venv/bin/python)", file=sys.stderr)
        return 2
    from . import cycles_engine, runner

    _register_addon()
    if args.command == "reference":
        return write_reference(args)
    options = runner.CompareOptions(mode=args.mode, samples=args.spp, seconds=args.seconds, runs=args.runs,
                                    seed=args.seed, alpha=args.alpha, resolution=args.resolution,
                                    reference=str(args.reference) if args.reference else None,
                                    cycles_motion_as_stills=args.cycles_motion_as_stills)
    try:
        options.validate()
        with quiet_stdout():
            if args.command == "demo":
                result = run_demo(args.out, options, args.example)
            else:
                result = runner.compare_file(args.blend, options, args.out, TextProgress())
    except cycles_engine.CyclesUnavailable as error:
        print(f"error: {error}", file=sys.stderr)
        return 3
    except (ValueError, FileNotFoundError, RuntimeError) as error:
        print(f"\nerror: {error}", file=sys.stderr)
        return 1
    print_summary(result)
    return 0


def write_reference(args) -> int:
    """One long Cycles render under the comparison's matched settings (VolPath's bounce limits)."""
    import bpy

    from volpath_native import imageio

    from . import cycles_engine, volpath_engine

    if not args.blend.is_file():
        print(f"error: no such .blend file: {args.blend}", file=sys.stderr)
        return 1
    bpy.ops.wm.open_mainfile(filepath=str(args.blend.resolve()))
    scene = bpy.context.scene
    try:
        native_scene, _ = volpath_engine.export(scene, args.resolution)
        bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
        print(f"rendering a {args.spp} spp Cycles reference ...", file=sys.stderr)
        with quiet_stdout(), cycles_engine.matched_settings(scene, bounces, args.resolution):
            run = cycles_engine.render_reference(scene, samples=args.spp, seed=args.seed)
    except (cycles_engine.CyclesUnavailable, ValueError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    imageio.write_exr(args.out, run.image)
    print(f"reference ({run.samples} spp, {run.seconds:.1f} s): {args.out}")
    return 0


def run_demo(out_dir: Path, options, example: str = DEMO_EXAMPLE):
    """Build examples/<example>.py's scene, save it next to the results, compare."""
    import importlib

    import bpy

    from . import runner

    root = Path(__file__).resolve().parents[2]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    from examples import scene_builder

    module = importlib.import_module(f"examples.{example}")
    if options.resolution is None:
        options.resolution = DEMO_RESOLUTION
    module.build(resolution=options.resolution, samples=options.samples)
    _register_addon()
    out_dir = Path(out_dir)
    blend = scene_builder.save(out_dir / f"{example}.blend")
    result = runner.compare_scene(bpy.context.scene, options, out_dir, TextProgress())
    result.outputs["blend"] = blend
    return result


def print_summary(result) -> None:
    agreement = result.comparison
    v, c = result.volpath, result.cycles
    print(f"VolPath: {v.samples_per_pixel} spp in {v.seconds:.2f} s ({v.spp_per_second:.1f} spp/s); "
          f"Cycles: {c.samples_per_pixel} spp in {c.seconds:.2f} s ({c.spp_per_second:.1f} spp/s)")
    print(f"VolPath kernels were compiled or loaded in {v.warm_up_seconds:.2f} s before timing (not counted)")
    print("mean ratio VolPath/Cycles R/G/B: " + " ".join(f"{r:.4f}" for r in agreement.means.ratio)
          + f"  (means agree: {'yes' if agreement.means.passed else 'NO'})")
    print(f"pixels passing the Sidak-corrected t-test: {100 * agreement.pixel.fraction_passed:.2f}%  "
          f"(pixels agree: {'yes' if agreement.pixel.passed else 'NO'}); relMSE {agreement.relmse_a_vs_b:.4g}")
    for size, test in agreement.blocks.items():
        print(f"  {size}x{size} blocks passing: {100 * test.fraction_passed:.2f}% "
              f"(agree: {'yes' if test.passed else 'NO'})")
    print(f"verdict: {'VolPath and Cycles agree' if result.agrees else 'VolPath and Cycles DISAGREE'} "
          f"at family-wise significance {result.options.alpha:g}")
    if result.reference_errors:
        ref = result.reference_errors
        print(f"relMSE vs reference: VolPath {ref['relmse_volpath']:.4g}, Cycles {ref['relmse_cycles']:.4g}, "
              f"ratio {ref['error_ratio']:.3g}")
    for warning in result.warnings:
        print(f"warning: {warning}")
    for name, path in result.outputs.items():
        print(f"{name:>22}: {path}")
