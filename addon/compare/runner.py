"""Compare VolPath with Cycles on one Blender scene: the function the operator, the CLI and the
tests all call.

Both engines render the frame `runs` times with independent seeds under matched settings (see
cycles_engine). The mean of the runs is each engine's image; the spread of the runs gives the
per-pixel variance for the statistical agreement tests in `metrics`.
Modes: 'equal-samples' (both engines get the same total samples per pixel) and 'equal-time'
(both get the same wall-clock budget; the report says how many samples each achieved).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import bpy
import numpy as np

from . import cycles_engine, metrics, report, sheet, volpath_engine

MODES = ("equal-samples", "equal-time")
ProgressCallback = Callable[[float, str], None]


@dataclass
class CompareOptions:
    mode: str = "equal-samples"
    samples: int = 64          # equal-samples: total samples per pixel per engine (split over runs)
    seconds: float = 10.0      # equal-time: wall-clock budget per engine (split over runs)
    runs: int = 8              # independent runs per engine (>= 2: the variance comes from them)
    seed: int = 0
    alpha: float = 0.01        # family-wise significance of the agreement tests
    resolution: Optional[tuple] = None  # override (width, height); None keeps the scene's
    reference: Optional[str] = None     # high-sample reference EXR for each engine's error
    # > 0: Cycles' motion blur as that many stills per run over the shutter (moving volumes: its
    # own blur of them is biased, export/motion.py moving_volume_note); equal-samples only
    cycles_motion_as_stills: int = 0

    def validate(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown mode '{self.mode}' (expected one of {MODES})")
        if self.runs < 2:
            raise ValueError("runs must be at least 2 (the per-pixel variance comes from independent runs)")
        if self.mode == "equal-samples" and self.samples < self.runs:
            raise ValueError(f"samples ({self.samples}) must be at least runs ({self.runs})")
        if self.mode == "equal-time" and not self.seconds > 0:
            raise ValueError("seconds must be positive in equal-time mode")
        if not 0 < self.alpha < 1:
            raise ValueError("alpha must be in (0, 1)")
        if self.cycles_motion_as_stills > 0:
            if self.mode != "equal-samples":
                raise ValueError("Cycles motion as stills works in equal-samples mode only")
            if self.samples_per_run % self.cycles_motion_as_stills:
                raise ValueError(f"samples per run ({self.samples_per_run}) must be a multiple of the Cycles stills "
                                 f"per run ({self.cycles_motion_as_stills})")

    @property
    def samples_per_run(self) -> int:
        return max(1, math.ceil(self.samples / self.runs))


@dataclass
class EngineResult:
    name: str
    runs: list
    statistics: metrics.RunStatistics
    warm_up_seconds: float = 0.0  # kernels compiled or loaded before the timed runs (not in `seconds`)

    @property
    def samples_per_pixel(self) -> int:
        return int(sum(run.samples for run in self.runs))

    @property
    def seconds(self) -> float:
        return float(sum(run.seconds for run in self.runs))

    @property
    def spp_per_second(self) -> float:
        return self.samples_per_pixel / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> dict:
        h, w = self.statistics.mean.shape[:2]
        return {
            "samples_per_pixel": self.samples_per_pixel,
            "samples_per_run": [run.samples for run in self.runs],
            "seconds": self.seconds,
            "seconds_per_run": [run.seconds for run in self.runs],
            "engine_render_seconds": float(sum(run.render_seconds for run in self.runs)),
            "warm_up_seconds": self.warm_up_seconds,
            "spp_per_second": self.spp_per_second,
            "pixel_samples_per_second": self.spp_per_second * w * h,
        }


@dataclass
class CompareResult:
    scene_name: str
    options: CompareOptions
    volpath: EngineResult
    cycles: EngineResult
    comparison: metrics.Comparison
    reference_errors: Optional[dict] = None
    reference_image: Optional[np.ndarray] = field(default=None, repr=False)
    warnings: list = field(default_factory=list)
    outputs: dict = field(default_factory=dict)

    @property
    def agrees(self) -> bool:
        return self.comparison.passed

    def report(self) -> dict:
        h, w = self.volpath.statistics.mean.shape[:2]
        return {
            "scene": self.scene_name,
            "mode": self.options.mode,
            "resolution": [w, h],
            "runs": self.options.runs,
            "seed": self.options.seed,
            "alpha": self.options.alpha,
            "requested": {"samples": self.options.samples, "seconds": self.options.seconds},
            "engines": {"volpath": self.volpath.summary(), "cycles": self.cycles.summary()},
            # In the agreement block, "a" is VolPath and "b" is Cycles.
            "agreement": self.comparison.summary(),
            "agrees": self.agrees,
            "reference": self.reference_errors,
            "warnings": self.warnings,
            "outputs": {k: str(v) for k, v in self.outputs.items()},
        }


class _Progress:
    """Maps engine-run counts to one 0..1 fraction for a single progress bar."""

    def __init__(self, callback: Optional[ProgressCallback], total_steps: int):
        self.callback, self.total, self.done = callback, max(total_steps, 1), 0

    def step(self, message: str) -> None:
        self.done += 1
        self.report(message)

    def at(self, base: float, message: str) -> None:
        """Report a fractional position `base` steps in (no step is consumed)."""
        if self.callback:
            self.callback(min(base / self.total, 1.0), message)

    def report(self, message: str) -> None:
        if self.callback:
            self.callback(min(self.done / self.total, 1.0), message)


def compare_scene(scene, options: CompareOptions, out_dir=None, progress: Optional[ProgressCallback] = None,
                  cancel: Optional[Callable[[], bool]] = None) -> CompareResult:
    """Render `scene` (a bpy Scene) with both engines, compare, and write outputs to `out_dir`."""
    options.validate()
    cycles_engine.require_cycles(scene)
    bar = _Progress(progress, 2 * options.runs + 2)
    bar.report("exporting the scene for VolPath")
    native_scene, warnings = volpath_engine.export(scene, options.resolution)
    reference_image = None
    if options.reference:  # a wrong reference should fail before minutes of rendering, not after
        film = native_scene.film
        reference_image = read_reference(options.reference, _film_shape(film))
    bar.step("exported")
    bar.report("VolPath: compiling or loading its kernels (not timed)")
    warm_up_seconds = volpath_engine.warm_up()  # before the clock: see volpath_engine.warm_up
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    equal_time = options.mode == "equal-time"
    per_run_seconds = options.seconds / options.runs if equal_time else 0.0

    volpath_runs = volpath_engine.render_runs(
        native_scene, runs=options.runs, samples=options.samples_per_run, base_seed=options.seed,
        time_limit=per_run_seconds, cancel=cancel,
        progress=lambda k, n: bar.at(1 + k, f"VolPath run {min(int(k) + 1, n)}/{n}"))
    bar.done = 1 + options.runs
    cycles_runs = cycles_engine.render_runs(
        scene, runs=options.runs, samples=options.samples_per_run, base_seed=options.seed, bounces=bounces,
        time_limit=per_run_seconds, resolution=options.resolution, cancel=cancel,
        progress=lambda k, n: bar.step(f"Cycles run {k}/{n}"), motion_as_stills=options.cycles_motion_as_stills)

    volpath = EngineResult("VolPath", volpath_runs, metrics.run_statistics([r.image for r in volpath_runs]),
                           warm_up_seconds=warm_up_seconds)
    cycles = EngineResult("Cycles", cycles_runs, metrics.run_statistics([r.image for r in cycles_runs]))
    if volpath.statistics.mean.shape != cycles.statistics.mean.shape:
        raise RuntimeError(f"VolPath rendered {volpath.statistics.mean.shape[:2]} pixels but Cycles "
                           f"{cycles.statistics.mean.shape[:2]}: the film settings do not match")
    comparison = metrics.compare_runs(volpath.statistics, cycles.statistics, options.alpha)
    name = Path(bpy.data.filepath).stem if bpy.data.filepath else scene.name
    result = CompareResult(scene_name=name, options=options, volpath=volpath, cycles=cycles,
                           comparison=comparison, warnings=warnings)
    if reference_image is not None:
        result.reference_image = reference_image
        result.reference_errors = reference_errors(result.reference_image, volpath, cycles)
        result.reference_errors["path"] = str(options.reference)
    if out_dir is not None:
        write_outputs(result, out_dir)
    bar.step("done")
    return result


def compare_file(blend_path, options: CompareOptions, out_dir=None,
                 progress: Optional[ProgressCallback] = None) -> CompareResult:
    """Open a .blend (replacing the current file) and compare its active scene."""
    blend_path = Path(blend_path)
    if not blend_path.is_file():
        raise FileNotFoundError(f"no such .blend file: {blend_path}")
    bpy.ops.wm.open_mainfile(filepath=str(blend_path.resolve()))
    return compare_scene(bpy.context.scene, options, out_dir, progress)


def _film_shape(film) -> tuple:
    """(H, W) of what both engines render: the border region when there is one."""
    from volpath_native.camera import crop_window

    _, _, width, height = crop_window(film)
    return height, width


def read_reference(path, shape) -> np.ndarray:
    """The reference EXR, checked against the renders' (H, W, ...) shape."""
    from volpath_native import imageio

    reference = imageio.read_exr(path)
    if reference.shape[:2] != tuple(shape[:2]) or reference.shape[2] < 3:
        raise ValueError(f"reference {path} is {reference.shape[1]}x{reference.shape[0]} px with "
                         f"{reference.shape[2]} channels; the renders are {shape[1]}x{shape[0]} RGB")
    return reference


