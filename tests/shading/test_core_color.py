"""Colour and mixing nodes compiled by ShaderCompiler against Cycles: Mix (float, vector uniform
and non-uniform, colour with all 19 blend modes, clamp factor / clamp result), legacy MixRGB,
Invert, Gamma, Bright/Contrast, Hue/Saturation/Value, RGB to BW, Blackbody, Separate / Combine
Color (RGB, HSV, HSL) and XYZ, Value and RGB inputs, and the implicit socket conversions."""
from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from compiled_oracle import (COLOR_AOVS, VALUE_AOVS, by_identifier, check_variant, combine, connect, math,  # noqa: E402
                             render_variants, replace_operand, split)
from cycles_oracle import Variant  # noqa: E402

from volpath_native.shading import program as P  # noqa: E402

# colours a little outside [0, 1]: x in [-0.5, 1.375], y in [-0.25, 1.625], z in [0, 1.875];
# factor w in [-0.4375, 1.4375]
GRID = dict(scale=(0.125, 0.125, 0.0625, 0.0625), offset=(-0.5, -0.25, 0.0, 0.5))
# colours inside [0, 1] (HSV / HSL round trips): x, y in [0, 0.9375], z in [0, 0.9375]
UNIT = dict(scale=(0.0625, 0.0625, 0.03125, 0.0625), offset=(0.0, 0.0, 0.0, 0.5))


def variant(name, build_outputs, grid=GRID, labels=None, **params):
    """build_outputs(nodes, links, x, y, z, w, a, b) -> {aov: socket} with colours a = (x, y, z),
    b = (z, 1 - x, y)."""
    def build(nodes, links, vector, w):
        x, y, z = split(nodes, links, vector)
        b = combine(nodes, links, z, math(nodes, links, "SUBTRACT", 1.0, x), y)
        return build_outputs(nodes, links, x, y, z, w, vector, b)

    return Variant(name, build, grid["scale"], grid["offset"], dict(labels=labels or {}, **params))


def mix_node(nodes, links, data_type, factor, a, b, blend="MIX", clamp_factor=False, clamp_result=False,
             factor_mode="UNIFORM"):
    node = nodes.new("ShaderNodeMix")
    node.data_type = data_type
    node.blend_type = blend
    node.clamp_factor = clamp_factor
    node.clamp_result = clamp_result
    if data_type == "VECTOR":
        node.factor_mode = factor_mode
    suffix = {"FLOAT": "Float", "VECTOR": "Vector", "RGBA": "Color"}[data_type]
    factor_id = "Factor_Vector" if (data_type == "VECTOR" and factor_mode == "NON_UNIFORM") else "Factor_Float"
    connect(links, by_identifier(node.inputs, factor_id), factor)
    connect(links, by_identifier(node.inputs, f"A_{suffix}"), a)
    connect(links, by_identifier(node.inputs, f"B_{suffix}"), b)
    return by_identifier(node.outputs, f"Result_{suffix}")


def mix_rgb_node(nodes, links, factor, a, b, blend, use_clamp):
    node = nodes.new("ShaderNodeMixRGB")
    node.blend_type = blend
    node.use_clamp = use_clamp
    for k, value in enumerate((factor, a, b)):
        connect(links, node.inputs[k], value)
    return node.outputs[0]


def blend_variant(name, modes, grid=GRID, legacy=False, clamp=False):
    def outputs(nodes, links, x, y, z, w, a, b):
        if legacy:
            return {aov: mix_rgb_node(nodes, links, w, a, b, mode, clamp) for aov, mode in zip(COLOR_AOVS, modes)}
        return {aov: mix_node(nodes, links, "RGBA", w, a, b, mode, clamp_factor=clamp, clamp_result=clamp)
                for aov, mode in zip(COLOR_AOVS, modes)}

    return variant(name, outputs, grid, dict(zip(COLOR_AOVS, modes)))


def _chunks(items, n):
    return [items[k:k + n] for k in range(0, len(items), n)]


