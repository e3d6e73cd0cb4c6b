"""Node-graph structure compiled by ShaderCompiler against Cycles: node groups (nested, unlinked
group-node inputs, a group input used twice), reroutes (chained, unlinked), muted nodes (their
internal links, conversions through them, outputs without one)."""
from __future__ import annotations

import pytest

pytest.importorskip("bpy")

from compiled_oracle import (VALUE_AOVS, by_identifier, check_variant, combine, connect, math,  # noqa: E402
                             render_variants, split)
from cycles_oracle import Variant  # noqa: E402

GRID = dict(scale=(0.125, 0.125, 0.0625, 0.0625), offset=(-0.5, -0.25, 0.0, 0.5))


def _reroute(nodes, links, source=None):
    node = nodes.new("NodeReroute")
    if source is not None:
        links.new(source, node.inputs[0])
    return node.outputs[0]


def _muted(nodes, kind, **settings):
    node = nodes.new(kind)
    for key, value in settings.items():
        setattr(node, key, value)
    node.mute = True
    return node


def _reroutes_and_muted(nodes, links, vector, w):
    x, y, z = split(nodes, links, vector)
    a = combine(nodes, links, x, y, z)
    out = {}
    out["v0"] = math(nodes, links, "ADD", _reroute(nodes, links, _reroute(nodes, links, x)), 0.25)
    unlinked = math(nodes, links, "ADD", 0.0, 0.5)
    links.new(_reroute(nodes, links), unlinked.node.inputs[0])  # an unlinked reroute: the input's own value
    unlinked.node.inputs[0].default_value = 0.375
    out["v1"] = math(nodes, links, "ADD", unlinked, y)

    m = _muted(nodes, "ShaderNodeMath", operation="MULTIPLY")
    links.new(x, m.inputs[0])
    m.inputs[1].default_value = 3.0
    out["v2"] = math(nodes, links, "ADD", m.outputs[0], 0.0625)

    m = _muted(nodes, "ShaderNodeMath", operation="SUBTRACT")  # first input unlinked
    m.inputs[0].default_value = 0.7
    links.new(y, m.inputs[1])
    out["v3"] = math(nodes, links, "ADD", m.outputs[0], 0.0625)

    m = _muted(nodes, "ShaderNodeMix", data_type="FLOAT")
    connect(links, by_identifier(m.inputs, "Factor_Float"), w)
    connect(links, by_identifier(m.inputs, "A_Float"), x)
    connect(links, by_identifier(m.inputs, "B_Float"), y)
    out["v4"] = by_identifier(m.outputs, "Result_Float")

    m = _muted(nodes, "ShaderNodeSeparateXYZ")
    links.new(a, m.inputs[0])
    out["v5"] = m.outputs[1]

    m = _muted(nodes, "ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    connect(links, by_identifier(m.inputs, "Factor_Float"), w)
    connect(links, by_identifier(m.inputs, "A_Color"), a)
    connect(links, by_identifier(m.inputs, "B_Color"), combine(nodes, links, y, 0.5, x))
    out["c0"] = by_identifier(m.outputs, "Result_Color")

    m = _muted(nodes, "ShaderNodeInvert")
    links.new(a, m.inputs["Color"])
    out["c1"] = m.outputs[0]

    m = _muted(nodes, "ShaderNodeValToRGB")  # float in, colour out
    links.new(x, m.inputs[0])
    out["c2"] = m.outputs["Color"]
    out["v6"] = m.outputs["Alpha"]

    m = _muted(nodes, "ShaderNodeCombineXYZ")
    links.new(y, m.inputs[1])
    links.new(z, m.inputs[2])
    m.inputs[0].default_value = 0.8
    out["c3"] = m.outputs[0]

    m = _muted(nodes, "ShaderNodeRGBToBW")  # colour in, float out
    links.new(a, m.inputs[0])
    out["v7"] = m.outputs[0]
    return out


def _muted_more(nodes, links, vector, w):
    """Conversions through a muted node (vector -> colour there, colour -> float after: luminance,
    not the vector's average) and muted nodes whose inputs are all unlinked."""
    x, y, z = split(nodes, links, vector)
    out = {}
    m = _muted(nodes, "ShaderNodeInvert")
    links.new(vector, m.inputs["Color"])
    out["v0"] = math(nodes, links, "ADD", m.outputs[0], 0.0625)
    m = _muted(nodes, "ShaderNodeMath", operation="MULTIPLY")
    m.inputs[0].default_value, m.inputs[1].default_value = 0.7, 0.2
    out["v1"] = math(nodes, links, "ADD", m.outputs[0], x)
    m = _muted(nodes, "ShaderNodeMix", data_type="RGBA")
    by_identifier(m.inputs, "A_Color").default_value = (0.3, 0.6, 0.9, 1.0)
    out["c0"] = math(nodes, links, "ADD", by_identifier(m.outputs, "Result_Color"), y)
    m = _muted(nodes, "ShaderNodeValToRGB")
    m.inputs[0].default_value = 0.3
    out["c1"] = math(nodes, links, "ADD", m.outputs["Color"], z)
    return out


def _group_trees():
    import bpy

    inner = bpy.data.node_groups.get("oracle_inner")
    if inner is None:
        inner = bpy.data.node_groups.new("oracle_inner", "ShaderNodeTree")
        inner.interface.new_socket("A", in_out="INPUT", socket_type="NodeSocketFloat")
        inner.interface.new_socket("B", in_out="INPUT", socket_type="NodeSocketColor")
        inner.interface.new_socket("C", in_out="INPUT", socket_type="NodeSocketVector")
        inner.interface.new_socket("Out", in_out="OUTPUT", socket_type="NodeSocketFloat")
        inner.interface.new_socket("Col", in_out="OUTPUT", socket_type="NodeSocketColor")
        gi, go = inner.nodes.new("NodeGroupInput"), inner.nodes.new("NodeGroupOutput")
        n, k = inner.nodes, inner.links
        twice = math(n, k, "MULTIPLY", gi.outputs["A"], 2.0)
        k.new(math(n, k, "ADD", twice, gi.outputs["B"]), go.inputs["Out"])  # colour -> float inside
        mix = n.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = "SCREEN"
        k.new(gi.outputs["A"], by_identifier(mix.inputs, "Factor_Float"))   # A used twice
        k.new(gi.outputs["B"], by_identifier(mix.inputs, "A_Color"))
        k.new(_reroute(n, k, gi.outputs["C"]), by_identifier(mix.inputs, "B_Color"))
        k.new(by_identifier(mix.outputs, "Result_Color"), go.inputs["Col"])
    outer = bpy.data.node_groups.get("oracle_outer")
    if outer is None:
        outer = bpy.data.node_groups.new("oracle_outer", "ShaderNodeTree")
        outer.interface.new_socket("X", in_out="INPUT", socket_type="NodeSocketFloat")
        outer.interface.new_socket("V", in_out="INPUT", socket_type="NodeSocketVector")
        outer.interface.new_socket("Out", in_out="OUTPUT", socket_type="NodeSocketFloat")
        outer.interface.new_socket("Col", in_out="OUTPUT", socket_type="NodeSocketColor")
        gi, go = outer.nodes.new("NodeGroupInput"), outer.nodes.new("NodeGroupOutput")
        g = outer.nodes.new("ShaderNodeGroup")
        g.node_tree = inner
        outer.links.new(gi.outputs["X"], g.inputs["A"])
        g.inputs["B"].default_value = (0.2, 0.4, 0.6, 1.0)  # unlinked inside the outer group
        outer.links.new(gi.outputs["V"], g.inputs["C"])
        outer.links.new(g.outputs["Out"], go.inputs["Out"])
        outer.links.new(math(outer.nodes, outer.links, "SINE", g.outputs["Col"]), go.inputs["Col"])
    return inner, outer


def _groups(nodes, links, vector, w):
    x, y, z = split(nodes, links, vector)
    inner, outer = _group_trees()
    out = {}
    g = nodes.new("ShaderNodeGroup")
    g.node_tree = inner
    links.new(x, g.inputs["A"])
    links.new(combine(nodes, links, y, z, 0.25), g.inputs["B"])
    links.new(vector, g.inputs["C"])
    out["v0"], out["c0"] = g.outputs["Out"], g.outputs["Col"]
    g = nodes.new("ShaderNodeGroup")  # a second instance with unlinked inputs
    g.node_tree = inner
    g.inputs["A"].default_value = 0.3
    g.inputs["B"].default_value = (0.9, 0.1, 0.5, 1.0)
    links.new(vector, g.inputs["C"])
    out["v1"], out["c1"] = g.outputs["Out"], g.outputs["Col"]
    g = nodes.new("ShaderNodeGroup")  # nested
    g.node_tree = outer
    links.new(w, g.inputs["X"])
    links.new(vector, g.inputs["V"])
    out["v2"], out["c2"] = g.outputs["Out"], g.outputs["Col"]
    g = nodes.new("ShaderNodeGroup")  # nested, V unlinked
    g.node_tree = outer
    links.new(y, g.inputs["X"])
    g.inputs["V"].default_value = (0.5, -0.25, 1.0)
    out["v3"], out["c3"] = g.outputs["Out"], g.outputs["Col"]
    return out


CASES = [
    Variant("reroutes_and_muted", _reroutes_and_muted, GRID["scale"], GRID["offset"]),
    Variant("groups", _groups, GRID["scale"], GRID["offset"]),
    Variant("muted_more", _muted_more, GRID["scale"], GRID["offset"]),
]


@pytest.fixture(scope="module")
def rendered():
    from compiled_oracle import COLOR_AOVS

    return render_variants(CASES, VALUE_AOVS, COLOR_AOVS)


@pytest.mark.parametrize("index", range(len(CASES)), ids=[c.name for c in CASES])
def test_compiled_graph_matches_cycles(rendered, index):
    failures, warnings = check_variant(CASES[index], index, rendered[index])
    assert not warnings
    assert not failures, "\n".join(failures)
