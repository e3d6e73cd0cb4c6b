"""Float Curve, RGB Curves and Vector Curves compiled by ShaderCompiler (tables baked as Blender's
Cycles sync bakes them) against Cycles: extrapolated and horizontal ends, points outside the unit
range, handle types, the combined C curve of RGB Curves, factors outside 0..1."""
from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from compiled_oracle import (COLOR_AOVS, VALUE_AOVS, check_variant, combine, connect, math,  # noqa: E402
                             render_variants, replace_operand, split)
from cycles_oracle import Variant  # noqa: E402

# values x + y in [-0.25, 1.244] (256 distinct dyadic values); z in [0, 0.9375]; w in [-0.25, 1.156]
GRID = dict(scale=(0.09375, 0.005859375, 0.03125, 0.046875), offset=(-0.25, 0.0, 0.0, 0.5))


def shape(curve, points, handles=None):
    """Replace a CurveMap's points by `points` [(x, y), ...] (the first two exist already)."""
    while len(curve.points) > 2:
        curve.points.remove(curve.points[-1])
    curve.points[0].location = points[0]
    curve.points[1].location = points[-1]
    for x, y in points[1:-1]:
        curve.points.new(x, y)
    if handles:
        for point, handle in zip(curve.points, handles):
            point.handle_type = handle


def _prepare(mapping, extend, clip=True):
    mapping.extend = extend
    mapping.use_clip = clip
    if not clip:
        mapping.clip_min_x, mapping.clip_max_x = -2.0, 2.0
        mapping.clip_min_y, mapping.clip_max_y = -2.0, 2.0


FLOAT_SHAPES = [
    ("EXTRAPOLATED", True, [(0.0, 0.1), (0.3, 0.8), (0.6, 0.35), (1.0, 0.9)], None),
    ("HORIZONTAL", True, [(0.0, 0.1), (0.3, 0.8), (0.6, 0.35), (1.0, 0.9)], None),
    ("EXTRAPOLATED", True, [(0.2, 0.0), (0.5, 1.0), (0.8, 0.2)], ["VECTOR", "AUTO_CLAMPED", "AUTO"]),
    ("EXTRAPOLATED", False, [(-0.5, 1.5), (0.25, -0.5), (1.5, 0.75)], None),
    ("HORIZONTAL", False, [(-0.5, 1.5), (0.25, -0.5), (1.5, 0.75)], ["AUTO", "VECTOR", "AUTO"]),
]


def _float_curves(nodes, links, vector, w):
    x, y, z = split(nodes, links, vector)
    value = math(nodes, links, "ADD", x, y)
    outputs = {}
    for aov, (extend, clip, points, handles) in zip(VALUE_AOVS, FLOAT_SHAPES):
        node = nodes.new("ShaderNodeFloatCurve")
        _prepare(node.mapping, extend, clip)
        shape(node.mapping.curves[0], points, handles)
        node.mapping.update()
        links.new(value, node.inputs["Value"])
        connect(links, node.inputs["Factor"], 1.0 if aov != "v4" else w)
        outputs[aov] = node.outputs[0]
    return outputs


def _rgb_curves(nodes, links, vector, w):
    x, y, z = split(nodes, links, vector)
    color = combine(nodes, links, math(nodes, links, "ADD", x, y), z, math(nodes, links, "SUBTRACT", 1.0, x))
    outputs = {}
    for k, (extend, clip) in enumerate([("EXTRAPOLATED", True), ("HORIZONTAL", True), ("EXTRAPOLATED", False)]):
        node = nodes.new("ShaderNodeRGBCurve")
        mapping = node.mapping
        _prepare(mapping, extend, clip)
        shape(mapping.curves[3], [(0.0, 0.05), (0.4, 0.6), (1.0, 0.95)])            # C
        shape(mapping.curves[0], [(0.0, 0.2), (0.5, 0.3), (1.0, 1.0)])             # R
        shape(mapping.curves[2], [(0.1, 0.9), (1.0, 0.1)] if clip else [(-0.5, 0.9), (1.25, 0.1)])  # B
        mapping.update()
        links.new(color, node.inputs["Color"])
        connect(links, node.inputs["Fac"], w if k == 1 else 1.0)
        outputs[COLOR_AOVS[k]] = node.outputs[0]
    for k, extend in enumerate(["EXTRAPOLATED", "HORIZONTAL"]):
        node = nodes.new("ShaderNodeVectorCurve")
        mapping = node.mapping
        _prepare(mapping, extend, True)
        shape(mapping.curves[0], [(-1.0, -0.5), (0.0, 0.5), (1.0, 0.25)])
        shape(mapping.curves[1], [(-0.5, 1.0), (0.5, -1.0)])
        mapping.update()
        links.new(combine(nodes, links, math(nodes, links, "MULTIPLY", x, 2.0), z, math(nodes, links, "ADD", w, -0.5)),
                  node.inputs["Vector"])
        connect(links, node.inputs["Fac"], 1.0)
        outputs[COLOR_AOVS[3 + k]] = node.outputs[0]
    return outputs


CASES = [
    Variant("float_curves", _float_curves, GRID["scale"], GRID["offset"]),
    Variant("rgb_vector_curves", _rgb_curves, GRID["scale"], GRID["offset"]),
]


@pytest.fixture(scope="module")
def rendered():
    return render_variants(CASES, VALUE_AOVS, COLOR_AOVS)


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.name for c in CASES])
def test_compiled_curves_match_cycles(rendered, index):
    failures, warnings = check_variant(CASES[index], index, rendered[index])
    assert not warnings
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("index, opcode", [(0, "CURVE_FLOAT"), (1, "CURVE_RGB")])
def test_planted_errors_are_caught(rendered, index, opcode):
    """Extrapolation ignored: horizontal ends where Cycles extrapolates."""
    changed = []
    failures, _ = check_variant(CASES[index], index, rendered[index],
                                mutate=lambda p: changed.append(replace_operand(p, opcode, "extrapolate#", 1, 0)))
    assert changed[0] >= 1 and failures
