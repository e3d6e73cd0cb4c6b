"""Math and Vector Math nodes compiled by ShaderCompiler against Cycles (every operation, the
edge cases each guards: division by 0, powers of negatives, logs of <= 0, wrap / ping-pong /
snap / compare / smooth min-max, use_clamp, degenerate vectors), through compiled_oracle."""
from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from compiled_oracle import (COLOR_AOVS, VALUE_AOVS, check_positions, check_variant, combine, math,  # noqa: E402
                             render_variants, split)
from cycles_oracle import Variant  # noqa: E402

from volpath_native.shading import program as P  # noqa: E402

# inputs: x, y in [-2, 1.75] (steps of 1/4), z in [-1, 2.75] (1/8), w = (i - j) 3/16
GRID = dict(scale=(0.25, 0.25, 0.125, 0.1875), offset=(-2.0, -2.0, -1.0, 0.0))
# x = 8 i in [0, 120]: overflow of exp / sinh / cosh and large powers
LARGE = dict(scale=(8.0, 0.25, 0.125, 0.1875), offset=(0.0, -2.0, -1.0, 0.0))


def math_variant(name, operations, grid=GRID, use_clamp=False, operands=None):
    """One value AOV per operation, all on the same inputs a, b, c = operands(x, y, z, w)."""
    def build(nodes, links, vector, w):
        x, y, z = split(nodes, links, vector)
        a, b, c = operands(nodes, links, x, y, z, w) if operands else (x, y, z)
        return {aov: math(nodes, links, op, a, b, c, use_clamp=use_clamp) for aov, op in zip(VALUE_AOVS, operations)}

    return Variant(name, build, grid["scale"], grid["offset"], dict(labels=dict(zip(VALUE_AOVS, operations))))


def _chunks(items, n):
    return [items[k:k + n] for k in range(0, len(items), n)]


MATH_CASES = [math_variant(f"math_{k}", ops) for k, ops in enumerate(_chunks(list(P.MATH_KINDS), 8))]
MATH_CASES += [
    # large arguments: exp/sinh/cosh overflow float32 in Cycles (inf); pow of big bases
    math_variant("math_large", ["EXPONENT", "SINH", "COSH", "POWER", "LOGARITHM", "TANGENT", "INVERSE_SQRT", "SQRT"],
                 LARGE),
    # powers of negatives: integer and non-integer exponents (w = 3/16 (i - j)), b = 0
    math_variant("math_pow_negative", ["POWER", "LOGARITHM", "PINGPONG", "WRAP", "SNAP", "FLOORED_MODULO",
                                       "MODULO", "SMOOTH_MAX"],
                 operands=lambda nodes, links, x, y, z, w: (y, math(nodes, links, "MULTIPLY", w, 0.5), x)),
    # constants: b = 0 (division, modulo, snap, pingpong by zero), c = 0 (smooth min/max k = 0)
    math_variant("math_zero", ["DIVIDE", "MODULO", "FLOORED_MODULO", "SNAP", "PINGPONG", "SMOOTH_MIN", "SMOOTH_MAX",
                               "ARCTAN2"],
                 operands=lambda nodes, links, x, y, z, w: (x, 0.0, 0.0)),
    # compare within a tolerance c that is sometimes 0 (FLT_EPSILON then), wrap with max < min
    math_variant("math_compare_wrap", ["COMPARE", "WRAP", "SMOOTH_MIN", "SMOOTH_MAX", "LESS_THAN", "GREATER_THAN",
                                       "ROUND", "TRUNC"],
                 operands=lambda nodes, links, x, y, z, w: (x, y, math(nodes, links, "MULTIPLY", w, 0.5))),
    math_variant("math_clamped", ["ADD", "MULTIPLY", "SUBTRACT", "DIVIDE", "POWER", "SINE", "EXPONENT", "ARCTAN2"],
                 use_clamp=True),
]

VECTOR_OPS = list(P.VECTOR_MATH_KINDS)
VALUE_OPS = ("DOT_PRODUCT", "DISTANCE", "LENGTH")


