"""The agreement suite: every example scene, rendered small by VolPath and by Cycles, must agree.

Criterion (addon/compare/metrics.py): 8 independent runs per engine; Welch t-tests per pixel, per
4x4 and 8x8 tile, and per channel on the image means, each family Sidak-corrected and the families
sharing a family-wise alpha of 1%. All tolerances come from the measured noise only. A failure is a bug in a
conversion or an estimator: the message gives the numbers to find which; never widen the test.
"""
import importlib
import pytest

from addon.compare import runner

from agreement_checks import assert_engines_agree

RESOLUTION = (32, 32)
SAMPLES = 256  # per engine, split over the runs
RUNS = 8

SCENES = [
    "cornell_fog", "cornell_defaults", "spot_godrays", "area_light", "sun_window", "sun_window_godrays",
    "absorbing_medium", "anisotropic_forward", "anisotropic_backward", "emissive_medium", "nested_media", "heavy_density",
    "near_clip_in_fog", "albedo_grid",
    "glass_of_liquid", "metals_glossy", "coat_sheen", "alpha_rough_glass",
]


@pytest.mark.agreement
@pytest.mark.parametrize("example", SCENES)
def test_volpath_agrees_with_cycles(registered_addon, example, tmp_path):
    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=SAMPLES, runs=RUNS, seed=1))
    assert_engines_agree(result, example, tmp_path)
