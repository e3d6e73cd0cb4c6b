"""Extreme input ends quickly with a defined, reported outcome; every pixel stays finite; a cancel
returns within a second with a consistent partial image and no thread left running."""
from __future__ import annotations

import os
import threading
import time
import tracemalloc

import numpy as np
import pytest

from volpath_native import Camera, Film, Material, Medium, PointLight, RenderSettings, Scene, SceneError, render
from volpath_native.grid_kernels import TRACKING_BUDGET
from volpath_native.grid_medium import GridMedium
from volpath_native.render import _Film

from native_helpers import box_mesh, camera_at

FLT_MAX = float(np.finfo(np.float32).max)
# Safety net: a render that should end on its own is cancelled after this, so a regression fails
# the test instead of hanging the suite.
HANG_SECONDS = 60.0
RANDOM_CANCELS = int(os.environ.get("VOLPATH_RANDOM_CANCELS", "20"))
SAMPLES_NEVER_REACHED = 20000


def cloud_scene(sigma, *, samples=4, size=32, threads=2, batch_size=1 << 16, density=None):
    """A floor lit from above, seen through a small grid medium (per-unit-density sigma_s = sigma_a
    = sigma/2) in its padded box."""
    if density is None:
        density = np.zeros((8, 8, 8), np.float32)
        density[2:6, 2:6, 2:6] = 1.0
    index_to_world = np.eye(4)
    index_to_world[:3, :3] *= 0.25
    index_to_world[:3, 3] = -1.0
    grid = GridMedium("cloud", density, index_to_world, np.full(3, 0.5 * sigma), np.full(3, 0.5 * sigma))
    materials = [Material("floor", base_color=0.5), Material("bounds", surface="null", base_color=0.0, medium=0)]
    scene = Scene(camera=Camera(camera_at([0, 0, 5])), film=Film(size, size),
                  meshes=[box_mesh("floor", [-3, -3, -3], [3, 3, -2.5], 0), grid.boundary_mesh(1)],
                  materials=materials, media=[grid], lights=[PointLight("p", [0, 0, 3], power=100.0)],
                  settings=RenderSettings(samples=samples, threads=threads, batch_size=batch_size))
    return scene, grid


def render_or_fail(scene, **kwargs):
    deadline = time.perf_counter() + HANG_SECONDS
    result = render(scene, cancel=lambda: time.perf_counter() > deadline, **kwargs)
    assert not result.cancelled, f"the render did not end within {HANG_SECONDS} s"
    return result


def test_flt_max_density_ends_quickly_as_opaque_and_is_reported():
    """Blender stores a Density typed as inf as FLT_MAX: the render used to run for hours. Now the
    step budget ends each ray at once as opaque, counted and named in a warning."""
    scene, _ = cloud_scene(FLT_MAX)
    result = render_or_fail(scene)
    assert result.samples == 4 and np.all(np.isfinite(result.image))
    assert result.stats["budget_exceeded"] > 0
    assert any("grid medium 'cloud'" in w and "treated as opaque" in w for w in result.warnings), result.warnings
    # The box's centre pixel looks through the cloud at the lit floor: opaque means black.
    assert np.all(result.image[16, 16, :3] == 0.0)


def test_budget_outcome_is_opaque_where_a_normal_majorant_sees_through():
    """An empty grid: with its own majorant (0) the floor shows through; with a majorant forced far
    above the budget the same rays end as opaque (the planted contrast of the fallback)."""
    empty = np.zeros((8, 8, 8), np.float32)
    scene, grid = cloud_scene(1.0, density=empty, samples=2)
    clear = render_or_fail(scene)
    assert clear.stats["budget_exceeded"] == 0 and clear.image[16, 16, :3].min() > 0.0
    grid.majorant_grid[:] = 1e3 * TRACKING_BUDGET
    blocked = render_or_fail(scene)
    assert blocked.stats["budget_exceeded"] > 0 and np.all(blocked.image[16, 16, :3] == 0.0)
    # the floor beside the box and its shadow stays lit, as bright as before where paths miss the box
    lit = blocked.image[..., 0] > 0.0
    assert lit.sum() > 50 and np.any(np.isclose(blocked.image[lit], clear.image[lit], rtol=1e-9))


def test_cancel_reaches_into_a_long_tracking_batch():
    """One batch of slow (in-budget) tracking takes about a minute; the stop flag ends it well
    within a second of the cancel."""
    empty = np.zeros((8, 8, 8), np.float32)
    scene, grid = cloud_scene(1.0, density=empty, samples=1, size=128, threads=1)
    grid.majorant_grid[:] = 0.33 * TRACKING_BUDGET  # ~0.9 budget per crossing of the 2.75 m box
    cancel_at = time.perf_counter() + 0.5
    result = render(scene, cancel=lambda: time.perf_counter() > cancel_at)
    returned = time.perf_counter()
    assert result.cancelled and result.samples == 0 and result.stats["budget_exceeded"] == 0
    assert returned - cancel_at < 1.0, returned - cancel_at


