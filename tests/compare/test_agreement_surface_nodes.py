"""Surfaces driven by nodes against Cycles (the agreement criterion of test_agreement.py):
anisotropic metals with the default radial tangent and a UV-map Tangent node (brushed_metal), and
a textured Emission light, a Principled card with a procedural emission colour, a Bump-mapped
sphere and a Box-projected image (textured_light_bump), a scaled sphere bumped by its Material
Output's Displacement ("Bump Only", displaced_sphere). Each feature has a planted error the
criterion must catch: the anisotropic rotation off by 90 degrees, the emission image upside down,
the bump inverted, the box-projected image mirrored, the displacement's object scale ignored (World
space). Cycles is rendered once per scene."""
import importlib

import numpy as np
import pytest

from addon.compare import cycles_engine, metrics, volpath_engine
from volpath_native.shading import program as P

RESOLUTION = (32, 32)
SAMPLES = 256
RUNS = 8
_CYCLES: dict = {}


def _scene(example):
    return importlib.import_module(f"examples.{example}").build(resolution=RESOLUTION, samples=SAMPLES)


def _cycles_statistics(example, scene, native_scene):
    if example not in _CYCLES:
        bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
        runs = cycles_engine.render_runs(scene, runs=RUNS, samples=SAMPLES // RUNS, base_seed=101, bounces=bounces,
                                         resolution=RESOLUTION)
        _CYCLES[example] = metrics.run_statistics([r.image for r in runs])
    return _CYCLES[example]


def _compare(example, plant=None):
    scene = _scene(example)
    native_scene, warnings = volpath_engine.export(scene, RESOLUTION)
    if plant is not None:
        plant(native_scene)
    ours = volpath_engine.render_runs(native_scene, runs=RUNS, samples=SAMPLES // RUNS, base_seed=1)
    return metrics.compare_runs(metrics.run_statistics([r.image for r in ours]),
                                _cycles_statistics(example, scene, native_scene)), warnings


@pytest.mark.agreement
@pytest.mark.parametrize("example", ["brushed_metal", "textured_light_bump", "displaced_sphere"])
def test_surface_node_scenes_agree_with_cycles(registered_addon, example, tmp_path):
    comparison, warnings = _compare(example)
    summary = comparison.summary()
    assert not warnings, warnings
    assert comparison.means.passed, summary
    assert comparison.pixel.passed, summary
    for size, test in comparison.blocks.items():
        assert test.passed, f"{size}x{size} blocks: {test.worst()}"
    assert min(summary["channel_means_b"]) > 1e-3


def _material(native_scene, name):
    return next(m for m in native_scene.materials if m.name == name)


def _rotate_90_degrees(native_scene):
    for name in ("Brushed sphere", "Brushed plate"):
        for node in _material(native_scene, name).surface_nodes:
            node.anisotropic_rotation += 0.25


def _flip_emission_image(native_scene):
    image = next(im for im in native_scene.images if im.name.startswith("stripes"))
    image.pixels = np.ascontiguousarray(image.pixels[::-1])


def _invert_bump(native_scene):
    code = _material(native_scene, "Bumpy sphere").surface_program.program.code
    by_code = {spec.code: spec for spec in P.OPS.values()}
    pc, found = 0, False
    while pc < len(code):
        spec = by_code[int(code[pc])]
        if int(code[pc]) == P.OP_BUMP:
            code[pc + 1] = 1 - code[pc + 1]
            found = True
        pc += 1 + len(spec.operands)
    assert found


def _displacement_in_world_space(native_scene):
    """The Displacement node read in World space: the sphere's object scale 1.6 no longer scales
    the displacement (a Midlevel error would not show: a constant height has no slope)."""
    code = _material(native_scene, "Displaced sphere").surface_program.program.code
    by_code = {spec.code: spec for spec in P.OPS.values()}
    pc, found = 0, 0
    while pc < len(code):
        spec = by_code[int(code[pc])]
        if int(code[pc]) == P.OP_DISPLACEMENT:
            code[pc + 1] = P.DISPLACEMENT_SPACES["WORLD"]
            found += 1
        pc += 1 + len(spec.operands)
    assert found == 3


def _mirror_box_image(native_scene):
    image = next(im for im in native_scene.images if im.name.startswith("box"))
    image.pixels = np.ascontiguousarray(image.pixels[:, ::-1])


@pytest.mark.agreement
@pytest.mark.parametrize("example, plant", [("brushed_metal", _rotate_90_degrees),
                                            ("textured_light_bump", _flip_emission_image),
                                            ("textured_light_bump", _invert_bump),
                                            ("textured_light_bump", _mirror_box_image),
                                            ("displaced_sphere", _displacement_in_world_space)],
                         ids=["rotation_off_by_90_degrees", "emission_upside_down", "bump_inverted",
                              "box_image_mirrored", "displacement_object_scale_ignored"])
def test_planted_surface_node_errors_fail(registered_addon, example, plant):
    comparison, _ = _compare(example, plant)
    assert not comparison.passed, comparison.summary()
