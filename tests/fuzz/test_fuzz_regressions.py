"""Minimal cases the fuzz suite found (shrunk by hypothesis), kept as regression tests: each broke
an invariant before its fix."""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")

import addon  # noqa: E402
import fuzz_blender  # noqa: E402

NORMAL = {"location": "normal", "rotation": "normal", "scale": "normal"}


def scene(objects=(), lights=(), materials=({"surface": None, "volume": None, "mix": None},), world=None):
    return {"camera": {"type": "PERSP", "location": "normal", "lens": "normal"}, "materials": list(materials),
            "objects": list(objects), "lights": list(lights) or [light()], "world": world, "volumes": [],
            "resolution": 6, "samples": 1, "volume_bounces": 0}


def light(energy="normal", color="normal", kind="POINT", size="normal"):
    return {"type": kind, "energy": energy, "size": size, "color": color, "transform": NORMAL}


def cube(shape="cube", material=None, **transform):
    return {"shape": shape, "transform": {**NORMAL, **transform}, "material": material}


@pytest.fixture(scope="module", autouse=True)
def registered():
    if "volpath" not in bpy.types.Scene.bl_rna.properties:
        addon.register()


CASES = {
    # Blender stores an inf typed into Location as FLT_MAX: the object went far away, unnamed.
    "location inf": scene(objects=[cube(location="inf")]),
    # dropping the triangles of a NaN vertex left the vertex itself: "non-finite vertex coordinates".
    "nan vertex": scene(objects=[cube(shape="nan_vertex")]),
    # energy inf x colour 0 gave numpy's "invalid value encountered in multiply", unnamed.
    "inf energy, zero colour": scene(lights=[light(energy="inf", color="negative")]),
    # NaN light size: radius NaN reached the renderer.
    "nan light size": scene(lights=[light(size="nan"), light(kind="AREA", size="nan"), light(kind="SUN", size="nan")]),
    # the numbers of an emitter beyond float32 (FLT_MAX colour x strength): contributions dropped, named.
    "flt_max emission": scene(objects=[cube(material=0)], materials=[
        {"surface": {"kind": "ShaderNodeEmission", "inputs": {"Color": "flt_max", "Strength": "huge"}},
         "volume": None, "mix": None}]),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_regression(name):
    outcome = fuzz_blender.check(CASES[name])
    assert not outcome.failed, outcome