def emitter_scene(radiance):
    """A diffuse floor beside a small emissive square the camera sees directly, lit by a lamp."""
    floor = box_mesh("floor", [-3, -3, -3], [3, 3, -2.5], 0)
    lamp = box_mesh("panel", [-0.5, -0.5, 0], [0.5, 0.5, 0.1], 1)
    materials = [Material("floor", base_color=0.5), Material("hot", base_color=0.0, emission=radiance)]
    return Scene(camera=Camera(camera_at([0, 0, 5])), film=Film(16, 16), meshes=[floor, lamp], materials=materials,
                 lights=[PointLight("p", [2, 0, 3], power=100.0)], settings=RenderSettings(samples=4, threads=2))


def test_contributions_beyond_float32_are_dropped_counted_and_reported():
    """Cycles zeroes non-finite components of every contribution in its float32 film: an emitter of
    1e300 W/(m^2 sr) gives zeros there and a finite image; one of 1e30 (float32 can hold it) is kept."""
    hot = render(emitter_scene(1e300))
    assert np.all(np.isfinite(hot.image)) and np.all(np.isfinite(hot.variance))
    assert hot.stats["dropped"] > 0 and np.all(hot.image[8, 8, :3] == 0.0)
    assert any("beyond float32's range" in w for w in hot.warnings), hot.warnings
    warm = render(emitter_scene(1e30))
    assert warm.stats["dropped"] == 0 and warm.stats["dropped_samples"] == 0
    assert warm.image[8, 8, :3] == pytest.approx(1e30, rel=1e-6)
    assert np.all(np.isfinite(warm.image)) and np.all(np.isfinite(warm.variance))


def test_film_zeroes_components_beyond_float32_and_counts_samples():
    film = _Film(3)
    film.add(np.array([0, 1, 2, 2]), np.array([[1.0, 2.0, 3.0], [np.nan, 1.0, 1.0], [3e38, 3e38, 1.0], [1e39, 0, 0]]))
    assert film.dropped == 2  # the NaN and the 1e39 sample; 3e38 fits in float32
    np.testing.assert_allclose(film.mean(), [[1, 2, 3], [0, 1, 1], [1.5e38, 1.5e38, 0.5]])
    assert np.all(np.isfinite(film.variance_of_mean(film.mean()).astype(np.float32)))


def test_huge_film_is_refused_before_anything_is_allocated():
    scene, _ = cloud_scene(1.0)
    scene.film = Film(10 ** 6, 10 ** 6)
    tracemalloc.start()
    try:
        with pytest.raises(SceneError, match="film 1000000x1000000: .* GiB of film buffers"):
            render(scene)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50 << 20


@pytest.mark.parametrize("bad", [dict(batch_size=10 ** 12), dict(threads=10 ** 6), dict(samples="4"),
                                 dict(max_bounces=-1)])
def test_unusable_settings_are_errors_naming_the_field(bad):
    scene, _ = cloud_scene(1.0)
    for key, value in bad.items():
        setattr(scene.settings, key, value)
    with pytest.raises(SceneError, match=f"settings.{next(iter(bad))}"):
        render(scene)


def fog_scene(samples, threads=2, parallelism="threads"):
    """Homogeneous fog around a grid cloud: every stage runs, rounds take ~20 ms."""
    scene, grid = cloud_scene(4.0, samples=samples, size=24, threads=threads, batch_size=1024)
    fog = box_mesh("fog", [-2, -2, -2], [2, 2, 2], 2)
    scene.meshes.append(fog)
    scene.materials.append(Material("fog", surface="null", base_color=0.0, medium=1))
    scene.media.append(Medium("fog", 0.2, 0.05, g=0.3))
    scene.settings.parallelism = parallelism
    return scene


def test_random_cancels_return_within_a_second_with_a_consistent_image():
    """Cancels at random moments (before the first round, during the first samples, mid-render):
    each render returns within a second, leaves no thread behind, and its image is exactly a
    complete render of the samples it reports. The sample count is far more than a render reaches
    by the latest cancel (1.5 s; ~250 k samples/s here, 576 pixels): a render finishing first would
    test nothing."""
    rng = np.random.default_rng(19)
    baseline = threading.active_count()
    reference_checks = 0
    worst = 0.0
    for k in range(RANDOM_CANCELS):
        parallelism = "processes" if k % 5 == 4 else "threads"
        scene = fog_scene(samples=SAMPLES_NEVER_REACHED, parallelism=parallelism)
        delay = float(rng.choice([0.0, rng.uniform(0.0, 0.1), rng.uniform(0.1, 1.5)]))
        start = time.perf_counter()
        cancel_at = start + delay
        result = render(scene, cancel=lambda: time.perf_counter() >= cancel_at)
        late = time.perf_counter() - max(cancel_at, start)
        worst = max(worst, late)
        assert result.cancelled and 0 <= result.samples < SAMPLES_NEVER_REACHED
        assert late < 1.0, (k, delay, late)
        assert threading.active_count() == baseline, threading.enumerate()
        alpha = result.image[..., 3]
        assert np.all(alpha == (1.0 if result.samples else 0.0))
        assert np.all(np.isfinite(result.image))
        if result.samples and reference_checks < 3:
            reference_checks += 1
            complete = fog_scene(samples=result.samples)
            np.testing.assert_allclose(render(complete).image, result.image, rtol=1e-9, atol=1e-12)
    print(f"{RANDOM_CANCELS} random cancels: slowest return {worst:.3f} s after the cancel")
