"""Equal render-time comparison of VolPath and Cycles on one Blender scene, shared by the benchmarks.

Reference: a high-sample Cycles image (seed 1000; the mean of renders of at most
cycles_engine.REFERENCE_CHUNK_SAMPLES each, against Cycles' float32 film drift), which also gives Cycles' cost per sample,
kept on disk (REFERENCE_CACHE, keyed by the scene as VolPath exports it, the resolution, the sample
count and Blender's version; a pilot render then measures the cost per sample); then each engine renders for the same render-time budget (Cycles' scene sync excluded, as its own
time limit does). relMSE against a noisy reference holds the reference's own error: for Cycles
(independent, same estimator) E[raw] = e_c (1 + n_c / n_ref); that share is removed from both.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REFERENCE_CACHE = Path(os.environ.get("VOLPATH_REFERENCE_CACHE", Path.home() / ".cache" / "volpath" / "references"))


@dataclass
class EqualTimeRow:
    name: str
    volpath_spp: int
    volpath_seconds: float
    cycles_spp: int
    cycles_seconds: float
    relmse_volpath: float
    relmse_cycles: float
    reference_spp: int
    mean_ratio: np.ndarray  # VolPath / reference, per channel
    lookups_per_sample: np.ndarray = None  # VolPath's medium lookups per camera sample: free flight, shadow, attenuation
    reference_mean: np.ndarray = None  # the Cycles reference's image mean, per channel

    @property
    def error_ratio(self) -> float:
        return self.relmse_volpath / self.relmse_cycles

    @property
    def sample_error_ratio(self) -> float:
        """relMSE x spp, VolPath / Cycles: independent of the machine's load."""
        return (self.relmse_volpath * self.volpath_spp) / (self.relmse_cycles * self.cycles_spp)

    @property
    def time_ratio(self) -> float:
        """Time VolPath needs for Cycles' error (relMSE x time is constant for unbiased MC)."""
        return (self.relmse_volpath * self.volpath_seconds) / (self.relmse_cycles * self.cycles_seconds)

    def lines(self, pixels: int) -> list:
        return [
            f"{self.name}: VolPath {self.volpath_spp} spp in {self.volpath_seconds:.1f} s "
            f"({self.volpath_spp * pixels / self.volpath_seconds / 1e3:.1f} k samples/s), Cycles {self.cycles_spp} spp "
            f"in {self.cycles_seconds:.1f} s ({self.cycles_spp * pixels / self.cycles_seconds / 1e3:.1f} k samples/s)",
            f"  relMSE vs a {self.reference_spp}-spp Cycles reference: VolPath {self.relmse_volpath:.4g}, Cycles "
            f"{self.relmse_cycles:.4g}; ratio {self.error_ratio:.3g}; VolPath needs {self.time_ratio:.3g}x Cycles' "
            "time for the same error",
            f"  error per sample (relMSE x spp) VolPath / Cycles: {self.sample_error_ratio:.3g}",
            "  image mean ratio VolPath/reference R/G/B: " + " ".join(f"{r:.4f}" for r in self.mean_ratio),
        ] + ([] if self.lookups_per_sample is None else [
            "  VolPath heterogeneous-medium lookups per sample: free flight {:.3g}, shadow / next-event "
            "transmittance {:.3g}, attenuation {:.3g}".format(*self.lookups_per_sample)])


def equal_time_row(name: str, scene, native_scene, seconds: float, reference_spp: int, scratch,
                   resolution=None, seed: int = 1, reference_factor: float = 0.0,
                   cycles_samples: int = 0) -> EqualTimeRow:
    """resolution: Cycles' render size override (native_scene must have been exported at it).
    seed: both engines' seed for this run (the reference keeps its own). reference_factor,
    cycles_samples: see equal_time_rows."""
    return equal_time_rows(name, scene, {"": native_scene}, seconds, reference_spp, scratch, resolution, seed,
                           reference_factor, cycles_samples)[""]


