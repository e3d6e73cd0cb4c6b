"""The agreement criterion must see a 3 % error in one BSDF lobe: metals_glossy rendered by VolPath
with its microfacet-reflection lobes (the Glossy floor and the gold Metallic sphere) 3 % too
bright has to fail the same tests (means, pixels, tiles; addon/compare/metrics.py compare_runs)
that the correct render passes in test_agreement.py. At the suite's 256 spp the shift (~1 % of
the image mean: the wall, the sky and the other spheres dilute it) hides in the noise, so this
test renders 4x the samples. Runtime ~30 s."""
import numpy as np
import pytest

from addon.compare import cycles_engine, metrics, volpath_engine

RESOLUTION = (32, 32)
SAMPLES_PER_RUN, RUNS = 128, 8
PLANTED_ERROR = 1.03


@pytest.mark.agreement
def test_a_three_percent_lobe_error_fails_the_agreement_tests(registered_addon):
    from examples import metals_glossy

    scene = metals_glossy.build(resolution=RESOLUTION, samples=SAMPLES_PER_RUN * RUNS)
    native_scene, warnings = volpath_engine.export(scene, RESOLUTION)
    assert not warnings, warnings
    correct = volpath_engine.render_runs(native_scene, runs=RUNS, samples=SAMPLES_PER_RUN, base_seed=1)
    for name, kind in (("Glossy floor", "glossy"), ("Gold", "metallic")):
        (node,) = next(m for m in native_scene.materials if m.name == name).surface_nodes
        assert node.kind == kind
        node.color = node.color * PLANTED_ERROR
    planted = volpath_engine.render_runs(native_scene, runs=RUNS, samples=SAMPLES_PER_RUN, base_seed=1)
    bounces = cycles_engine.BounceLimits.from_settings(native_scene.settings)
    cycles = cycles_engine.render_runs(scene, runs=RUNS, samples=SAMPLES_PER_RUN, base_seed=101, bounces=bounces,
                                       resolution=RESOLUTION)
    cycles_statistics = metrics.run_statistics([r.image for r in cycles])
    baseline = metrics.compare_runs(metrics.run_statistics([r.image for r in correct]), cycles_statistics)
    assert baseline.passed, baseline.summary()  # at this sample count the correct render still agrees
    comparison = metrics.compare_runs(metrics.run_statistics([r.image for r in planted]), cycles_statistics)
    assert not comparison.passed, comparison.summary()
    assert np.all(comparison.means.ratio > 1.0)
