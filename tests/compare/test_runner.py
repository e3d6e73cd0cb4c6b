"""The comparison tool itself: matched settings restored, outputs written, modes, CLI, operator."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
TINY = (16, 16)


@pytest.fixture
def fog_scene(registered_addon):
    from examples import cornell_fog

    return cornell_fog.build(resolution=TINY, samples=8)


def test_user_settings_restored_and_outputs_written(fog_scene, tmp_path):
    from addon.compare import runner

    scene = fog_scene
    scene.render.engine = "BLENDER_EEVEE"  # whatever the user had
    scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.volume_bounces = 7, True, 3
    scene.cycles.use_adaptive_sampling = True
    scene.render.filepath = "//my_frames/"
    result = runner.compare_scene(scene, runner.CompareOptions(samples=8, runs=2), tmp_path)
    assert scene.render.engine == "BLENDER_EEVEE"
    assert (scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.volume_bounces) == (7, True, 3)
    assert scene.cycles.use_adaptive_sampling and scene.render.filepath == "//my_frames/"
    assert (scene.render.resolution_x, scene.render.resolution_y) == TINY
    for key in ("volpath_exr", "cycles_exr", "sheet_png", "report_json", "report_md"):
        assert Path(result.outputs[key]).is_file(), key
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["engines"]["volpath"]["samples_per_pixel"] == 8
    assert report["engines"]["cycles"]["samples_per_pixel"] == 8
    assert report["engines"]["cycles"]["spp_per_second"] > 0
    assert report["engines"]["volpath"]["warm_up_seconds"] >= 0.0
    assert "warm-up before timing" in (tmp_path / "report.md").read_text()
    assert 0.0 <= report["agreement"]["pixel_fraction_passed"] <= 1.0
    assert "VolPath vs Cycles" in (tmp_path / "report.md").read_text()


def test_cycles_gets_volpath_bounce_limits(fog_scene):
    from addon.compare import cycles_engine

    limits = cycles_engine.BounceLimits(max_bounces=5, diffuse_bounces=2, glossy_bounces=1,
                                        transmission_bounces=3, volume_bounces=4, transparent_bounces=6)
    with cycles_engine.matched_settings(fog_scene, limits, resolution=(8, 8)):
        c = fog_scene.cycles
        assert (c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces,
                c.volume_bounces, c.transparent_max_bounces) == (5, 2, 1, 3, 4, 6)
        assert c.device == "CPU" and not c.use_denoising and not c.use_adaptive_sampling
        assert c.sample_clamp_direct == 0 and c.sample_clamp_indirect == 0 and not c.volume_biased
        assert fog_scene.render.resolution_x == 8
        assert c.use_light_tree  # VolPath's default selection, Cycles' too
    assert fog_scene.render.resolution_x == TINY[0]
    with cycles_engine.matched_settings(fog_scene, cycles_engine.BounceLimits(light_tree=False)):
        assert not fog_scene.cycles.use_light_tree


def test_equal_time_and_reference(fog_scene, tmp_path):
    from addon.compare import runner
    from volpath_native import imageio

    reference = tmp_path / "reference.exr"
    first = runner.compare_scene(fog_scene, runner.CompareOptions(samples=32, runs=2))
    imageio.write_exr(reference, first.cycles.statistics.mean.astype(np.float32))
    budget = 1.0
    result = runner.compare_scene(fog_scene, runner.CompareOptions(mode="equal-time", seconds=budget, runs=2,
                                                                   reference=str(reference)), tmp_path / "out")
    for engine in (result.volpath, result.cycles):
        assert engine.samples_per_pixel >= 2
        # Each engine spent about the budget (start-up overhead is allowed, not ten times more).
        assert 0.5 * budget <= engine.seconds <= budget + 5.0, engine.summary()
    ref = result.reference_errors
    assert ref["relmse_volpath"] > 0 and ref["relmse_cycles"] > 0
    assert ref["error_ratio"] == pytest.approx(ref["relmse_volpath"] / ref["relmse_cycles"])
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["reference"]["path"] == str(reference) and report["mode"] == "equal-time"
    assert (tmp_path / "out" / "sheet.png").is_file()


def test_bad_options_are_rejected():
    from addon.compare import runner

    for options in (runner.CompareOptions(runs=1), runner.CompareOptions(mode="fastest"),
                    runner.CompareOptions(samples=4, runs=8), runner.CompareOptions(mode="equal-time", seconds=0),
                    runner.CompareOptions(mode="equal-time", cycles_motion_as_stills=4),
                    runner.CompareOptions(samples=48, runs=8, cycles_motion_as_stills=4)):  # 6 spp: not 4 stills
        with pytest.raises(ValueError):
            options.validate()
    runner.CompareOptions(samples=64, runs=8, cycles_motion_as_stills=4).validate()  # 8 spp as 4 stills of 2


def test_reference_of_wrong_size_is_a_clear_error(fog_scene, tmp_path):
    from addon.compare import runner
    from volpath_native import imageio

    reference = imageio.write_exr(tmp_path / "ref.exr", np.ones((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="reference"):
        runner.compare_scene(fog_scene, runner.CompareOptions(samples=2, runs=2, reference=str(reference)))


def test_operator_runs_headless(fog_scene, tmp_path):
    import bpy

    assert hasattr(bpy.ops.volpath, "compare_with_cycles")
    result = bpy.ops.volpath.compare_with_cycles("EXEC_DEFAULT", samples=4, runs=2, output=str(tmp_path) + "/")
    assert result == {"FINISHED"}
    assert (tmp_path / "sheet.png").is_file() and (tmp_path / "report.json").is_file()
    assert any(Path(image.filepath).name == "sheet.png" for image in bpy.data.images)


def test_cli_run(tmp_path, registered_addon):
    from examples import cornell_fog, scene_builder

    cornell_fog.build(resolution=TINY, samples=4)
    blend = scene_builder.save(tmp_path / "fog.blend")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "addon.compare", "run", str(blend), "--out", str(out),
                           "--spp", "4", "--runs", "2", "--resolution", "12x10"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "sheet_png" in proc.stdout and (out / "sheet.png").is_file()
    report = json.loads((out / "report.json").read_text())
    assert report["resolution"] == [12, 10] and report["scene"] == "fog"
    missing = subprocess.run([sys.executable, "-m", "addon.compare", "run", str(tmp_path / "nope.blend"),
                              "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert missing.returncode == 1 and "no such .blend" in missing.stderr


def test_cli_demo_tiny(tmp_path):
    """`make demo`'s command, shrunk: builds the glass-of-liquid scene, renders both, writes everything."""
    proc = subprocess.run([sys.executable, "-m", "addon.compare", "demo", "--out", str(tmp_path),
                           "--resolution", "16x16", "--spp", "8", "--runs", "2"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    for name in ("glass_of_liquid.blend", "volpath.exr", "cycles.exr", "sheet.png", "report.json", "report.md"):
        assert (tmp_path / name).is_file(), name
    assert "100.0%" in proc.stderr  # the progress bar reached the end
    assert "Fra:" not in proc.stdout  # Cycles' per-sample chatter is kept off the terminal


def test_batch_script_with_albedo_grid(tmp_path):
    proc = subprocess.run([sys.executable, "examples/render_all.py", str(tmp_path), "--resolution", "8x8",
                           "--spp", "4", "--runs", "2", "--only", "cornell_fog", "albedo_grid"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode in (0, 1), proc.stderr[-2000:]  # 1 = some scene disagrees (4 spp: noise only)
    assert (tmp_path / "summary.md").is_file()
    assert (tmp_path / "albedo_grid" / "albedo_grid.png").is_file()
    cells = json.loads((tmp_path / "albedo_grid" / "albedo_grid.json").read_text())
    assert len(cells) == 9
    assert (tmp_path / "blend" / "cornell_fog.blend").is_file()


def test_render_border_compares_the_region(fog_scene):
    """With a border, VolPath renders only the region; Cycles' output is cropped to match."""
    from addon.compare import runner

    render = fog_scene.render
    render.use_border, render.use_crop_to_border = True, False
    render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y = 0.25, 0.75, 0.5, 1.0
    result = runner.compare_scene(fog_scene, runner.CompareOptions(samples=4, runs=2))
    assert result.volpath.statistics.mean.shape == result.cycles.statistics.mean.shape == (8, 8, 3)
    assert render.use_crop_to_border is False  # the user's setting is back


def test_timed_runs_start_after_the_kernels_are_ready(fog_scene, monkeypatch):
    """A first render after an install compiles the kernels (~100 s): the comparison makes them
    ready first, reports that warm-up apart, and times only the renders. Simulated: until
    warm_up() has run, a render stalls 2 s as if compiling."""
    import volpath_native
    from addon.compare import runner
    native_render = sys.modules["volpath_native.render"]

    ready = []
    real_render, real_warm_up = native_render.render, volpath_native.warm_up

    def warm_up():
        ready.append(True)
        return real_warm_up() + 2.0

    def render(scene, **kwargs):
        if not ready:
            import time
            time.sleep(2.0)
        return real_render(scene, **kwargs)

    monkeypatch.setattr(volpath_native, "warm_up", warm_up)
    monkeypatch.setattr(native_render, "render", render)
    result = runner.compare_scene(fog_scene, runner.CompareOptions(samples=4, runs=2))
    assert ready and result.volpath.warm_up_seconds >= 2.0
    assert result.volpath.seconds < 2.0, result.volpath.summary()


def test_a_reference_is_the_sample_weighted_mean_of_short_renders(fog_scene, tmp_path, monkeypatch):
    # Cycles sums samples into float32 buffers, so one long render drifts (REFERENCE_CHUNK_SAMPLES);
    # a reference is the float64 mean of renders of at most that many samples, seeds seed, seed + 1, ...
    from addon.compare import cycles_engine

    monkeypatch.setattr(cycles_engine, "REFERENCE_CHUNK_SAMPLES", 4)
    bounces = cycles_engine.BounceLimits()
    with cycles_engine.matched_settings(fog_scene, bounces, TINY):
        reference = cycles_engine.render_reference(fog_scene, samples=10, seed=50, scratch=tmp_path)
        parts = [cycles_engine.render_once(fog_scene, samples=n, seed=50 + k, scratch=tmp_path)
                 for k, n in enumerate((4, 4, 2))]
        single = cycles_engine.render_reference(fog_scene, samples=3, seed=50, scratch=tmp_path)
        once = cycles_engine.render_once(fog_scene, samples=3, seed=50, scratch=tmp_path)
    expected = sum(p.image.astype(np.float64) * p.samples for p in parts) / 10
    assert reference.samples == 10
    np.testing.assert_allclose(reference.image, expected, rtol=1e-6, atol=1e-7)
    # not a single 10-spp render nor an unweighted mean of the parts (the 2-spp part weighs less)
    assert not np.allclose(reference.image, np.mean([p.image for p in parts], axis=0), rtol=1e-4, atol=1e-6)
    np.testing.assert_array_equal(single.image, once.image)  # one chunk: one render