def equal_time_rows(name: str, scene, native_scenes: dict, seconds: float, reference_spp: int, scratch,
                    resolution=None, seed: int = 1, reference_factor: float = 0.0,
                    cycles_samples: int = 0) -> dict:
    """One row per VolPath variant (label -> native scene, e.g. settings changed), all against
    the same reference and the same Cycles run. reference_factor > 0: the reference has at least
    that many times the samples Cycles renders in the budget (the next power of two): the share of
    the reference's own error removed from both relMSEs is n_c / (n_c + n_ref) of Cycles' raw one,
    and where the runs out-sample the reference (a fast row: 13000 spp against 4096) that
    subtraction, not the engines, decides the ratio. cycles_samples > 0: Cycles' samples in the
    budget as an earlier run of the same row measured them (its cycles_spp), instead of a pilot
    render: the seeds of one row share one budget."""
    from addon.compare import cycles_engine, metrics, volpath_engine

    first = next(iter(native_scenes.values()))
    bounces = cycles_engine.BounceLimits.from_settings(first.settings)
    with cycles_engine.matched_settings(scene, bounces, resolution):
        reference = _cycles_reference(scene, first, reference_spp, scratch)
        if cycles_samples <= 0 and reference.render_seconds > 0.0:  # just rendered: its cost per sample
            cycles_samples = max(1, int(seconds / (reference.render_seconds / reference_spp)))
        elif cycles_samples <= 0:
            cycles_samples = cycles_engine.samples_for_budget(scene, seconds, seed=2, count_setup=False)
        wanted = int(2 ** np.ceil(np.log2(max(reference_factor * cycles_samples, 1.0))))
        if reference_factor > 0 and wanted > reference_spp:
            reference_spp = wanted
            reference = _cycles_reference(scene, first, reference_spp, scratch)
        cycles_run = cycles_engine.render_once(scene, samples=cycles_samples, seed=seed, scratch=scratch)
    raw_c = metrics.relmse(cycles_run.image, reference.image)
    reference_share = raw_c * cycles_run.samples / (cycles_run.samples + reference_spp)
    means_r = metrics.rgb(reference.image).mean(axis=(0, 1))
    rows = {}
    for label, native_scene in native_scenes.items():
        grids = [m for m in native_scene.media if hasattr(m, "lookups")]
        for medium in grids:
            medium.lookups[:] = 0
        volpath_run = volpath_engine.render_runs(native_scene, runs=1, samples=1, base_seed=seed,
                                                 time_limit=seconds)[0]
        samples = volpath_run.samples * volpath_run.image.shape[0] * volpath_run.image.shape[1]
        lookups = sum(m.lookups for m in grids) / samples if grids else None
        raw_v = metrics.relmse(volpath_run.image, reference.image)
        means_v = metrics.rgb(volpath_run.image).mean(axis=(0, 1))
        rows[label] = EqualTimeRow(f"{name} {label}".strip(), volpath_run.samples, volpath_run.render_seconds,
                                   cycles_run.samples, max(cycles_run.render_seconds, 1e-9), raw_v - reference_share,
                                   raw_c - reference_share, reference_spp, means_v / np.maximum(means_r, 1e-30),
                                   lookups, means_r)
    return rows


def _cycles_reference(scene, native_scene, reference_spp: int, scratch):
    """The Cycles reference at reference_spp: from the cache (render_seconds 0), else rendered and
    cached."""
    from addon.compare import cycles_engine

    cached = _reference_path(native_scene, reference_spp, scratch)
    if cached.exists():
        from volpath_native import imageio
        return cycles_engine.CyclesRun(image=imageio.read_exr(cached), samples=reference_spp, seconds=0.0,
                                       render_seconds=0.0)
    reference = cycles_engine.render_reference(scene, samples=reference_spp, seed=1000, scratch=scratch)
    _store_reference(reference.image, cached)
    return reference


def _reference_path(native_scene, reference_spp: int, scratch) -> Path:
    """Where the reference of this scene (as VolPath exports it: geometry, materials, media, lights,
    camera, film, bounce limits), sample count and Blender version is kept."""
    import bpy
    from addon.compare.cycles_engine import REFERENCE_CHUNK_SAMPLES
    from volpath_native.scene_io import save_scene

    saved = save_scene(native_scene, Path(scratch) / "reference_key.vpscene")
    # the chunk size too: references from one long render (float32 film drift) are not reused
    digest = hashlib.sha256(json.dumps([reference_spp, bpy.app.version_string,
                                        f"chunks of {REFERENCE_CHUNK_SAMPLES}"]).encode())
    with np.load(saved) as arrays:  # the arrays, not the zip file (its entries carry the time of writing)
        for name in sorted(arrays.files):
            digest.update(name.encode())
            digest.update(np.ascontiguousarray(arrays[name]).tobytes())
    return REFERENCE_CACHE / f"{digest.hexdigest()[:24]}.exr"


def _store_reference(image, path: Path) -> None:
    from volpath_native import imageio

    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(".partial.exr")
    imageio.write_exr(partial, image)
    partial.replace(path)
