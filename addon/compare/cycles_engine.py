"""Render a Blender scene with Cycles under settings matched to VolPath's, then restore the user's.

Matched means: CPU, no denoising, no adaptive sampling, no clamping, no light-threshold
termination, no path guiding, Filter Glossy 0, the bounce limits of VolPath's RenderSettings, the same resolution,
camera and pixel filter (both engines read them from the same .blend), unbiased volume rendering
(Cycles 5.0's default null-scattering path, `volume_biased` off) and scene-linear float output.
Each run is written to an uncompressed 32-bit EXR in a scratch folder and read back.
"""
from __future__ import annotations

import contextlib
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Optional

import bpy
import numpy as np

# Samples of the pilot render that measures Cycles' cost per sample for equal-time runs.
PILOT_SAMPLES = 8


class CyclesUnavailable(RuntimeError):
    """Cycles is not registered in this Blender (disabled add-on or a build without it)."""


def cycles_available() -> bool:
    # The engine enum is dynamic (its RNA lists only built-in engines): look at the registered
    # engine classes and at the settings Cycles adds to the scene.
    registered = {getattr(engine, "bl_idname", None) for engine in bpy.types.RenderEngine.__subclasses__()}
    return "CYCLES" in registered and "cycles" in bpy.types.Scene.bl_rna.properties


def require_cycles(scene) -> None:
    if not cycles_available():
        raise CyclesUnavailable("Cycles is not available in this Blender: enable the Cycles add-on "
                                "(Preferences > Add-ons > Cycles Render Engine) to compare with it")


class SettingsSnapshot:
    """Set attributes on Blender data while remembering the old values; restore() undoes all."""

    def __init__(self):
        self._saved: list = []

    def set(self, owner, attribute: str, value) -> None:
        if not hasattr(owner, attribute):
            return  # older/newer Blender without this setting: nothing to match
        self._saved.append((owner, attribute, getattr(owner, attribute)))
        setattr(owner, attribute, value)

    def restore(self) -> None:
        for owner, attribute, value in reversed(self._saved):
            try:
                setattr(owner, attribute, value)
            except (AttributeError, TypeError, ReferenceError):
                pass  # the data block went away; nothing left to restore
        self._saved.clear()


@dataclass
class BounceLimits:
    """VolPath's bounce limits (Cycles' meanings, see volpath_native.scene.RenderSettings)."""

    max_bounces: int = 12
    diffuse_bounces: int = 4
    glossy_bounces: int = 4
    transmission_bounces: int = 12
    volume_bounces: int = 0
    transparent_bounces: int = 8
    light_tree: bool = True  # not a bounce limit: the light selection, matched as well

    @classmethod
    def from_settings(cls, settings) -> "BounceLimits":
        values = {name: int(getattr(settings, name)) for name in cls.__dataclass_fields__ if name != "light_tree"}
        return cls(**values, light_tree=bool(getattr(settings, "light_tree", True)))


@contextlib.contextmanager
def matched_settings(scene, bounces: BounceLimits, resolution: Optional[tuple] = None) -> Iterator[SettingsSnapshot]:
    """Configure `scene` for a Cycles render matched to VolPath; the user's settings come back
    on exit, also after an error."""
    require_cycles(scene)
    snapshot = SettingsSnapshot()
    try:
        render, cycles = scene.render, scene.cycles
        snapshot.set(render, "engine", "CYCLES")
        snapshot.set(cycles, "device", "CPU")
        snapshot.set(cycles, "use_denoising", False)
        snapshot.set(cycles, "use_adaptive_sampling", False)
        snapshot.set(cycles, "sample_clamp_direct", 0.0)
        snapshot.set(cycles, "sample_clamp_indirect", 0.0)
        # 0 disables probabilistic light-sample termination (unbiased either way, but noisier).
        snapshot.set(cycles, "light_sampling_threshold", 0.0)
        # the same light selection as VolPath's (per-point light tree, or by power)
        snapshot.set(cycles, "use_light_tree", bounces.light_tree)
        snapshot.set(cycles, "use_guiding", False)
        snapshot.set(cycles, "use_animated_seed", False)
        snapshot.set(cycles, "use_layer_samples", "IGNORE")
        snapshot.set(cycles, "use_sample_subset", False)
        # Cycles 5.0: unbiased null-scattering volumes (True would be ray marching, biased).
        snapshot.set(cycles, "volume_biased", False)
        # VolPath does not blur glossy closures after rough bounces (Filter Glossy = 0; README).
        snapshot.set(cycles, "blur_glossy", 0.0)
        snapshot.set(cycles, "min_light_bounces", 0)
        snapshot.set(cycles, "min_transparent_bounces", 0)
        snapshot.set(cycles, "max_bounces", bounces.max_bounces)
        snapshot.set(cycles, "diffuse_bounces", bounces.diffuse_bounces)
        snapshot.set(cycles, "glossy_bounces", bounces.glossy_bounces)
        snapshot.set(cycles, "transmission_bounces", bounces.transmission_bounces)
        snapshot.set(cycles, "volume_bounces", bounces.volume_bounces)
        snapshot.set(cycles, "transparent_max_bounces", bounces.transparent_bounces)
        snapshot.set(render, "use_persistent_data", False)
        snapshot.set(render, "film_transparent", False)
        # With a render border, VolPath renders just the region: make Cycles' file the region too.
        snapshot.set(render, "use_crop_to_border", True)
        snapshot.set(render, "use_compositing", False)
        snapshot.set(render, "use_sequencer", False)
        if resolution is not None:
            snapshot.set(render, "resolution_x", int(resolution[0]))
            snapshot.set(render, "resolution_y", int(resolution[1]))
            snapshot.set(render, "resolution_percentage", 100)
        settings = render.image_settings
        snapshot.set(settings, "file_format", "OPEN_EXR")
        snapshot.set(settings, "color_mode", "RGBA")
        snapshot.set(settings, "color_depth", "32")
        snapshot.set(settings, "exr_codec", "NONE")
        snapshot.set(render, "use_file_extension", True)
        # Changed per run by render_once: remembered here so they come back too.
        snapshot.set(cycles, "samples", cycles.samples)
        snapshot.set(cycles, "seed", cycles.seed)
        snapshot.set(cycles, "time_limit", cycles.time_limit)
        snapshot.set(render, "filepath", render.filepath)
        yield snapshot
    finally:
        snapshot.restore()


