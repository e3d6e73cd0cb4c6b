"""Cameras against Cycles on scenes that need them (the criterion of test_agreement.py): depth of
field in fog under a spot, camera motion blur in fog, an equirectangular view of a world volume,
object motion blur (a moving instance beside a still one) in fog, a moving emissive panel in a
drifting fog box, a moving box of procedural fog (its density pattern travels with it)."""
import importlib

import pytest

from addon.compare import runner

from agreement_checks import assert_engines_agree, unexpected_warnings

RUNS = 8
SCENES = {"dof_fog_spot": ((32, 32), 256), "motion_blur_fog": ((32, 32), 256), "sun_window_equirect": ((48, 24), 256),
          "moving_sphere_fog": ((32, 32), 256), "moving_emitter_fog": ((24, 24), 128),
          "moving_procedural_fog": ((24, 24), 128)}


@pytest.mark.agreement
@pytest.mark.parametrize("example", list(SCENES))
def test_camera_effects_agree_with_cycles(registered_addon, example, tmp_path):
    resolution, samples = SCENES[example]
    scene = importlib.import_module(f"examples.{example}").build(resolution=resolution, samples=samples)
    result = runner.compare_scene(scene, runner.CompareOptions(samples=samples, runs=RUNS, seed=1))
    assert_engines_agree(result, example, tmp_path)


def _without_object_motion(native_scene):
    for mesh in native_scene.meshes:
        mesh.motion = None


def _volume_at_the_centre(native_scene):
    """What VolPath did before: the box moves, its varying medium stays at the shutter centre."""
    for medium in native_scene.media:
        if getattr(medium, "motion", None) is not None:
            medium.motion = None


PLANTED = {"dof_fog_spot": dict(aperture_size=0.0), "motion_blur_fog": dict(motion_transforms=[]),
           "moving_sphere_fog": _without_object_motion, "moving_emitter_fog": _without_object_motion,
           "moving_procedural_fog": _volume_at_the_centre}


@pytest.mark.agreement
@pytest.mark.parametrize("case", list(PLANTED))
def test_without_the_effect_the_engines_disagree(registered_addon, case):
    """The criterion sees the effect: VolPath rendering the scene as a pinhole, without the
    camera's motion or without the objects' motion, must fail against Cycles where the full render
    passes (above)."""
    from addon.compare import cycles_engine, metrics, volpath_engine

    resolution, samples = SCENES[case]
    scene = importlib.import_module(f"examples.{case}").build(resolution=resolution, samples=samples)
    native_scene, warnings = volpath_engine.export(scene, resolution)
    assert not unexpected_warnings(warnings), warnings
    if callable(PLANTED[case]):
        PLANTED[case](native_scene)
    else:
        for key, value in PLANTED[case].items():
            setattr(native_scene.camera, key, value)
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=samples // RUNS, base_seed=1)
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=RUNS, samples=samples // RUNS, base_seed=101, bounces=bounces,
                                       resolution=resolution)
    comparison = metrics.compare_runs(metrics.run_statistics([r.image for r in planted]),
                                      metrics.run_statistics([r.image for r in cycles]))
    assert not comparison.passed, comparison.summary()
