"""Clamp, Map Range (float and vector), Color Ramp, Mapping and Texture Coordinate nodes compiled
by ShaderCompiler against Cycles."""
from __future__ import annotations

import math as pymath

import pytest

pytest.importorskip("bpy")

from compiled_oracle import (BLOCK, COLOR_AOVS, VALUE_AOVS, by_identifier, check_variant, combine,  # noqa: E402
                             connect, math, render_variants, replace_operand, split)
from cycles_oracle import Variant  # noqa: E402

from volpath_native.shading import program as P  # noqa: E402

GRID = dict(scale=(0.25, 0.25, 0.125, 0.1875), offset=(-2.0, -2.0, -1.0, 0.0))
# ramp factors x + y in [-0.25, 1.244]: 256 distinct dyadic values, some outside [0, 1]
RAMP = dict(scale=(0.09375, 0.005859375, 0.0, 0.0), offset=(-0.25, 0.0, 0.0, 0.0))
MAP_RANGE_TYPES = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")


def variant(name, build_outputs, grid=GRID, **params):
    def build(nodes, links, vector, w):
        x, y, z = split(nodes, links, vector)
        return build_outputs(nodes, links, vector, x, y, z, w)

    return Variant(name, build, grid["scale"], grid["offset"], dict(params))


def _clamp(nodes, links, vector, x, y, z, w):
    outputs = {}
    for aov, (kind, lo, hi) in zip(VALUE_AOVS, [("MINMAX", x, y), ("RANGE", x, y), ("MINMAX", -0.5, 0.75),
                                                 ("RANGE", 0.75, -0.5), ("MINMAX", 0.75, -0.5)]):
        node = nodes.new("ShaderNodeClamp")
        node.clamp_type = kind
        connect(links, node.inputs["Value"], z)
        connect(links, node.inputs["Min"], lo)
        connect(links, node.inputs["Max"], hi)
        outputs[aov] = node.outputs[0]
    return outputs


def map_range_node(nodes, links, kind, clamp, value, from_min, from_max, to_min, to_max, steps, vector=False):
    node = nodes.new("ShaderNodeMapRange")
    node.data_type = "FLOAT_VECTOR" if vector else "FLOAT"
    node.interpolation_type = kind
    node.clamp = clamp
    suffix = "_FLOAT3" if vector else ""
    names = ("Vector",) if vector else ("Value",)
    connect(links, by_identifier(node.inputs, names[0]), value)
    for key, v in (("From Min", from_min), ("From Max", from_max), ("To Min", to_min), ("To Max", to_max),
                   ("Steps", steps)):
        connect(links, by_identifier(node.inputs, key.replace(" ", "_") + suffix if vector else key), v)
    return by_identifier(node.outputs, "Vector" if vector else "Result")


def _map_range_float(operands):
    def outputs(nodes, links, vector, x, y, z, w):
        args = operands(nodes, links, x, y, z, w)
        result = {}
        aovs = iter(VALUE_AOVS)
        for kind in MAP_RANGE_TYPES:
            for clamp in (False, True):
                result[next(aovs)] = map_range_node(nodes, links, kind, clamp, *args)
        return result
    return outputs


def _map_range_vector(kinds):
    def outputs(nodes, links, vector, x, y, z, w):
        args = (vector, combine(nodes, links, y, 0.0, -1.0), combine(nodes, links, 0.5, z, -1.0),
                combine(nodes, links, z, -0.5, 2.0), combine(nodes, links, 1.0, 0.25, w),
                combine(nodes, links, 4.0, w, 0.0))
        result = {}
        aovs = iter(COLOR_AOVS)
        for kind in kinds:
            for clamp in (False, True):
                result[next(aovs)] = map_range_node(nodes, links, kind, clamp, *args, vector=True)
        return result
    return outputs


def _ramp(nodes, links, factor, interpolation, color_mode="RGB", hue="NEAR"):
    node = nodes.new("ShaderNodeValToRGB")
    ramp = node.color_ramp
    ramp.color_mode = color_mode
    ramp.hue_interpolation = hue
    ramp.interpolation = interpolation
    ramp.elements[0].position = 0.1
    ramp.elements[0].color = (0.9, 0.1, 0.2, 0.25)
    ramp.elements[1].position = 0.8
    ramp.elements[1].color = (0.1, 0.3, 1.0, 1.0)
    middle = ramp.elements.new(0.45)
    middle.color = (0.2, 0.95, 0.4, 0.5)
    links.new(factor, node.inputs["Fac"])
    return node


def _ramps(settings):
    def outputs(nodes, links, vector, x, y, z, w):
        factor = math(nodes, links, "ADD", x, y)
        result = {}
        for k, args in enumerate(settings):
            node = _ramp(nodes, links, factor, *args)
            result[COLOR_AOVS[k]] = node.outputs["Color"]
            result[VALUE_AOVS[k]] = node.outputs["Alpha"]
        return result
    return outputs


