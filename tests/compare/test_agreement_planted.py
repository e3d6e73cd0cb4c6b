"""The agreement criterion must see a 3 % error in one BSDF lobe: metals_glossy's Glossy floor
(half the image) rendered by VolPath with its colour 3 % high has to fail the same tests
(means, pixels, tiles; addon/compare/metrics.py compare_runs) that the correct render passes in
test_agreement.py. Runtime ~15 s (one Cycles and one VolPath set of runs at the suite's size)."""
import numpy as np
import pytest

from addon.compare import cycles_engine, metrics, volpath_engine

RESOLUTION = (32, 32)
SAMPLES_PER_RUN, RUNS = 32, 8  # the agreement suite's 256 spp over 8 runs
PLANTED_ERROR = 1.03


@pytest.mark.agreement
def test_a_three_percent_lobe_error_fails_the_agreement_tests(registered_addon):
    from examples import metals_glossy

    scene = metals_glossy.build(resolution=RESOLUTION, samples=SAMPLES_PER_RUN * RUNS)
    native_scene, warnings = volpath_engine.export(scene, RESOLUTION)
    assert not warnings, warnings
    floor = next(m for m in native_scene.materials if m.name == "Glossy floor")
    (node,) = floor.surface_nodes
    assert node.kind == "glossy"
    node.color = node.color * PLANTED_ERROR
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=SAMPLES_PER_RUN, base_seed=1)
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=RUNS, samples=SAMPLES_PER_RUN, base_seed=101, bounces=bounces,
                                       resolution=RESOLUTION)
    comparison = metrics.compare_runs(metrics.run_statistics([r.image for r in planted]),
                                      metrics.run_statistics([r.image for r in cycles]))
    assert not comparison.passed, comparison.summary()
    assert np.all(comparison.means.ratio > 1.0)