BLENDS = list(P.MIX_BLEND_KINDS)
BLEND_CASES = [blend_variant(f"mix_color_{k}", modes) for k, modes in enumerate(_chunks(BLENDS, 6))]
BLEND_CASES += [blend_variant(f"mix_color_unit_{k}", modes, UNIT) for k, modes in enumerate(_chunks(BLENDS, 6))]
BLEND_CASES += [blend_variant(f"mix_color_clamped_{k}", modes, clamp=True) for k, modes in enumerate(_chunks(BLENDS, 6))]
BLEND_CASES += [blend_variant(f"mix_rgb_{k}", modes, legacy=True, clamp=k % 2 == 1)
                for k, modes in enumerate(_chunks(BLENDS, 6))]


def _mix_float_vector(nodes, links, x, y, z, w, a, b):
    factor3 = combine(nodes, links, w, x, y)
    return {
        "v0": mix_node(nodes, links, "FLOAT", w, x, z),
        "v1": mix_node(nodes, links, "FLOAT", w, x, z, clamp_factor=True),
        "c0": mix_node(nodes, links, "VECTOR", w, a, b),
        "c1": mix_node(nodes, links, "VECTOR", w, a, b, clamp_factor=True),
        "c2": mix_node(nodes, links, "VECTOR", factor3, a, b, factor_mode="NON_UNIFORM"),
        "c3": mix_node(nodes, links, "VECTOR", factor3, a, b, clamp_factor=True, factor_mode="NON_UNIFORM"),
    }


def _color_ops(nodes, links, x, y, z, w, a, b):
    def node(kind, **inputs):
        n = nodes.new(kind)
        for key, value in inputs.items():
            connect(links, n.inputs[key.replace("_", " ")], value)
        return n

    outputs = {
        "c0": node("ShaderNodeInvert", Fac=w, Color=a).outputs[0],
        "c1": node("ShaderNodeGamma", Color=a, Gamma=y).outputs[0],
        "c2": node("ShaderNodeBrightContrast", Color=a, Bright=x, Contrast=y).outputs[0],
        "c3": node("ShaderNodeHueSaturation", Hue=x, Saturation=y, Value=z, Fac=w, Color=b).outputs[0],
        "v0": node("ShaderNodeRGBToBW", Color=a).outputs[0],
    }
    value = nodes.new("ShaderNodeValue")
    value.outputs[0].default_value = 0.625
    rgb = nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.25, 0.5, 0.875, 1.0)
    outputs["c4"] = mix_node(nodes, links, "RGBA", value.outputs[0], a, rgb.outputs[0], "MULTIPLY")
    return outputs


def _separate_combine(nodes, links, x, y, z, w, a, b):
    outputs = {}
    values = iter(VALUE_AOVS)
    for mode in ("RGB", "HSV", "HSL"):
        sep = nodes.new("ShaderNodeSeparateColor")
        sep.mode = mode
        links.new(b, sep.inputs[0])
        if mode != "RGB":
            for k in range(3):
                outputs[next(values)] = sep.outputs[k]
        else:
            outputs[next(values)] = sep.outputs[1]
        comb = nodes.new("ShaderNodeCombineColor")
        comb.mode = mode
        for k, value in enumerate((x, y, z)):
            links.new(value, comb.inputs[k])
        outputs[f"c{len([k for k in outputs if k.startswith('c')])}"] = comb.outputs[0]
    xyz = nodes.new("ShaderNodeSeparateXYZ")
    links.new(b, xyz.inputs[0])
    outputs[next(values)] = xyz.outputs[2]
    return outputs


def _conversions(nodes, links, x, y, z, w, a, b):
    """colour -> float is luminance, vector -> float the average, float -> colour a splat."""
    inverted = nodes.new("ShaderNodeInvert")  # a colour output
    inverted.inputs["Fac"].default_value = 1.0
    links.new(a, inverted.inputs["Color"])
    return {
        "v0": math(nodes, links, "ADD", inverted.outputs[0], 0.25),   # colour -> float
        "v1": math(nodes, links, "ADD", b, 0.25),                      # vector -> float
        "v2": inverted.outputs[0],                                      # colour into a Value AOV
        "v3": b,                                                        # vector into a Value AOV
        "c0": math(nodes, links, "MULTIPLY", x, y),                    # float into a Color AOV
        "c1": mix_node(nodes, links, "RGBA", 0.5, x, a, "ADD"),        # float into a colour input
    }


