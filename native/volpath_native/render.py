"""Progressive rendering: rounds of samples over the crop region, batches of paths traced by a
thread pool (Embree and large numpy operations release the GIL), callbacks for progress,
partial images and cancellation."""
from __future__ import annotations

import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from .camera import crop_window
from .integrator import Cancelled, Integrator
from .jit import kernel
from .round_schedule import fixed_round_samples, round_chunks, timed_round_samples
from .scene import Scene, SceneError
from .scene_schema import check_settings
from .shading.images import table_nbytes


@dataclass
class RenderResult:
    image: np.ndarray          # (H, W, 4) float32 scene-linear RGBA, row 0 = top, crop region
    # (H, W, 3) float32 estimated variance of each pixel's mean: the samples' variance over their
    # count, the variance of independent samples. A pixel's samples are stratified
    # (sample_pattern), so the error of its mean is usually smaller; compare independent renders
    # (other seeds) for the error itself.
    variance: np.ndarray
    samples: int               # samples per pixel actually rendered
    seconds: float
    stats: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    cancelled: bool = False
    crop_offset: tuple = (0, 0)  # (x, y) of the crop region from the top-left of the full frame


FLOAT32_MAX = float(np.finfo(np.float32).max)


class _Film:
    """Per-pixel running sums of the samples and their squares (float64)."""

    def __init__(self, n_pixels: int):
        self.n_pixels = n_pixels
        self.sum = self.sum_sq = self.count = None  # allocated on the first sample
        self.dropped = 0  # samples with a component zeroed (see add)
        self.lock = threading.Lock()

    @property
    def empty(self) -> bool:
        return self.count is None

    def add(self, pixel, values):
        """Accumulate one sample per row. A component that is not finite or beyond float32's range
        (a sum of contributions each within it can be) is zeroed and the sample counted in
        `dropped`, so every pixel of the float32 image is finite."""
        with self.lock:
            if self.count is None:
                self.sum = np.zeros((self.n_pixels, 3))
                self.sum_sq = np.zeros((self.n_pixels, 3))
                self.count = np.zeros(self.n_pixels)
            self.dropped += int(_accumulate(self.sum, self.sum_sq, self.count, pixel, values))

    def commit(self, pending: "_Film"):
        """Add a round's film (a complete round: see render) to this one and empty it."""
        if pending.empty:
            return
        with self.lock:
            if self.count is None:
                self.sum, self.sum_sq, self.count = (np.zeros_like(a) for a in (pending.sum, pending.sum_sq,
                                                                                 pending.count))
            self.sum += pending.sum
            self.sum_sq += pending.sum_sq
            self.count += pending.count
            self.dropped += pending.dropped
        for a in (pending.sum, pending.sum_sq, pending.count):
            a[:] = 0.0
        pending.dropped = 0

    def mean(self):
        return self.sum / np.maximum(self.count, 1)[:, None]

    def variance_of_mean(self, mean):
        """Unbiased sample variance of each pixel's samples divided by their count (what the
        mean's variance would be were the samples independent: see RenderResult.variance)."""
        n = np.maximum(self.count, 1)[:, None]
        var = self.sum_sq / n
        var -= mean * mean
        var *= 1.0 / np.maximum(n - 1, 1)
        return np.clip(var, 0.0, FLOAT32_MAX, out=var)  # stays finite in float32


@kernel
def _accumulate(total, total_sq, count, pixel, values):
    """count / total / total_sq += each pixel's sample count, sum and sum of squares over the
    chunk, summed over the chunk's own pixel range first (the cost follows the batch, not the
    resolution), in one pass that also zeroes components not within float32's range; returns how
    many samples had one (the numpy checks, copies and np.bincount passes this replaced were ~1 ms
    per 64k-path chunk: 5 % of a cheap-sample render)."""
    if pixel.shape[0] == 0:
        return 0
    lo, hi = pixel[0], pixel[0]
    for i in range(pixel.shape[0]):
        lo, hi = min(lo, pixel[i]), max(hi, pixel[i])
    chunk = np.zeros((hi + 1 - lo, 7))
    dropped = 0
    for i in range(pixel.shape[0]):
        j = pixel[i] - lo
        chunk[j, 0] += 1.0
        bad = False
        for c in range(3):
            v = values[i, c]
            if not abs(v) <= FLOAT32_MAX:
                v, bad = 0.0, True
            chunk[j, 1 + c] += v
            chunk[j, 4 + c] += v * v
        dropped += bad
    for j in range(hi + 1 - lo):
        count[lo + j] += chunk[j, 0]
        for c in range(3):
            total[lo + j, c] += chunk[j, 1 + c]
            total_sq[lo + j, c] += chunk[j, 4 + c]
    return dropped


_COUNTERS = ("rays", "shadow_rays", "vertices", "paths", "dropped")


