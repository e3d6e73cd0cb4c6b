"""The agreement suite: every example scene, rendered small by VolPath and by Cycles, must agree.

Criterion (addon/compare/metrics.py): 8 independent runs per engine; per-pixel Welch t-tests,
Sidak-corrected to a family-wise alpha of 1%, and a per-channel t-test on the image means (also
Sidak-corrected). Both tolerances come from the measured noise only. A failure is a bug in a
conversion or an estimator: the message gives the numbers to find which; never widen the test.
"""
import importlib
import json

import pytest

from addon.compare import runner

RESOLUTION = (32, 32)
SAMPLES = 256  # per engine, split over the runs
RUNS = 8

# Known, reported bugs (strict: the test fails again as soon as the bug is fixed, so the mark goes).
KNOWN_BUGS = {
    "area_light": "Blender 5.0 creates light objects with visible_camera=False, so Cycles does not show "
                  "the area light to camera rays; VolPath's exporter ignores Object.visible_camera and "
                  "the renderer always shows area lights (image mean 1.30 vs 0.99 at 32x32, 256 spp)",
    "cornell_defaults": "same visible_camera bug for a point light of radius 0.1 m: VolPath shows the "
                        "light's disc, Cycles (visible_camera False) does not: image mean ratio 1.98 / 1.97 "
                        "/ 2.16 (noise allows +-0.17); with visible_camera True both agree (0.935 +- 0.09)",
}

SCENES = [
    "cornell_fog",
    pytest.param("cornell_defaults", marks=pytest.mark.xfail(strict=True, reason=KNOWN_BUGS["cornell_defaults"])),
    "spot_godrays",
    pytest.param("area_light", marks=pytest.mark.xfail(strict=True, reason=KNOWN_BUGS["area_light"])), "sun_window", "sun_window_godrays", "absorbing_medium",
    "anisotropic_forward", "anisotropic_backward", "emissive_medium", "nested_media", "heavy_density",
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