def reference_errors(reference: np.ndarray, volpath: EngineResult, cycles: EngineResult) -> dict:
    """Each engine's relMSE against the reference and their ratio (< 1: VolPath is closer)."""
    rv = metrics.relmse(volpath.statistics.mean, reference)
    rc = metrics.relmse(cycles.statistics.mean, reference)
    return {"relmse_volpath": rv, "relmse_cycles": rc, "error_ratio": rv / rc if rc > 0 else float("inf")}


def write_outputs(result: CompareResult, out_dir) -> dict:
    """EXRs (means and variances of both engines), the PNG sheet, report.json and report.md."""
    from volpath_native import imageio

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "volpath_exr": imageio.write_exr(out / "volpath.exr", result.volpath.statistics.mean.astype(np.float32)),
        "cycles_exr": imageio.write_exr(out / "cycles.exr", result.cycles.statistics.mean.astype(np.float32)),
        "volpath_variance_exr": imageio.write_exr(out / "volpath_variance.exr",
                                                  result.volpath.statistics.variance_of_mean.astype(np.float32)),
        "cycles_variance_exr": imageio.write_exr(out / "cycles_variance.exr",
                                                 result.cycles.statistics.variance_of_mean.astype(np.float32)),
    }
    paths["sheet_png"] = write_sheet(result, out / "sheet.png")
    result.outputs.update(paths)
    result.outputs["report_json"] = out / "report.json"
    result.outputs["report_md"] = out / "report.md"
    data = result.report()
    report.write_json(out / "report.json", data)
    report.write_markdown(out / "report.md", data)
    return result.outputs