_WORKER = None  # (Integrator, stop event) of the render being served by forked workers


def _chunk_paths(chunk):
    """(pixel, sample) arrays of one chunk (first, end, first sample, pixels): the paths of a round
    are numbered sample-major and made per chunk, so memory follows the batch, not the image."""
    first, end, sample0, n_pix = chunk
    k = np.arange(first, end, dtype=np.int64)
    return k % n_pix, sample0 + k // n_pix


def _chunk_pixels(chunk):
    """The pixel array of _chunk_paths(chunk) alone."""
    first, end, _, n_pix = chunk
    return np.arange(first, end, dtype=np.int64) % n_pix


def _run_in_worker(chunk):
    integrator, stop = _WORKER
    if stop.is_set():
        raise Cancelled()
    return (*integrator.render_paths(*_chunk_paths(chunk), stop.is_set), chunk)


def _fork_available() -> bool:
    """Processes are forked, never spawned: a spawned child would re-run Blender."""
    return "fork" in multiprocessing.get_all_start_methods()


def _thread_count(requested: int) -> int:
    return max(1, requested if requested > 0 else (os.cpu_count() or 1))


def render(scene: Scene, *, progress=None, cancel=None, partial=None) -> RenderResult:
    """Render scene.settings.samples samples per pixel progressively (see module docstring).

    cancel() is polled several times a second: once true, the render returns within about a second
    with the rounds completed so far (every pixel holds the same number of samples)."""
    warnings = list(scene.validate())
    st = scene.settings
    check_settings(st)
    check_film_memory(scene.film)
    start = time.perf_counter()
    integrator = Integrator(scene)
    warnings += integrator.warnings
    x0, y0, cw, ch = integrator.crop
    n_pix = cw * ch
    film = _Film(n_pix)
    # The round in progress: render threads add their batches to it as they finish (results held
    # until the round's end were a mapping per batch and a serial add after it); committed to
    # `film` when the round completes. Forked workers return their results instead.
    round_film = _Film(n_pix)
    threads = _thread_count(st.threads)
    batch = max(256, int(st.batch_size))
    batch_limit = physical_memory() // (4 * threads * PATH_BYTES) or batch
    if batch > batch_limit:
        warnings.append(f"batch size {batch} would need {batch * threads * PATH_BYTES / 2 ** 30:.3g} GiB of path "
                        f"state; reduced to {batch_limit} (a quarter of this machine's memory)")
        batch = max(256, batch_limit)
    per_round = fixed_round_samples(st.samples, threads, batch, n_pix)
    time_limit = float(st.time_limit)
    seconds_per_pass = 0.0
    stats = {k: 0 for k in _COUNTERS}
    # image textures, one copy each (shading/images.py)
    stats["texture_images"] = len(scene.images)
    stats["texture_bytes"] = table_nbytes(integrator.images)
    budget = np.zeros(len(integrator.grids), dtype=np.int64)  # tracking calls ended, per grid medium
    done = 0
    cancelled = False

    # cancel() is only ever called from this (the caller's) thread -- Blender's test_break must
    # not be called from worker threads; workers watch an Event instead.
    use_processes = st.parallelism == "processes" and threads > 1 and _fork_available()
    if use_processes:
        mp = multiprocessing.get_context("fork")
        stop = mp.Event()
        global _WORKER
        _WORKER = (integrator, stop)  # inherited by the forked workers
        executor = ProcessPoolExecutor(max_workers=threads, mp_context=mp)
        run = _run_in_worker
    else:
        stop = threading.Event()
        executor = ThreadPoolExecutor(max_workers=threads)

        def run(chunk):
            if stop.is_set():
                raise Cancelled()
            pixel, sample = _chunk_paths(chunk)
            values, stats = integrator.render_paths(pixel, sample, stop.is_set, reuse_radiance=True)
            round_film.add(pixel, values)
            return None, stats, chunk

    def stop_workers():
        stop.set()
        integrator.request_stop()  # reaches into long grid tracking, in threads and forked workers

    def wait_polling_cancel(futures):
        pending = set(futures)
        while pending:
            _, pending = wait(pending, timeout=0.05)
            if cancel is not None and not stop.is_set() and cancel():
                stop_workers()

    trace_start = time.perf_counter()  # the time limit leaves out the set-up above, as Cycles' does
    with executor as pool:
        while done < st.samples and not cancelled:
            round_start = time.perf_counter()
            if time_limit > 0.0:
                n_smp = timed_round_samples(done, st.samples, round_start - trace_start, time_limit, seconds_per_pass,
                                            threads, batch, n_pix)
                if n_smp == 0:
                    break
            else:
                n_smp = min(per_round, st.samples - done)
            n_paths = n_pix * n_smp
            # batches, then smaller chunks at the round's end (round_chunks: the threads finish it
            # together); a small round still gives every thread work
            chunks = [(first, end, done, n_pix) for first, end in round_chunks(n_paths, batch, threads)]
            # A round is committed to the film only when complete, so after a cancel every pixel
            # still holds the same number of samples.
            futures = [pool.submit(run, c) for c in chunks]
            wait_polling_cancel(futures)
            try:
                results = [f.result() for f in futures]
            except Cancelled:
                cancelled = True
                for f in futures:
                    f.cancel()
                break
            for values, s, chunk in results:
                if values is not None:  # from a forked worker
                    round_film.add(_chunk_pixels(chunk), values)
                for k in _COUNTERS:
                    stats[k] += s[k]
                budget += s["budget"]
            film.commit(round_film)
            done += n_smp
            seconds_per_pass = (time.perf_counter() - round_start) / n_smp
            elapsed = time.perf_counter() - start
            stats.update(seconds=elapsed, samples_per_second=done * n_pix / max(elapsed, 1e-9),
                         rays_per_second=(stats["rays"] + stats["shadow_rays"]) / max(elapsed, 1e-9),
                         vertices_per_second=stats["vertices"] / max(elapsed, 1e-9))
            if partial is not None:
                partial(_image(film, ch, cw))
            if progress is not None:
                progress(done, st.samples, dict(stats))
            if cancel is not None and cancel():
                cancelled = True
    elapsed = time.perf_counter() - start
    stats["seconds"] = elapsed
    stats["dropped_samples"] = film.dropped
    stats["budget_exceeded"] = int(budget.sum())
    warnings += _guard_warnings(integrator, stats, budget)
    if film.empty:  # cancelled before the first round completed
        return RenderResult(image=np.zeros((ch, cw, 4), np.float32), variance=np.zeros((ch, cw, 3), np.float32),
                            samples=0, seconds=elapsed, stats=stats, warnings=warnings, cancelled=cancelled,
                            crop_offset=(x0, y0))
    mean = film.mean()
    if not np.all(np.isfinite(mean)):  # the guards above make this unreachable
        bad = int(np.count_nonzero(~np.isfinite(mean).all(axis=1)))
        warnings.append(f"{bad} pixels had non-finite values and were set to 0 (please report)")
        mean = np.nan_to_num(mean, nan=0.0, posinf=0.0, neginf=0.0)
    image = _image(film, ch, cw, mean)
    variance = film.variance_of_mean(mean).reshape(ch, cw, 3).astype(np.float32)
    return RenderResult(image=image, variance=variance, samples=done, seconds=elapsed, stats=stats,
                        warnings=warnings, cancelled=cancelled, crop_offset=(x0, y0))


