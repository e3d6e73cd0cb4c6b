"""Textured surfaces against Cycles (the agreement criterion of test_agreement.py): an sRGB image on a
wall, a Non-Color roughness map, a Noise Texture through Mix Color (textured_surfaces); a
normal-mapped sphere, a Principled card with image alpha and a colour-attribute box in fog
(textured_details). Planted errors the criterion must catch: the wall picture upside down, and the
normal map ignored (the interpolated normal used instead)."""
import importlib

import numpy as np
import pytest

from addon.compare import cycles_engine, metrics, runner, volpath_engine

from agreement_checks import assert_engines_agree

RESOLUTION = (32, 32)
SAMPLES = 256
RUNS = 8


@pytest.mark.agreement
@pytest.mark.parametrize("example", ["textured_surfaces", "textured_details"])
def test_textured_scenes_agree_with_cycles(registered_addon, example, tmp_path):
    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=SAMPLES, runs=RUNS, seed=1))
    assert_engines_agree(result, example, tmp_path)


def _planted(example, plant):
    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    native_scene, _ = volpath_engine.export(scene, RESOLUTION)
    plant(native_scene)
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=SAMPLES // RUNS, base_seed=1)
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=RUNS, samples=SAMPLES // RUNS, base_seed=101, bounces=bounces,
                                       resolution=RESOLUTION)
    return metrics.compare_runs(metrics.run_statistics([r.image for r in planted]),
                                metrics.run_statistics([r.image for r in cycles]))


@pytest.mark.agreement
def test_an_upside_down_picture_fails(registered_addon):
    def flip(native_scene):
        image = next(im for im in native_scene.images if im.name.startswith("wall picture"))
        image.pixels = np.ascontiguousarray(image.pixels[::-1])
    comparison = _planted("textured_surfaces", flip)
    assert not comparison.passed, comparison.summary()


@pytest.mark.agreement
def test_an_ignored_normal_map_fails(registered_addon):
    def drop_normal(native_scene):
        material = next(m for m in native_scene.materials if m.name == "Bumpy")
        material.surface_program.normal = -1
    comparison = _planted("textured_details", drop_normal)
    assert not comparison.passed, comparison.summary()