def _blackbody(nodes, links, x, y, z, w, a, b):
    bb = nodes.new("ShaderNodeBlackbody")
    links.new(math(nodes, links, "ADD", x, y), bb.inputs[0])
    return {"c0": bb.outputs[0]}


OTHER_CASES = [
    variant("mix_float_vector", _mix_float_vector),
    variant("color_ops", _color_ops),
    variant("color_ops_unit", _color_ops, UNIT),
    variant("separate_combine", _separate_combine),
    variant("separate_combine_unit", _separate_combine, UNIT),
    variant("conversions", _conversions),
    # temperatures 300 .. 12,000 + 750 K: below 800 K, every table segment, above 12,000 K
    variant("blackbody", _blackbody, dict(scale=(800.0, 50.0, 1.0, 1.0), offset=(300.0, 0.0, 0.0, 0.0))),
]

CASES = BLEND_CASES + OTHER_CASES


@pytest.fixture(scope="module")
def rendered():
    return render_variants(CASES, VALUE_AOVS, COLOR_AOVS)


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.name for c in CASES])
def test_compiled_color_nodes_match_cycles(rendered, index):
    failures, warnings = check_variant(CASES[index], index, rendered[index])
    assert not warnings
    assert not failures, "\n".join(failures)


def _index(name):
    return next(k for k, case in enumerate(CASES) if case.name == name)


@pytest.mark.parametrize("variant_name, opcode, operand, old, new", [
    # a wrong blend formula: overlay as soft light, burn as dodge, hue as colour
    ("mix_color_0", "MIX_COLOR", "blend#", P.MIX_BLEND["OVERLAY"], P.MIX_BLEND["SOFT_LIGHT"]),
    ("mix_color_1", "MIX_COLOR", "blend#", P.MIX_BLEND["BURN"], P.MIX_BLEND["DODGE"]),
    ("mix_color_unit_2", "MIX_COLOR", "blend#", P.MIX_BLEND["HUE"], P.MIX_BLEND["COLOR"]),
    # the clamped factor forgotten
    ("mix_color_clamped_0", "MIX_COLOR", "clamp_factor#", 1, 0),
    # HSL read as HSV
    ("separate_combine_unit", "SEPARATE3", "mode#", 2, 1),
])
def test_planted_errors_are_caught(rendered, variant_name, opcode, operand, old, new):
    index = _index(variant_name)
    changed = []
    failures, _ = check_variant(CASES[index], index, rendered[index],
                                mutate=lambda program: changed.append(replace_operand(program, opcode, operand,
                                                                                      old, new)))
    assert changed[0] >= 1 and failures


def test_planted_luminance_error_is_caught(rendered):
    """Cycles' no-OCIO fallback weights (0.2126729, 0.7151522, 0.0721750), 3e-5 off the weights
    Blender's config gives, must fail the colour -> float conversions."""
    from volpath_native.shading.program import OPERAND_COUNT, OPS

    def fallback_weights(program):
        changed, pc = 0, 0
        while pc < len(program.code):
            op = int(program.code[pc])
            if op in (OPS["COLOR_TO_FLOAT"].code, OPS["RGB_TO_BW"].code):
                weights = int(program.code[pc + 2])
                program.init[weights:weights + 3] = (0.2126729, 0.7151522, 0.0721750)
                changed += 1
            pc += 1 + int(OPERAND_COUNT[op])
        return changed

    for name in ("color_ops", "conversions"):
        index = _index(name)
        changed = []
        failures, _ = check_variant(CASES[index], index, rendered[index],
                                    mutate=lambda program: changed.append(fallback_weights(program)))
        assert changed[0] >= 1 and failures, name
