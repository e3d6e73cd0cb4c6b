"""The agreement assertions every VolPath-vs-Cycles case of the suite shares."""
import json


def unexpected_warnings(warnings):
    """The exporter's warnings less its notes on where Cycles is knowingly biased (the scene is
    still compared: VolPath's side of it is what the test checks)."""
    from addon.export.motion import CYCLES_MOVING_VOLUME_NOTE

    return [w for w in warnings if CYCLES_MOVING_VOLUME_NOTE not in w]


def assert_engines_agree(result, label, tmp_path):
    """Assert the comparison's verdict part by part (means, pixels, tiles) with the numbers needed to
    find the culprit; on failure the EXRs and sheet are written to tmp_path for inspection."""
    from addon.compare import runner

    summary = result.comparison.summary()
    details = json.dumps({k: summary[k] for k in (
        "channel_means_a", "channel_means_b", "channel_mean_ratio", "channel_mean_ratio_tolerance",
        "channel_mean_p_values", "pixel_fraction_passed", "worst_pixel")}, indent=1)
    if not result.agrees:
        runner.write_outputs(result, tmp_path)
        details += f"\noutputs in {tmp_path}"
    assert not unexpected_warnings(result.warnings), result.warnings
    assert result.comparison.means.passed, f"{label}: image means differ (VolPath / Cycles)\n{details}"
    assert result.comparison.pixel.passed, f"{label}: pixels differ (VolPath / Cycles)\n{details}"
    for size, test in result.comparison.blocks.items():
        assert test.passed, f"{label}: {size}x{size} blocks differ (VolPath / Cycles): worst {test.worst()}\n{details}"
    # Guard against a vacuous pass: the scene must actually be lit.
    assert min(summary["channel_means_b"]) > 1e-3


def assert_planted_error_fails(scene, native_scene, correct, planted, runs: int, samples_per_run: int):
    """The correct VolPath runs agree with Cycles and the planted ones do not (the criterion can see
    the error at this sample count); returns the failing comparison."""
    from addon.compare import cycles_engine, metrics

    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=runs, samples=samples_per_run, base_seed=101, bounces=bounces,
                                       resolution=tuple(native_scene_resolution(native_scene)))
    cycles_statistics = metrics.run_statistics([r.image for r in cycles])
    baseline = metrics.compare_runs(metrics.run_statistics([r.image for r in correct]), cycles_statistics)
    assert baseline.passed, baseline.summary()
    comparison = metrics.compare_runs(metrics.run_statistics([r.image for r in planted]), cycles_statistics)
    assert not comparison.passed, comparison.summary()
    return comparison


def native_scene_resolution(native_scene):
    return native_scene.film.width, native_scene.film.height