def sheet_panels(result: CompareResult, exposure: Optional[float] = None) -> list:
    """Rows of panels: VolPath | Cycles | difference (and reference | errors with a reference)."""
    v, c = result.volpath, result.cycles
    exposure = metrics.display_exposure(c.statistics.mean) if exposure is None else exposure
    agreement = result.comparison
    rows = [[
        sheet.render_panel("VolPath", v.statistics.mean,
                           exposure, f"{v.samples_per_pixel} spp, {v.seconds:.1f} s"),
        sheet.render_panel("Cycles", c.statistics.mean,
                           exposure, f"{c.samples_per_pixel} spp, {c.seconds:.1f} s"),
        sheet.difference_panel("(VolPath - Cycles) / mean", agreement.relative_difference,
                               caption=f"{100 * agreement.pixel.fraction_passed:.1f}% px pass the t-test"),
    ]]
    ref = result.reference_errors
    if ref and result.reference_image is not None:
        image = result.reference_image
        scale = metrics.difference_scale(metrics.signed_relative_difference(c.statistics.mean, image))
        rows.append([
            sheet.render_panel("Reference", image, exposure, ""),
            sheet.difference_panel("VolPath - reference", metrics.signed_relative_difference(v.statistics.mean, image),
                                   scale, f"relMSE {ref['relmse_volpath']:.3g}"),
            sheet.difference_panel("Cycles - reference", metrics.signed_relative_difference(c.statistics.mean, image),
                                   scale, f"relMSE {ref['relmse_cycles']:.3g}"),
        ])
    return rows


def write_sheet(result: CompareResult, path) -> Path:
    title = (f"{result.scene_name}: {result.options.mode}, mean ratio R/G/B "
             + " ".join(f"{r:.3f}" for r in result.comparison.means.ratio))
    return sheet.write_contact_sheet(path, sheet_panels(result), title)
