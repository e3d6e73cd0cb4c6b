"""Voronoi Texture against Cycles: every dimension, feature and metric, the fractal octaves
(detail, roughness, lacunarity), normalize, randomness, smoothness, large and negative
coordinates. Distance, Color, Position, W and Radius at every pixel of each 16 x 16 block."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy")

from cycles_oracle import Variant, link_input, point_inputs, render_variants, set_input  # noqa: E402
from oracle_compare import RELATIVE_TOLERANCE, mismatches  # noqa: E402

from volpath_native.shading.textures.voronoi import VORONOI_FEATURES, VORONOI_METRICS, voronoi_texture  # noqa: E402

DEFAULTS = dict(dims=3, feature="F1", metric="EUCLIDEAN", normalize=False, scale=5.0, detail=0.0, roughness=0.5,
                lacunarity=2.0, smoothness=1.0, exponent=0.5, randomness=1.0)
#: points allowed to differ per variant: a cell choice flips where two feature points are equally
#: near to within float32 rounding (Color and Position jump there); none seen, bound kept small
ALLOWED_FLIPS = 2


def case(name, coord_scale=(0.25, 0.25, 0.125, 0.1875), coord_offset=(0.1, 0.2, 0.3, 0.4), **params):
    p = dict(DEFAULTS, **params)

    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexVoronoi")
        node.voronoi_dimensions = f"{p['dims']}D"
        node.feature = p["feature"]
        node.distance = p["metric"]
        node.normalize = p["normalize"]
        for socket, key in (("Scale", "scale"), ("Detail", "detail"), ("Roughness", "roughness"),
                            ("Lacunarity", "lacunarity"), ("Smoothness", "smoothness"), ("Exponent", "exponent"),
                            ("Randomness", "randomness")):
            set_input(node, socket, p[key])
        link_input(links, node, "Vector", vector)
        link_input(links, node, "W", w)
        out = {s.identifier: s for s in node.outputs}
        return {"v0": out["Distance"], "c0": out["Color"], "c1": out["Position"], "v1": out["W"], "v2": out["Radius"]}

    return Variant(name, build, coord_scale, coord_offset, p)


CASES = (
    [case(f"{d}d_{f.lower()}", dims=d, feature=f) for d in (1, 2, 3, 4) for f in VORONOI_FEATURES]
    + [case(f"{d}d_{f.lower()}_{m.lower()}", dims=d, feature=f, metric=m, exponent=e)
       for d in (2, 3, 4) for f in ("F1", "F2", "SMOOTH_F1")
       for m, e in (("MANHATTAN", 0.5), ("CHEBYCHEV", 0.5), ("MINKOWSKI", 0.5 if d != 3 else 3.0))]
    + [
        case("fractal_1d_f1", dims=1, detail=2.5, roughness=0.6, lacunarity=2.3),
        case("fractal_2d_f2", dims=2, feature="F2", detail=3.0, roughness=0.7),
        case("fractal_3d_f1", detail=2.5, roughness=0.6, lacunarity=2.3),
        case("fractal_3d_smooth", feature="SMOOTH_F1", detail=1.6, smoothness=0.7),
        case("fractal_4d_f1", dims=4, detail=1.4, roughness=0.8),
        case("fractal_1d_edge", dims=1, feature="DISTANCE_TO_EDGE", detail=3.3),
        case("fractal_3d_edge", feature="DISTANCE_TO_EDGE", detail=2.7, lacunarity=1.7, roughness=0.9),
        case("fractal_3d_edge_normalized", feature="DISTANCE_TO_EDGE", detail=2.7, normalize=True),
        case("detail_15", detail=15.0, scale=1.3),
        case("roughness_0", detail=3.0, roughness=0.0),
        case("normalized_1d_f2", dims=1, feature="F2", normalize=True),
        case("normalized_2d_f1_manhattan", dims=2, metric="MANHATTAN", normalize=True, detail=1.5),
        case("normalized_3d_f1", normalize=True),
        case("normalized_4d_f2_minkowski", dims=4, feature="F2", metric="MINKOWSKI", exponent=1.5, normalize=True),
        case("normalized_3d_smooth", feature="SMOOTH_F1", normalize=True, detail=2.0),
        case("randomness_0", randomness=0.0, coord_offset=(0.13, 0.21, 0.37, 0.4)),
        case("randomness_half_2d", dims=2, randomness=0.5, feature="F2"),
        case("smoothness_0", feature="SMOOTH_F1", smoothness=0.0),
        case("smoothness_2_2d", dims=2, feature="SMOOTH_F1", smoothness=2.0),
        case("large_coordinates", scale=1.0, coord_scale=(0.75, 0.625, 0.5, 0.5),
             coord_offset=(1.0e6, -2.0e6, 3.0e6, 0.0)),
        case("large_coordinates_1d", dims=1, scale=1.0, coord_offset=(0, 0, 0, 3.0e6)),
        case("negative", coord_offset=(-7.3, -12.9, -3.1, -5.5), scale=2.7),
    ]
)


@pytest.fixture(scope="module")
def cycles_values():
    return render_variants(CASES)


def evaluate(variant, i, j):
    p = variant.params
    x, y, z, w = (c.astype(np.float64) for c in point_inputs(variant, i, j))  # float32 values
    return np.array([voronoi_texture(p["dims"], VORONOI_FEATURES[p["feature"]], VORONOI_METRICS[p["metric"]],
                                     p["normalize"], x[k], y[k], z[k], w[k], p["scale"], p["detail"], p["roughness"],
                                     p["lacunarity"], p["smoothness"], p["exponent"], p["randomness"])
                     for k in range(len(x))])


def cycles_columns(values):
    """Cycles' outputs in voronoi_texture's order: distance, colour (3), position (3), W, radius."""
    return np.column_stack([values["v0"], values["c0"][:, :3], values["c1"][:, :3], values["v1"], values["v2"]])


def test_voronoi_texture_matches_cycles(cycles_values):
    report = []
    for variant, values in zip(CASES, cycles_values):
        bad, worst = mismatches(evaluate(variant, values["i"], values["j"]), cycles_columns(values))
        if bad > ALLOWED_FLIPS:
            report.append(f"{variant.name}: {bad} of {len(values['i'])} points differ (worst {worst:.3g})")
    assert not report, "\n".join(report)


def test_planted_voronoi_errors_are_caught(cycles_values):
    """A feature point hashed from a neighbouring cell (wrong PCG input) or randomness off by 1 %
    must fail the same comparison."""
    variant, values = next((v, r) for v, r in zip(CASES, cycles_values) if v.name == "3d_f1")
    shifted = Variant(variant.name, variant.build, variant.scale,
                      (variant.offset[0] + 1.0 / variant.params["scale"],) + variant.offset[1:], variant.params)
    bad, _ = mismatches(evaluate(shifted, values["i"], values["j"]), cycles_columns(values))
    assert bad > len(values["i"]) // 2
    wrong = Variant(variant.name, variant.build, variant.scale, variant.offset,
                    dict(variant.params, randomness=0.99))
    bad, _ = mismatches(evaluate(wrong, values["i"], values["j"]), cycles_columns(values))
    assert bad > len(values["i"]) // 4
