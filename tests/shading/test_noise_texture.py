"""Noise Texture against Cycles: every dimension and type, fractional / zero / maximal detail,
roughness 0, lacunarity, distortion, normalize off, and coordinates large enough (>= 1e6) for
the precision correction, negative, and across the 1e5 wrap. Fac and Color are compared at every
pixel of each variant's 16 x 16 block (cycles_oracle.py)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy")

from cycles_oracle import Variant, point_inputs, render_variants, set_input, link_input  # noqa: E402
from oracle_compare import RELATIVE_TOLERANCE, mismatches  # noqa: E402

from volpath_native.shading.textures.noise import NOISE_TYPES, noise_texture  # noqa: E402

DEFAULTS = dict(dims=3, type="FBM", normalize=True, scale=5.0, detail=2.0, roughness=0.5, lacunarity=2.0,
                offset=0.0, gain=1.0, distortion=0.0)


def case(name, coord_scale=(0.25, 0.25, 0.125, 0.1875), coord_offset=(0.1, 0.2, 0.3, 0.4), **params):
    p = dict(DEFAULTS, **params)

    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexNoise")
        node.noise_dimensions = f"{p['dims']}D"
        node.noise_type = p["type"]
        node.normalize = p["normalize"]
        for socket, key in (("Scale", "scale"), ("Detail", "detail"), ("Roughness", "roughness"),
                            ("Lacunarity", "lacunarity"), ("Offset", "offset"), ("Gain", "gain"),
                            ("Distortion", "distortion")):
            set_input(node, socket, p[key])
        link_input(links, node, "Vector", vector)
        link_input(links, node, "W", w)
        return {"v0": node.outputs["Fac"], "c0": node.outputs["Color"]}

    return Variant(name, build, coord_scale, coord_offset, p)


CASES = (
    # every dimension x type at defaults, the terrain types with a non-trivial offset and gain
    [case(f"{d}d_{t.lower()}", dims=d, type=t) for d in (1, 2, 3, 4) for t in ("FBM", "MULTIFRACTAL")]
    + [case(f"{d}d_{t.lower()}", dims=d, type=t, offset=1.0, gain=2.0, detail=3.0)
       for d in (1, 2, 3, 4) for t in ("HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN")]
    + [
        case("detail_0", detail=0.0),
        case("detail_15", detail=15.0),
        case("detail_fractional", detail=2.6),
        case("detail_fractional_4d_multi", dims=4, type="MULTIFRACTAL", detail=4.3, roughness=0.7),
        case("detail_fractional_hetero", type="HETERO_TERRAIN", detail=5.5, offset=0.5),
        case("detail_fractional_hybrid", type="HYBRID_MULTIFRACTAL", detail=4.3, offset=0.7, gain=3.0),
        case("detail_fractional_ridged", type="RIDGED_MULTIFRACTAL", detail=6.4, offset=1.2, gain=1.5),
        case("roughness_0", detail=3.0, roughness=0.0),
        case("lacunarity_2_3", detail=3.7, lacunarity=2.3, roughness=0.65),
        case("not_normalized_1d", dims=1, normalize=False, detail=3.0),
        case("not_normalized_3d", normalize=False, detail=4.5),
        case("distortion_1d", dims=1, distortion=1.3),
        case("distortion_2d", dims=2, distortion=2.1),
        case("distortion_3d", distortion=1.7, detail=3.2),
        case("distortion_4d", dims=4, distortion=0.8),
        case("precision_1e6", scale=1.0, coord_offset=(1.0e6, 1.5e6, -2.0e6, 3.0e6)),
        case("precision_1e6_4d", dims=4, scale=1.0, detail=3.0, coord_offset=(1.0e6, 1.5e6, -2.0e6, 3.0e6)),
        case("precision_1e6_1d", dims=1, scale=1.0, coord_offset=(0, 0, 0, -1.25e6)),
        case("across_wrap", scale=1.0, coord_offset=(99998.1, -99998.3, 99999.5, 0.0)),
        case("negative", coord_offset=(-7.3, -12.9, -3.1, -5.5), scale=2.7),
        case("scale_fractional_2d", dims=2, scale=0.37, coord_scale=(1.7, 2.3, 0.5, 0.5)),
    ]
)


@pytest.fixture(scope="module")
def cycles_values():
    return render_variants(CASES)


def evaluate(variant, i, j, planted_scale=1.0):
    p = variant.params
    x, y, z, w = (c.astype(np.float64) for c in point_inputs(variant, i, j))  # float32 values
    out = np.array([noise_texture(p["dims"], NOISE_TYPES[p["type"]], p["normalize"], True, x[k], y[k], z[k], w[k],
                                  p["scale"], p["detail"], p["roughness"], p["lacunarity"], p["offset"], p["gain"],
                                  p["distortion"]) for k in range(len(x))])
    return out


def test_noise_texture_matches_cycles(cycles_values):
    report = []
    for variant, values in zip(CASES, cycles_values):
        ours = evaluate(variant, values["i"], values["j"])
        # distortion moves the coordinate by a float32 rounding of Cycles' own noise value: one ulp
        # of |p| ~ 20 (2e-6) times the fBM's slope (~3 per unit) -> 1e-4
        tolerance = 1e-4 if variant.params["distortion"] else RELATIVE_TOLERANCE
        bad, worst = mismatches(np.column_stack([ours[:, 0], ours[:, 2:]]),
                                np.column_stack([values["v0"], values["c0"][:, 1:3]]), tolerance)
        if bad:
            report.append(f"{variant.name}: {bad} of {len(ours)} points differ (worst {worst:.3g})")
    assert not report, "\n".join(report)


def test_planted_noise_scale_error_is_caught(cycles_values):
    """The 3D scale constant 0.9820 off by 0.1 % must fail the same comparison."""
    variant, values = next((v, r) for v, r in zip(CASES, cycles_values) if v.name == "3d_fbm")
    ours = evaluate(variant, values["i"], values["j"])
    # fBM normalized: fac = 0.5 sum/maxamp + 0.5 is linear in the noise scale
    planted = 0.5 + (ours[:, 0] - 0.5) * (0.9830 / 0.9820)
    bad, _ = mismatches(planted, values["v0"])
    assert bad > len(planted) // 4


def test_random_offsets_table_equals_compiled_hash():
    """noise.RANDOM_OFFSETS (built at import) holds what the compiled hashes give for every
    (dimensions, seed, component) the node uses; a table entry off by one float32 ulp fails."""
    import numba
    from volpath_native.shading.textures import noise as N
    hashed = numba.njit(N._hashed_random_offset)
    for d in range(1, 5):
        for s in range(6):
            for c in range(4):
                assert N.RANDOM_OFFSETS[d, s, c] == hashed(d, float(s), c), (d, s, c)
    assert N.RANDOM_OFFSETS[3, 3, 0] != np.nextafter(hashed(3, 3.0, 0), np.float32(300.0))