@dataclass
class CyclesRun:
    image: np.ndarray   # (H, W, 4) float32, row 0 = top
    samples: int
    seconds: float      # wall clock of the whole render call (sync + render + write)
    render_seconds: float  # Cycles' own render time (metadata), 0 if unknown


def render_once(scene, *, samples: int, seed: int, scratch: Optional[Path] = None) -> CyclesRun:
    """One Cycles render of `scene` (already inside matched_settings) to scene-linear pixels."""
    from volpath_native import imageio

    cycles = scene.cycles
    cycles.samples = int(samples)
    cycles.seed = int(seed)
    cycles.time_limit = 0.0
    with contextlib.ExitStack() as stack:
        folder = Path(scratch) if scratch else Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="volpath_cycles_")))
        path = folder / f"cycles_seed{seed}.exr"
        scene.render.filepath = str(path)
        start = time.perf_counter()
        result = bpy.ops.render.render(write_still=True, scene=scene.name)
        seconds = time.perf_counter() - start
        if "FINISHED" not in result or not path.exists():
            raise RuntimeError(f"Cycles render failed for scene '{scene.name}' ({result})")
        image = imageio.read_exr(path)
        metadata = _exr_metadata(path)
    achieved = _metadata_number(metadata, ".samples", default=samples)
    render_seconds = _metadata_seconds(metadata, ".render_time")
    if image.shape[2] == 3:
        image = np.concatenate([image, np.ones(image.shape[:2] + (1,), np.float32)], axis=2)
    return CyclesRun(image=image, samples=int(achieved), seconds=seconds, render_seconds=render_seconds)


def render_runs(scene, *, runs: int, samples: int, base_seed: int, bounces: BounceLimits,
                time_limit: float = 0.0, resolution: Optional[tuple] = None,
                progress: Optional[Callable[[int, int], None]] = None,
                cancel: Optional[Callable[[], bool]] = None, motion_as_stills: int = 0) -> list:
    """`runs` independent Cycles renders (seeds base_seed, base_seed + 1, ...).

    time_limit > 0: each run renders the sample count that fits that many seconds, measured by a
    pilot render (Cycles' own time limit would stop on time but does not report how many samples
    it finished: its metadata stamps the requested count).
    motion_as_stills > 0: each run is the mean of that many still renders (motion blur off) at
    stratified shutter times (render_shutter_stills): Cycles' own blur of a moving volume is
    biased (export/motion.py moving_volume_note). Equal-samples only.
    """
    if motion_as_stills > 0 and time_limit > 0:
        raise ValueError("Cycles motion as stills renders a fixed sample count: not in equal-time mode")
    results = []
    with matched_settings(scene, bounces, resolution):
        if time_limit > 0:
            samples = samples_for_budget(scene, time_limit, seed=base_seed + runs)
        for k in range(runs):
            if cancel is not None and cancel():
                raise InterruptedError("comparison cancelled")
            if motion_as_stills > 0:
                results.append(render_shutter_stills(scene, stills=motion_as_stills, samples=samples,
                                                     seed=base_seed + k))
            else:
                results.append(render_once(scene, samples=samples, seed=base_seed + k))
            if progress:
                progress(k + 1, runs)
    return results


#: Largest sample count of one Cycles render inside a reference. Cycles sums samples into float32
#: render buffers (kernel/film/write.h film_write_pass_spectrum: atomic float adds), so a pixel
#: that returns the same value every sample drifts as the sum outgrows its increments: measured
#: on the coloured absorber's emissive backdrop, Emission (1, 0.95, 0.9) x 2 seen directly, green
#: 1.900001 at 64 spp, 1.90027 at 16384, 1.89892 at 65536 (red, 2.0, exact). A reference is
#: the float64 mean of renders of at most this many samples (relative drift <= about
#: REFERENCE_CHUNK_SAMPLES x 2^-24 = 6e-5).
REFERENCE_CHUNK_SAMPLES = 1024


