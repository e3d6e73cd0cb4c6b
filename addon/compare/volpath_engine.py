"""Render a Blender scene with VolPath's renderer directly (export once, render K seeds).

Going through export_scene + volpath_native.render (not bpy.ops.render.render) gives the
comparison the renderer's own sample counts and timings, and lets equal-time runs stop on a clock.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Optional

import bpy
import numpy as np

from .cycles_engine import SettingsSnapshot

# VolPath renders progressively; an equal-time run asks for "as many as fit" and stops on the clock.
EQUAL_TIME_SAMPLE_CAP = 1 << 20


@dataclass
class VolPathRun:
    image: np.ndarray   # (H, W, 4) float32, row 0 = top
    samples: int
    seconds: float      # wall clock of the render call
    render_seconds: float  # the renderer's own timing
    variance: Optional[np.ndarray] = None  # the renderer's own per-pixel variance of the mean


def warm_up() -> float:
    """Compile VolPath's kernels, or load them from the on-disk cache; returns the seconds it took.
    The comparison calls this before any timed run: a first render after an install would otherwise
    count ~100 s of compiling as render time."""
    from volpath_native import warm_up as compile_kernels

    return float(compile_kernels())


def export(scene, resolution: Optional[tuple] = None):
    """The scene as VolPath's native model (+ exporter warnings), at an optional resolution."""
    from ..export import export_scene  # the add-on's exporter; relative: works as an extension too

    snapshot = SettingsSnapshot()
    try:
        if resolution is not None:
            snapshot.set(scene.render, "resolution_x", int(resolution[0]))
            snapshot.set(scene.render, "resolution_y", int(resolution[1]))
            snapshot.set(scene.render, "resolution_percentage", 100)
        view_layer = scene.view_layers[0] if scene.view_layers else None
        if bpy.context.scene is scene:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        else:
            depsgraph = scene.evaluated_depsgraph_get(view_layer)
        depsgraph.update()
        native_scene, warnings = export_scene(depsgraph)
    finally:
        snapshot.restore()
    return native_scene, list(warnings)


def render_runs(native_scene, *, runs: int, samples: int, base_seed: int, time_limit: float = 0.0,
                progress: Optional[Callable[[float, int], None]] = None,
                cancel: Optional[Callable[[], bool]] = None) -> list:
    """`runs` independent renders of the exported scene with seeds base_seed, base_seed + 1, ...

    time_limit > 0: each run renders until that many seconds have passed (equal-time mode).
    progress(runs_done, runs) is called during each run with a fractional runs_done.
    """
    from volpath_native.render import render

    settings = native_scene.settings
    original = (settings.samples, settings.seed, settings.time_limit)
    results = []
    try:
        for k in range(runs):
            settings.seed = int(base_seed + k)
            settings.samples = EQUAL_TIME_SAMPLE_CAP if time_limit > 0 else int(samples)
            # the renderer's own time limit sizes its rounds to the time left (round_schedule.py)
            settings.time_limit = float(time_limit)
            start = time.perf_counter()

            def run_progress(done, total, stats, k=k, start=start):
                if progress:
                    fraction = (time.perf_counter() - start) / time_limit if time_limit > 0 else done / max(total, 1)
                    progress(k + min(fraction, 1.0), runs)

            result = render(native_scene, cancel=cancel, progress=run_progress)
            seconds = time.perf_counter() - start
            if cancel is not None and cancel():
                raise InterruptedError("comparison cancelled")
            if result.samples < 1:
                raise RuntimeError("VolPath returned no samples")
            results.append(VolPathRun(image=np.asarray(result.image, np.float32), samples=int(result.samples),
                                      seconds=seconds, render_seconds=float(result.seconds),
                                      variance=getattr(result, "variance", None)))
            if progress:
                progress(k + 1, runs)
    finally:
        settings.samples, settings.seed, settings.time_limit = original
    return results
