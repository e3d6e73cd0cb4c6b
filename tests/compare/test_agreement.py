"""The agreement suite: every example scene, rendered small by VolPath and by Cycles, must agree.

Criterion (addon/compare/metrics.py): 8 independent runs per engine; Welch t-tests per pixel, per
4x4 and 8x8 tile, and per channel on the image means, each family Sidak-corrected and the families
sharing a family-wise alpha of 1%. All tolerances come from the measured noise only. A failure is a bug in a
conversion or an estimator: the message gives the numbers to find which; never widen the test.
"""
import importlib
import json

import pytest

from addon.compare import runner

RESOLUTION = (32, 32)
SAMPLES = 256  # per engine, split over the runs
RUNS = 8

SCENES = [
    "cornell_fog", "cornell_defaults", "spot_godrays", "area_light", "sun_window", "sun_window_godrays",
    "absorbing_medium", "anisotropic_forward", "anisotropic_backward", "emissive_medium", "nested_media", "heavy_density",
    "albedo_grid",
]


@pytest.mark.agreement
@pytest.mark.parametrize("example", SCENES)
def test_volpath_agrees_with_cycles(registered_addon, example, tmp_path):
    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=SAMPLES, runs=RUNS, seed=1))
    summary = result.comparison.summary()
    details = json.dumps({k: summary[k] for k in (
        "channel_means_a", "channel_means_b", "channel_mean_ratio", "channel_mean_ratio_tolerance",
        "channel_mean_p_values", "pixel_fraction_passed", "worst_pixel")}, indent=1)
    if not result.agrees:
        runner.write_outputs(result, tmp_path)  # EXRs + sheet to inspect the failure
        details += f"\noutputs in {tmp_path}"
    assert not result.warnings, result.warnings
    assert result.comparison.means.passed, f"{example}: image means differ (VolPath / Cycles)\n{details}"
    assert result.comparison.pixel.passed, f"{example}: pixels differ (VolPath / Cycles)\n{details}"
    for size, test in result.comparison.blocks.items():
        assert test.passed, f"{example}: {size}x{size} blocks differ (VolPath / Cycles): worst {test.worst()}\n{details}"
    # Guard against a vacuous pass: the scene must actually be lit.
    assert min(summary["channel_means_b"]) > 1e-3
