"""SurfaceNode (bsdfs/nodes.py): Blender's node defaults, Cycles' clamping of bad input with a
warning per change, lossless records, and the packed table the kernels read."""
import json
import math

import numpy as np
import pytest

from volpath_native.bsdfs import KINDS, SurfaceNode, check_material, surface_node_table
from volpath_native.bsdfs.nodes import KIND_CODES, MAX_CLOSURES, TABLE_FIELDS


def test_defaults_are_blenders():
    p = SurfaceNode()
    assert p.kind == "principled" and p.distribution == "multi_ggx"
    assert np.allclose(p.color, 0.8) and p.roughness == 0.5 and p.ior == 1.5 and p.specular_ior_level == 0.5
    assert p.coat_roughness == 0.03 and p.coat_ior == 1.5 and p.sheen_roughness == 0.5
    assert np.allclose(SurfaceNode.for_kind("glass").color, 1.0) and SurfaceNode.for_kind("glass").roughness == 0
    r = SurfaceNode.for_kind("refraction")
    assert r.ior == 1.45 and r.distribution == "beckmann"
    m = SurfaceNode.for_kind("metallic")
    assert np.allclose(m.color, (0.617, 0.577, 0.540)) and np.allclose(m.edge_tint, (0.695, 0.726, 0.770))
    assert np.allclose(m.conductor_n, (2.757, 2.513, 2.231)) and np.allclose(m.conductor_k, (3.867, 3.404, 3.009))
    with pytest.raises(ValueError):
        SurfaceNode.for_kind("velvet")


def test_sanitize_clamps_as_cycles_and_warns():
    n = SurfaceNode(roughness=1.7, metallic=-0.2, ior=-1.0, alpha=float("nan"), color=(-0.5, 0.3, float("inf")),
                    coat_ior=0.5, coat_weight=-1.0, specular_ior_level=-2.0, distribution="ashikhmin_shirley")
    warnings = n.sanitize()
    assert n.roughness == 1.0 and n.metallic == 0.0 and n.ior == 1e-5 and n.alpha == 1.0
    assert n.coat_ior == 1.0 and n.coat_weight == 0.0 and n.specular_ior_level == 0.0
    assert np.allclose(n.color, (0.0, 0.3, 0.8)) and n.distribution == "multi_ggx"
    text = "\n".join(warnings)
    for word in ["Roughness", "Metallic", "Ior", "Alpha", "Color", "Coat Ior", "distribution"]:
        assert word in text, (word, text)
    assert n.sanitize() == [] and n.validate() == []  # idempotent: nothing left to fix
    # base colour above 1 is legal (the diffuse lobe uses it unclamped)
    assert SurfaceNode(color=(2.0, 1.0, 1.0)).sanitize() == []


def test_sanitize_kind_specific_rules():
    r = SurfaceNode.for_kind("refraction", roughness=-0.4)
    assert r.sanitize() and r.roughness == 0.4  # Cycles squares the Refraction roughness
    g = SurfaceNode.for_kind("glossy", anisotropic=1.5)
    g.sanitize()
    assert g.anisotropic == 0.99
    p = SurfaceNode(distribution="beckmann")
    assert p.sanitize() and p.distribution == "multi_ggx"
    s = SurfaceNode(subsurface_weight=0.5)
    assert any("ubsurface" in w for w in s.sanitize())
    u = SurfaceNode(kind="toon")
    assert u.sanitize() and u.kind == "diffuse"


def test_records_round_trip_through_json():
    nodes = [SurfaceNode(coat_weight=0.3, sheen_tint=(0.2, 0.4, 0.6), weight=0.25),
             SurfaceNode.for_kind("metallic", fresnel="physical", roughness=0.2)]
    back = [SurfaceNode.from_record(r) for r in json.loads(json.dumps([n.to_record() for n in nodes]))]
    for a, b in zip(nodes, back):
        for k, v in a.to_record().items():
            assert b.to_record()[k] == v
    # missing keys take the kind's defaults, unknown keys are ignored
    g = SurfaceNode.from_record({"kind": "glass", "ior": 1.33, "future_socket": 1})
    assert g.ior == 1.33 and g.roughness == 0.0 and np.allclose(g.color, 1.0)


def test_table_layout():
    mats = [[SurfaceNode()], [], [SurfaceNode.for_kind(k) for k in KINDS]]
    t = surface_node_table(mats)
    assert list(t._fields) == TABLE_FIELDS
    assert t.node_start.tolist() == [0, 1, 1] and t.node_count.tolist() == [1, 0, len(KINDS)]
    assert t.kind.dtype == np.int32 and t.kind.tolist() == [KIND_CODES["principled"]] + [KIND_CODES[k] for k in KINDS]
    assert t.color.shape == (1 + len(KINDS), 3) and t.color.dtype == np.float64
    assert t.roughness.shape == (1 + len(KINDS),)
    empty = surface_node_table([])
    assert empty.kind.shape == (0,) and empty.color.shape == (0, 3)
    # the table holds sanitised copies; the caller's nodes are untouched
    bad = SurfaceNode(roughness=math.nan)
    assert surface_node_table([[bad]]).roughness[0] == 0.5 and math.isnan(bad.roughness)


def test_check_material_warns_beyond_max_closures():
    assert check_material([SurfaceNode()]) == []
    many = [SurfaceNode(alpha=0.5, sheen_weight=1, coat_weight=1, metallic=0.5, transmission=0.5)] * 3
    assert any("closures" in w for w in check_material(many))
    assert sum(1 for _ in range(MAX_CLOSURES)) == MAX_CLOSURES