def vector_math_variant(name, operations, grid=GRID, operands=None):
    """Vector outputs of the operations into colour AOVs, value outputs into value AOVs; inputs
    a = (x, y, z), b = (y, z, w), c = (w, x, 1/2), scale = w unless operands says otherwise."""
    def build(nodes, links, vector, w):
        x, y, z = split(nodes, links, vector)
        if operands:
            a, b, c, s = operands(nodes, links, x, y, z, w)
        else:
            a, b, c, s = vector, combine(nodes, links, y, z, w), combine(nodes, links, w, x, 0.5), w
        outputs = {}
        colors, values = iter(COLOR_AOVS), iter(VALUE_AOVS)
        for op in operations:
            node = nodes.new("ShaderNodeVectorMath")
            node.operation = op
            for k, value in enumerate((a, b, c, s)):
                if hasattr(value, "node"):
                    links.new(value, node.inputs[k])
                else:
                    node.inputs[k].default_value = value
            if op in VALUE_OPS:
                outputs[next(values)] = node.outputs["Value"]
            else:
                outputs[next(colors)] = node.outputs["Vector"]
        return outputs

    labels = {}
    colors, values = iter(COLOR_AOVS), iter(VALUE_AOVS)
    for op in operations:
        labels[next(values) if op in VALUE_OPS else next(colors)] = op
    return Variant(name, build, grid["scale"], grid["offset"], dict(labels=labels))


_vector_ops = [op for op in VECTOR_OPS if op not in VALUE_OPS]
VECTOR_CASES = [vector_math_variant(f"vector_math_{k}", ops + (list(VALUE_OPS) if k == 0 else []))
                for k, ops in enumerate(_chunks(_vector_ops, 6))]
VECTOR_CASES += [
    # zero vectors and zero divisors: b = (y, 0, 0) has zero length where y = 0 (normalize, project,
    # reflect, refract of degenerate normals), modulo / snap / wrap / divide by zero components
    vector_math_variant("vector_math_degenerate", ["NORMALIZE", "PROJECT", "REFLECT", "REFRACT", "MODULO", "SNAP"],
                        operands=lambda nodes, links, x, y, z, w: (combine(nodes, links, y, 0.0, 0.0),
                                                                   combine(nodes, links, y, 0.0, 0.0),
                                                                   combine(nodes, links, x, 0.0, y), w)),
    # refract with total internal reflection (ior = 1.5 + 3/16 (i - j)), faceforward both ways,
    # wrap with max < min and max == min, power of negative bases
    vector_math_variant("vector_math_refract", ["REFRACT", "FACEFORWARD", "WRAP", "POWER", "DIVIDE", "SIGN"],
                        operands=lambda nodes, links, x, y, z, w: (
                            combine(nodes, links, x, y, 0.5), combine(nodes, links, 0.25, y, z),
                            combine(nodes, links, y, 0.0, x), math(nodes, links, "ADD", w, 1.5))),
]

CASES = MATH_CASES + VECTOR_CASES


@pytest.fixture(scope="module")
def rendered():
    return render_variants(CASES, VALUE_AOVS, COLOR_AOVS)


def test_pixel_positions(rendered):
    assert check_positions(rendered) is None


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.name for c in CASES])
def test_compiled_math_matches_cycles(rendered, index):
    failures, warnings = check_variant(CASES[index], index, rendered[index])
    assert not warnings
    assert not failures, "\n".join(failures)


def _index(name):
    return next(k for k, case in enumerate(CASES) if case.name == name)


@pytest.mark.parametrize("variant, opcode, operand, old, new", [
    # smooth max without its smoothing, floored modulo as truncated, wrap as pingpong
    ("math_4", "MATH", "kind#", P.MATH["SMOOTH_MAX"], P.MATH["MAXIMUM"]),
    ("math_5", "MATH", "kind#", P.MATH["FLOORED_MODULO"], P.MATH["MODULO"]),
    ("math_compare_wrap", "MATH", "kind#", P.MATH["WRAP"], P.MATH["PINGPONG"]),
    # refract as reflect, faceforward as the identity-ish multiply
    ("vector_math_refract", "VECTOR_MATH", "kind#", P.VECTOR_MATH["REFRACT"], P.VECTOR_MATH["REFLECT"]),
])
def test_planted_errors_are_caught(rendered, variant, opcode, operand, old, new):
    from compiled_oracle import replace_operand

    index = _index(variant)
    changed = []
    failures, _ = check_variant(CASES[index], index, rendered[index],
                                mutate=lambda program: changed.append(replace_operand(program, opcode, operand,
                                                                                      old, new)))
    assert changed[0] >= 1 and failures
