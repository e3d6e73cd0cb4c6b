"""Gradient, White Noise, Wave and Magic textures against Cycles, every type / dimension /
direction / profile / depth, in one render (cycles_oracle.py)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy")

from cycles_oracle import Variant, link_input, point_inputs, render_variants, set_input  # noqa: E402
from oracle_compare import RELATIVE_TOLERANCE, mismatches  # noqa: E402

from volpath_native.shading.textures import hash as hashes  # noqa: E402
from volpath_native.shading.textures.gradient import GRADIENT_TYPES, gradient_texture  # noqa: E402
from volpath_native.shading.textures.magic import magic_texture  # noqa: E402
from volpath_native.shading.textures.wave import (BANDS_DIRECTIONS, RINGS_DIRECTIONS, WAVE_PROFILES,  # noqa: E402
                                                  WAVE_TYPES, wave_texture)
from volpath_native.shading.textures.white_noise import white_noise_texture  # noqa: E402


def gradient_case(kind):
    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexGradient")
        node.gradient_type = kind
        link_input(links, node, "Vector", vector)
        return {"v0": node.outputs["Fac"], "c0": node.outputs["Color"]}

    def ours(x, y, z, w):
        f = gradient_texture(GRADIENT_TYPES[kind], x, y, z)
        return f, f, f, f

    return Variant(f"gradient_{kind.lower()}", build, (0.1, 0.1, 0.05, 0.1), (-0.5, -0.75, -0.4, 0.0),
                   dict(ours=ours, flips=0))


def white_noise_case(dims, coord_scale=(0.25, 0.25, 0.125, 0.1875), coord_offset=(0.1, 0.2, 0.3, 0.4), tag=""):
    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexWhiteNoise")
        node.noise_dimensions = f"{dims}D"
        link_input(links, node, "Vector", vector)
        link_input(links, node, "W", w)
        return {"v0": node.outputs["Value"], "c0": node.outputs["Color"]}

    def ours(x, y, z, w):
        return white_noise_texture(dims, True, x, y, z, w)

    return Variant(f"white_noise_{dims}d{tag}", build, coord_scale, coord_offset, dict(ours=ours, flips=0))


def wave_case(kind, direction, profile, scale=5.0, distortion=0.0, detail=2.0, detail_scale=1.0, roughness=0.5,
              phase=0.0, coord_offset=(0.1, 0.2, 0.3, 0.4)):
    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexWave")
        node.wave_type = kind
        if kind == "BANDS":
            node.bands_direction = direction
        else:
            node.rings_direction = direction
        node.wave_profile = profile
        for socket, value in (("Scale", scale), ("Distortion", distortion), ("Detail", detail),
                              ("Detail Scale", detail_scale), ("Detail Roughness", roughness),
                              ("Phase Offset", phase)):
            set_input(node, socket, value)
        link_input(links, node, "Vector", vector)
        return {"v0": node.outputs["Fac"], "c0": node.outputs["Color"]}

    directions = BANDS_DIRECTIONS if kind == "BANDS" else RINGS_DIRECTIONS

    def ours(x, y, z, w):
        f = wave_texture(WAVE_TYPES[kind], directions[direction], WAVE_PROFILES[profile], x, y, z, scale, distortion,
                         detail, detail_scale, roughness, phase)
        return f, f, f, f

    # saw / triangle jump where n crosses a multiple of 2 pi: a float32 ulp of n can flip a point
    name = f"wave_{kind.lower()}_{direction.lower()}_{profile.lower()}" + ("_distorted" if distortion else "")
    # distortion d moves n by d times the fBM's float32 error
    tolerance = RELATIVE_TOLERANCE * max(1.0, distortion)
    return Variant(name, build, (0.05, 0.05, 0.025, 0.05), coord_offset,
                   dict(ours=ours, flips=0 if profile == "SIN" else 2, tolerance=tolerance))


def magic_case(depth, scale=5.0, distortion=1.0, coord_offset=(0.1, 0.2, 0.3, 0.4), tag=""):
    def build(nodes, links, vector, w):
        node = nodes.new("ShaderNodeTexMagic")
        node.turbulence_depth = depth
        set_input(node, "Scale", scale)
        set_input(node, "Distortion", distortion)
        link_input(links, node, "Vector", vector)
        return {"v0": node.outputs["Fac"], "c0": node.outputs["Color"]}

    def ours(x, y, z, w):
        return magic_texture(depth, x, y, z, scale, distortion)

    return Variant(f"magic_{depth}{tag}", build, (0.05, 0.05, 0.025, 0.05), coord_offset,
                   dict(ours=ours, flips=0))


CASES = (
    [gradient_case(kind) for kind in GRADIENT_TYPES]
    + [white_noise_case(d) for d in (1, 2, 3, 4)]
    # negative zero (0 * -s) and large values hash their own bit patterns
    + [white_noise_case(d, (-0.5, -0.25, -1.0, -0.75), (0.0, 3.0e6, -1.0e-30, 0.0), "_signed_zero") for d in (1, 3, 4)]
    + [wave_case("BANDS", d, p) for d in BANDS_DIRECTIONS for p in WAVE_PROFILES]
    + [wave_case("RINGS", d, p) for d in RINGS_DIRECTIONS for p in WAVE_PROFILES]
    + [
        wave_case("BANDS", "X", "SIN", distortion=3.0, detail=2.5, detail_scale=1.7, roughness=0.6, phase=0.7),
        wave_case("RINGS", "SPHERICAL", "SAW", distortion=1.5, detail=0.0, phase=-1.3, coord_offset=(-1, -2, 0.5, 0)),
        wave_case("BANDS", "DIAGONAL", "TRI", distortion=7.0, detail=6.0, detail_scale=3.0, roughness=0.8),
    ]
    + [magic_case(depth) for depth in range(11)]
    + [
        magic_case(4, distortion=0.0, tag="_undistorted"),
        magic_case(3, scale=1.3, distortion=2.5, tag="_distortion_2_5"),
        magic_case(2, scale=0.7, coord_offset=(1.0e4, -3.0e4, 77.7, 0.0), tag="_wrapped"),
    ]
)


@pytest.fixture(scope="module")
def cycles_values():
    return render_variants(CASES)


def evaluate(variant, i, j, function=None):
    x, y, z, w = point_inputs(variant, i, j)
    function = function or variant.params["ours"]
    return np.array([function(float(x[k]), float(y[k]), float(z[k]), float(w[k])) for k in range(len(x))])


def test_simple_textures_match_cycles(cycles_values):
    report = []
    for variant, values in zip(CASES, cycles_values):
        ours = evaluate(variant, values["i"], values["j"])
        bad, worst = mismatches(ours, np.column_stack([values["v0"], values["c0"][:, :3]]),
                                variant.params.get("tolerance", RELATIVE_TOLERANCE))
        if bad > variant.params["flips"]:
            report.append(f"{variant.name}: {bad} of {len(ours)} points differ (worst {worst:.3g})")
    assert not report, "\n".join(report)


def test_white_noise_is_bit_exact(cycles_values):
    """Hashes of the inputs' bit patterns: every value equals Cycles' float32 exactly."""
    for variant, values in zip(CASES, cycles_values):
        if variant.name.startswith("white_noise"):
            ours = evaluate(variant, values["i"], values["j"])
            assert np.array_equal(ours[:, 0].astype(np.float32), values["v0"]), variant.name
            assert np.array_equal(ours[:, 1:].astype(np.float32), values["c0"][:, :3]), variant.name


def lookup3_final_with(rotations):
    """hash.h `final` with the given seven rotations, uncompiled."""
    mask, rot = hashes.MASK32, hashes.rot.py_func
    steps = (("c", "b"), ("a", "c"), ("b", "a"), ("c", "b"), ("a", "c"), ("b", "a"), ("c", "b"))

    def final(a, b, c):
        state = {"a": a, "b": b, "c": c}
        for rotation, (target, source) in zip(rotations, steps):
            state[target] = (state[target] ^ state[source]) & mask
            state[target] = (state[target] - rot(state[source], rotation)) & mask
        return state["a"], state["b"], state["c"]

    return final


@pytest.mark.parametrize("rotations, agrees", [((14, 11, 25, 16, 4, 14, 24), True),
                                               ((13, 11, 25, 16, 4, 14, 24), False)])
def test_planted_hash_rotation_error_is_caught(cycles_values, monkeypatch, rotations, agrees):
    """White Noise 3D through an uncompiled lookup3 `final`: Cycles' rotations reproduce Cycles
    bit for bit (the control), the first rotation 14 -> 13 disagrees almost everywhere."""
    for name in ("hash_uint3", "uint_to_float_incl", "float32_bits"):
        monkeypatch.setattr(hashes, name, getattr(hashes, name).py_func)
    monkeypatch.setattr(hashes, "lookup3_final", lookup3_final_with(rotations))
    variant, values = next((v, r) for v, r in zip(CASES, cycles_values) if v.name == "white_noise_3d")
    ours = evaluate(variant, values["i"], values["j"], lambda x, y, z, w: hashes.hash_float3_to_float.py_func(x, y, z))
    bad, _ = mismatches(ours, values["v0"])
    if agrees:
        assert bad == 0
    else:
        assert bad > 0.9 * len(ours)
