"""Procedural media against Cycles: volumes whose density is computed by nodes, rendered by both
engines from the same .blend (examples/height_fog.py, examples/noise_cloud.py), and a planted 5 %
density error in the noise cloud that the same tests must catch."""
import numpy as np
import pytest

from addon.compare import cycles_engine, metrics, runner, volpath_engine
from agreement_checks import assert_engines_agree

RESOLUTION = (32, 32)
SAMPLES, RUNS = 256, 8
PLANTED_ERROR = 1.05


@pytest.mark.agreement
@pytest.mark.parametrize("example", ["height_fog", "noise_cloud"])
def test_procedural_medium_agrees_with_cycles(registered_addon, example, tmp_path):
    import importlib

    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=SAMPLES, runs=RUNS, seed=1))
    assert_engines_agree(result, example, tmp_path)


@pytest.mark.agreement
def test_a_five_percent_density_error_fails(registered_addon):
    from examples import noise_cloud
    from volpath_native.program_medium import ProgramMedium

    scene = noise_cloud.build(resolution=RESOLUTION, samples=SAMPLES)
    native_scene, warnings = volpath_engine.export(scene, RESOLUTION)
    assert not warnings, warnings
    per_run = SAMPLES // RUNS
    correct = volpath_engine.render_runs(native_scene, runs=RUNS, samples=per_run, base_seed=1)
    (index, medium), = [(i, m) for i, m in enumerate(native_scene.media) if isinstance(m, ProgramMedium)]
    program = medium.program
    density_scale = np.flatnonzero(program.init == 6.0)  # the Math node's "x 6" (noise_cloud density)
    assert len(density_scale) == 1
    program.init[density_scale] *= PLANTED_ERROR
    native_scene.media[index] = ProgramMedium(medium.name, program, medium.object_to_world, medium.object_bounds,
                                              medium.frame[1], g=medium.g)
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=per_run, base_seed=1)
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=RUNS, samples=per_run, base_seed=101, bounces=bounces,
                                       resolution=RESOLUTION)
    cycles_statistics = metrics.run_statistics([r.image for r in cycles])
    baseline = metrics.compare_runs(metrics.run_statistics([r.image for r in correct]), cycles_statistics)
    assert baseline.passed, baseline.summary()
    comparison = metrics.compare_runs(metrics.run_statistics([r.image for r in planted]), cycles_statistics)
    assert not comparison.passed, comparison.summary()
