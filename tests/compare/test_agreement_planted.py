"""The agreement criterion must see a 3 % error in one BSDF lobe: metals_glossy rendered by VolPath
with its microfacet-reflection lobes (the Glossy floor and the gold Metallic sphere) 3 % too
bright has to fail the same tests (means, pixels, tiles; addon/compare/metrics.py compare_runs)
that the correct render passes in test_agreement.py. At the suite's 256 spp the shift (~1 % of
the image mean: the wall, the sky and the other spheres dilute it) hides in the noise, so this
test renders 4x the samples. Runtime ~30 s."""
import numpy as np
import pytest

from addon.compare import volpath_engine
from agreement_checks import assert_planted_error_fails

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
    # at this sample count the correct render still agrees, the planted one must not
    comparison = assert_planted_error_fails(scene, native_scene, correct, planted, RUNS, SAMPLES_PER_RUN)
    assert np.all(comparison.means.ratio > 1.0)