def render_reference(scene, *, samples: int, seed: int, scratch: Optional[Path] = None) -> CyclesRun:
    """A high-sample Cycles image (inside matched_settings) as the mean of independent renders of
    at most REFERENCE_CHUNK_SAMPLES each (seeds seed, seed + 1, ...), free of the float32 film
    drift one long render accumulates; render_seconds is the chunks' sum."""
    if int(samples) < 1:
        raise ValueError(f"a Cycles reference needs at least one sample per pixel, got {samples}")
    chunk = REFERENCE_CHUNK_SAMPLES
    return _mean_run([render_once(scene, samples=min(chunk, int(samples) - start), seed=seed + k, scratch=scratch)
                      for k, start in enumerate(range(0, int(samples), chunk))])


def _mean_run(runs: list) -> CyclesRun:
    """Renders of one scene as one run: the sample-weighted float64 mean of their images, their
    samples and times summed."""
    samples = sum(r.samples for r in runs)
    image = sum(r.image.astype(np.float64) * r.samples for r in runs) / samples
    return CyclesRun(image=image.astype(np.float32), samples=samples, seconds=sum(r.seconds for r in runs),
                     render_seconds=sum(r.render_seconds for r in runs))


def render_shutter_stills(scene, *, stills: int, samples: int, seed: int) -> CyclesRun:
    """One run of `samples` spp as the mean of `stills` still renders (motion blur off, the frame
    moved to each time), one time drawn uniformly in each of `stills` equal parts of the shutter
    (an unbiased estimate of the shutter's time integral; the spread between runs carries the time
    sampling's variance). Assumes the default flat shutter curve and no rolling shutter."""
    from ..export.motion import shutter_times

    if not scene.render.use_motion_blur:
        return render_once(scene, samples=samples, seed=seed)
    if samples % stills:
        raise ValueError(f"samples per run ({samples}) must be a multiple of the stills per run ({stills})")
    centre, shutter = shutter_times(scene)
    frame, subframe = scene.frame_current, float(scene.frame_subframe)
    offsets = np.random.default_rng(seed).random(stills)
    runs = []
    try:
        scene.render.use_motion_blur = False
        for k in range(stills):
            time_k = centre + shutter * ((k + offsets[k]) / stills - 0.5)
            whole = int(np.floor(time_k))
            scene.frame_set(whole, subframe=float(time_k - whole))
            runs.append(render_once(scene, samples=samples // stills, seed=seed * stills + k))
    finally:
        scene.render.use_motion_blur = True
        scene.frame_set(frame, subframe=subframe)
    return _mean_run(runs)  # stills of samples // stills each: their plain mean


def samples_for_budget(scene, seconds: float, seed: int, count_setup: bool = True) -> int:
    """Samples per pixel one Cycles render of `scene` fits into `seconds` of wall clock
    (inside matched_settings): cost per sample from a pilot render. count_setup: the budget is the
    whole render's (the pilot's fixed overhead -- sync, BVH, volume octree -- comes off it, the
    comparison tool's equal time); else it is the sampling time alone (the benchmarks' sample
    efficiency, where a setup longer than the budget would leave Cycles one sample)."""
    pilot_samples = PILOT_SAMPLES
    while True:
        pilot = render_once(scene, samples=pilot_samples, seed=seed)
        # Cycles stamps times in 1/100 s (a fast pilot reads 0.00): grow the pilot until its time
        # is well resolved. Only without a stamp does the whole call (setup included) stand in.
        render_seconds = pilot.render_seconds
        if render_seconds >= min(0.5, seconds / 4) or pilot_samples >= 4096:
            break
        pilot_samples *= 4
    if render_seconds <= 0:
        render_seconds = pilot.seconds
    per_sample = max(render_seconds / pilot_samples, 1e-6)
    overhead = max(pilot.seconds - render_seconds, 0.0) if count_setup else 0.0
    return max(1, int((seconds - overhead) / per_sample))


def _exr_metadata(path) -> dict:
    try:
        import OpenImageIO as oiio
    except ImportError:
        return {}
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        return {}
    try:
        return {attribute.name: attribute.value for attribute in inp.spec().extra_attribs}
    finally:
        inp.close()


def _metadata_number(metadata: dict, suffix: str, default: int) -> int:
    """Cycles stamps 'cycles.<view layer>.samples' into the render result."""
    for name, value in metadata.items():
        if name.startswith("cycles.") and name.endswith(suffix):
            try:
                return int(value)
            except (TypeError, ValueError):
                break
    return default


def _metadata_seconds(metadata: dict, suffix: str) -> float:
    """'MM:SS.cc' or 'HH:MM:SS.cc' -> seconds."""
    for name, value in metadata.items():
        if name.startswith("cycles.") and name.endswith(suffix):
            try:
                seconds = 0.0
                for part in str(value).split(":"):
                    seconds = seconds * 60 + float(part)
                return seconds
            except ValueError:
                break
    return 0.0
