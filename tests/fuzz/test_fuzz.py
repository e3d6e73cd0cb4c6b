"""The fuzz suite's short run (make test): random .vpscene files and random Blender scenes must hold
the invariants of fuzz_vpscene / fuzz_blender. Hypothesis shrinks any failure to a minimal case;
each one found becomes a regression test in test_fuzz_regressions.py. The long run: make fuzz
(tests/fuzz/run_fuzz.py, >= 1000 scenes, figures logged)."""
from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings

import fuzz_vpscene

EXAMPLES = int(os.environ.get("VOLPATH_FUZZ_EXAMPLES", "100"))
FUZZ_SETTINGS = dict(deadline=None, derandomize=True, database=None,
                     suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                            HealthCheck.data_too_large])


@pytest.fixture(scope="module", autouse=True)
def kernels_ready():
    """Compile (or load) the kernels first: the hang clock must not count the compile."""
    import volpath_native
    volpath_native.warm_up()


@settings(max_examples=2 * EXAMPLES, **FUZZ_SETTINGS)
@given(case=fuzz_vpscene.cases)
def test_malformed_vpscene_files_hold_the_invariants(case, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz") / "scene.vpscene"
    outcome = fuzz_vpscene.check(case, path)
    assert not outcome.failed, outcome


@settings(max_examples=EXAMPLES, **FUZZ_SETTINGS)
@given(desc=__import__("hypothesis").strategies.deferred(lambda: _blender().scenes))
def test_random_blender_scenes_hold_the_invariants(desc):
    outcome = _blender().check(desc)
    assert not outcome.failed, (outcome.crash or outcome, desc)


def _blender():
    pytest.importorskip("bpy")
    import addon
    import bpy
    if "volpath" not in bpy.types.Scene.bl_rna.properties:
        addon.register()
    import fuzz_blender
    return fuzz_blender
