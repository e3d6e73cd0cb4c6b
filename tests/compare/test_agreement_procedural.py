"""Procedural media against Cycles: volumes whose density is computed by nodes, rendered by both
engines from the same .blend (examples/height_fog.py, noise_cloud.py, procedural_fire.py), and a
planted 5 % density error in the height fog that the same tests must catch (the thick, bright noise
cloud hardly changes with its density: multiple scattering at albedo 0.9 keeps its brightness)."""
import numpy as np
import pytest

from addon.compare import runner, volpath_engine
from agreement_checks import assert_engines_agree, assert_planted_error_fails

RESOLUTION = (32, 32)
SAMPLES, RUNS = 256, 8
PLANTED_ERROR = 1.05


@pytest.mark.agreement
@pytest.mark.parametrize("example", ["height_fog", "noise_cloud", "procedural_fire"])
def test_procedural_medium_agrees_with_cycles(registered_addon, example, tmp_path):
    import importlib

    module = importlib.import_module(f"examples.{example}")
    scene = module.build(resolution=RESOLUTION, samples=SAMPLES)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=SAMPLES, runs=RUNS, seed=1))
    assert_engines_agree(result, example, tmp_path)


@pytest.mark.agreement
def test_a_five_percent_density_error_fails(registered_addon):
    from examples import height_fog
    from volpath_native.program_medium import ProgramMedium

    scene = height_fog.build(resolution=RESOLUTION, samples=SAMPLES)
    native_scene, warnings = volpath_engine.export(scene, RESOLUTION)
    assert not warnings, warnings
    per_run = SAMPLES // RUNS
    correct = volpath_engine.render_runs(native_scene, runs=RUNS, samples=per_run, base_seed=1)
    (index, medium), = [(i, m) for i, m in enumerate(native_scene.media) if isinstance(m, ProgramMedium)]
    program = medium.program
    density_scale = np.flatnonzero(np.isclose(program.init, 1.2, rtol=1e-6))  # Map Range To Min (float32 in Blender)
    assert len(density_scale) == 1
    program.init[density_scale] *= PLANTED_ERROR
    native_scene.media[index] = ProgramMedium(medium.name, program, medium.object_to_world, medium.object_bounds,
                                              medium.frame[1], g=medium.g)
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=per_run, base_seed=1)
    assert_planted_error_fails(scene, native_scene, correct, planted, RUNS, per_run)