# Upper bound of what a path in flight holds (integrator._Buffers: state, rays, two shadow-queue
# entries, Embree hits, radiance).
PATH_BYTES = 1024
# What the film holds per rendered pixel at the end of a render: float64 sums, squares and count
# (twice: the film and the round in progress), the float64 mean, the float32 RGBA image and RGB
# variance.
FILM_BYTES_PER_PIXEL = (2 * (3 + 3 + 1) + 3) * 8 + (4 + 3) * 4


def physical_memory() -> int:
    """Bytes of RAM of this machine (0 if unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def film_memory_problem(film):
    """Why a film's buffers would not fit in this machine's memory, or None; computed from the
    resolution before anything is allocated."""
    _, _, width, height = crop_window(film)
    needed = width * height * FILM_BYTES_PER_PIXEL
    memory = physical_memory()
    if memory and needed > memory // 2:
        return (f"{width}x{height} pixels need {needed / 2 ** 30:.3g} GiB of film buffers, more than half of "
                f"this machine's {memory / 2 ** 30:.3g} GiB of memory; lower the resolution")
    return None


def check_film_memory(film) -> None:
    """SceneError naming the resolution if film_memory_problem finds one."""
    problem = film_memory_problem(film)
    if problem:
        raise SceneError(f"film {film.width}x{film.height}: {problem}")


def _guard_warnings(integrator, stats, budget) -> list:
    """What the numeric guards did, for the user: dropped contributions and samples, grid media
    whose tracking the step budget ended."""
    messages = []
    if stats["dropped"] or stats["dropped_samples"]:
        messages.append(f"{stats['dropped']} light contributions and {stats['dropped_samples']} samples had "
                        "components that were not finite or beyond float32's range; those components were "
                        "dropped (as Cycles does). Check for extreme emission strengths, light powers or densities")
    for grid, count in zip(integrator.grids, budget):
        if count:
            messages.append(grid.budget_message(int(count)))
    return messages


def _image(film: _Film, h: int, w: int, mean=None) -> np.ndarray:
    image = np.empty((h, w, 4), dtype=np.float32)
    image[..., :3] = (film.mean() if mean is None else mean).reshape(h, w, 3)
    image[..., 3] = (film.count > 0).reshape(h, w)
    return image