def _mapping(nodes, links, vector, x, y, z, w):
    result = {}
    rotation = combine(nodes, links, math(nodes, links, "MULTIPLY", x, 0.5), 0.3, w)
    for aov, (kind, scale) in zip(COLOR_AOVS, [("POINT", (1.5, -0.5, 2.0)), ("TEXTURE", (1.5, -0.5, 2.0)),
                                              ("VECTOR", (1.5, -0.5, 2.0)), ("NORMAL", (1.5, -0.5, 2.0)),
                                              ("TEXTURE", (0.0, 2.0, 1.0)), ("NORMAL", (1.0, 0.0, 1.0))]):
        node = nodes.new("ShaderNodeMapping")
        node.vector_type = kind
        links.new(vector, by_identifier(node.inputs, "Vector"))
        by_identifier(node.inputs, "Location").default_value = (0.25, -0.5, 0.75)  # unused by vector / normal
        links.new(rotation, by_identifier(node.inputs, "Rotation"))
        by_identifier(node.inputs, "Scale").default_value = scale
        result[aov] = node.outputs[0]
    return result


def _texture_space(obj):
    obj.data.use_auto_texspace = False
    obj.data.texspace_location = (0.3, 0.6, 0.1)
    obj.data.texspace_size = (0.4, 0.7, 0.5)


def _texture_coordinate(nodes, links, vector, x, y, z, w):
    import bpy

    reference = bpy.data.objects.get("texco_reference") or bpy.data.objects.new("texco_reference", None)
    reference.location = (0.5, -1.0, 0.25)
    reference.rotation_euler = (0.3, -0.2, 1.1)
    reference.scale = (2.0, 0.5, 1.5)
    plain = nodes.new("ShaderNodeTexCoord")
    other = nodes.new("ShaderNodeTexCoord")
    other.object = reference
    return {"c0": plain.outputs["Generated"], "c1": plain.outputs["Object"], "c2": other.outputs["Object"]}


# The pixel's sample lies within 0.005 px of its centre (Box filter 0.01): coordinates read
# directly (not floored to the cell) agree to that, times the coordinate's gradient (<= 2.5 here).
TEXCO_ABSOLUTE = 2.5 * 0.005 / BLOCK

CASES = [
    variant("clamp", _clamp),
    # from_min = y crosses from_max = 0.5 (equal and inverted ranges); to_min = z crosses to_max = 1
    variant("map_range_linked", _map_range_float(lambda nodes, links, x, y, z, w: (x, y, 0.5, z, 1.0, 4.0))),
    variant("map_range_inverted", _map_range_float(lambda nodes, links, x, y, z, w: (x, 1.0, -1.0, 2.0, -0.5, w))),
    variant("map_range_equal", _map_range_float(lambda nodes, links, x, y, z, w: (x, 0.5, 0.5, 0.25, 0.75, 3.0))),
    variant("map_range_vector_0", _map_range_vector(MAP_RANGE_TYPES[:3])),
    variant("map_range_vector_1", _map_range_vector(MAP_RANGE_TYPES[3:])),
    variant("color_ramp_rgb", _ramps([("LINEAR",), ("CONSTANT",), ("EASE",), ("B_SPLINE",), ("CARDINAL",)]), RAMP),
    variant("color_ramp_hsv", _ramps([("LINEAR", "HSV", "NEAR"), ("LINEAR", "HSV", "FAR"), ("LINEAR", "HSL", "CW"),
                                      ("LINEAR", "HSL", "CCW"), ("EASE", "HSV", "NEAR"), ("CONSTANT", "HSL", "FAR")]),
            RAMP),
    variant("mapping", _mapping),
    variant("texture_coordinate", _texture_coordinate, setup=_texture_space,
            absolute={"c0": TEXCO_ABSOLUTE, "c1": TEXCO_ABSOLUTE, "c2": TEXCO_ABSOLUTE}),
]


@pytest.fixture(scope="module")
def rendered():
    return render_variants(CASES, VALUE_AOVS, COLOR_AOVS)


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.name for c in CASES])
def test_compiled_nodes_match_cycles(rendered, index):
    failures, warnings = check_variant(CASES[index], index, rendered[index])
    assert not warnings
    assert not failures, "\n".join(failures)


def _index(name):
    return next(k for k, case in enumerate(CASES) if case.name == name)


def _swap_texspace(program):
    """Planted error: Generated read as Object coordinates."""
    return replace_operand(program, "TEXCO", "kind#", P.TEXCO_GENERATED, P.TEXCO_OBJECT)


@pytest.mark.parametrize("variant_name, mutate", [
    ("clamp", lambda p: replace_operand(p, "CLAMP", "kind#", 1, 0)),          # range without the swap
    ("map_range_inverted", lambda p: replace_operand(p, "MAP_RANGE", "kind#", 2, 3)),  # smoothstep as smootherstep
    ("mapping", lambda p: replace_operand(p, "MAPPING", "kind#", 1, 0)),      # texture as point
    ("color_ramp_rgb", lambda p: replace_operand(p, "COLOR_RAMP", "interpolate#", 0, 1)),  # constant interpolated
    ("texture_coordinate", _swap_texspace),
])
def test_planted_errors_are_caught(rendered, variant_name, mutate):
    index = _index(variant_name)
    changed = []
    failures, _ = check_variant(CASES[index], index, rendered[index], mutate=lambda p: changed.append(mutate(p)))
    assert changed[0] >= 1 and failures
