"""End to end through the add-on: Blender texture nodes compiled by shader_nodes_textures into a
shader program, run by the interpreter at points, against Cycles' render of the same nodes.

The node compiler's host (addon/export/shader_compiler.py, the lead's) is stood in for by
StandInCompiler: its linked vector input is the point P itself and unlinked inputs are their
default values, which is what the oracle's materials feed the nodes."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("bpy")

from cycles_oracle import Variant, link_input, point_inputs, render_variants, set_input  # noqa: E402
from oracle_compare import mismatches  # noqa: E402

from addon.export.shader_nodes_textures import TEXTURE_NODE_COMPILERS  # noqa: E402
from volpath_native.shading import program as P  # noqa: E402
from volpath_native.shading.builder import ProgramBuilder  # noqa: E402
from volpath_native.shading.interpreter import run_program_many  # noqa: E402
from volpath_native.shading.images import empty_image_table  # noqa: E402


class StandInCompiler:
    """The slice of ShaderCompiler the texture compile functions use."""

    def __init__(self):
        self.builder = ProgramBuilder("stand-in")
        self.warnings = []

    def alloc(self, n=1):
        return self.builder.alloc(n)

    def const(self, value):
        return self.builder.const(value)

    def emit(self, name, *operands):
        self.builder.emit(name, *operands)

    def table(self, values):
        return self.builder.table(values)

    def warn(self, node, message):
        self.warnings.append(f"{node.name}: {message}")

    def _socket(self, node, key):
        return next(s for s in node.inputs if s.identifier == key or s.name == key)

    def float_input(self, node, key):
        socket = self._socket(node, key)
        assert not socket.is_linked, f"{key} is linked: the stand-in only links the vector"
        return self.const(float(socket.default_value))

    def vector_input(self, node, key):
        socket = self._socket(node, key)
        return P.R_P if socket.is_linked else self.const(list(socket.default_value))

    color_input = vector_input

    def texture_vector(self, node, key="Vector"):
        assert self._socket(node, key).is_linked
        return P.R_P


def node_case(name, bl_idname, settings, inputs, outputs, coord_offset=(0.1, 0.2, 0.3, 0.4),
              coord_scale=(0.25, 0.25, 0.125, 0.1875)):
    """outputs: {aov: output identifier}."""
    def build(nodes, links, vector, w):
        node = nodes.new(bl_idname)
        node.name = name
        for attribute, value in settings.items():
            setattr(node, attribute, value)
        for socket, value in inputs.items():
            set_input(node, socket, value)
        link_input(links, node, "Vector", vector)
        sockets = {s.identifier: s for s in node.outputs}
        return {aov: sockets[identifier] for aov, identifier in outputs.items()}

    return Variant(name, build, coord_scale, coord_offset, dict(outputs=outputs))


CASES = [
    node_case("noise_4d", "ShaderNodeTexNoise", dict(noise_dimensions="4D", noise_type="HYBRID_MULTIFRACTAL"),
              {"W": 0.37, "Detail": 3.5, "Offset": 0.8, "Gain": 1.5, "Distortion": 0.4},
              {"v0": "Fac", "c0": "Color"}),
    node_case("noise_3d_fac_only", "ShaderNodeTexNoise", {}, {"Detail": 2.5}, {"v0": "Fac"}),
    node_case("voronoi_3d_f2", "ShaderNodeTexVoronoi", dict(feature="F2", distance="MANHATTAN"),
              {"Detail": 1.5, "Randomness": 0.8}, {"v0": "Distance", "c0": "Color", "c1": "Position"}),
    node_case("voronoi_4d_radius", "ShaderNodeTexVoronoi", dict(voronoi_dimensions="4D", feature="N_SPHERE_RADIUS"),
              {"W": -1.25}, {"v0": "Radius"}),
    node_case("voronoi_4d_smooth", "ShaderNodeTexVoronoi", dict(voronoi_dimensions="4D", feature="SMOOTH_F1"),
              {"W": 0.6, "Smoothness": 0.6}, {"v0": "Distance", "v1": "W", "c0": "Color"}),
    node_case("gradient_radial", "ShaderNodeTexGradient", dict(gradient_type="RADIAL"), {},
              {"v0": "Fac", "c0": "Color"}, coord_offset=(-2.0, -2.0, 0.0, 0.0)),
    node_case("wave_rings", "ShaderNodeTexWave", dict(wave_type="RINGS", rings_direction="Y", wave_profile="SIN"),
              {"Distortion": 1.5, "Detail": 3.0}, {"v0": "Fac", "c0": "Color"},
              # the wave's float32 argument n = 20 |p| scale: keep it small enough for 2e-5
              coord_scale=(0.05, 0.05, 0.025, 0.05)),
    node_case("magic_3", "ShaderNodeTexMagic", dict(turbulence_depth=3), {"Distortion": 1.7},
              {"v0": "Fac", "c0": "Color"}),
    node_case("white_noise_4d", "ShaderNodeTexWhiteNoise", dict(noise_dimensions="4D"), {"W": 0.5},
              {"v0": "Value", "c0": "Color"}),
]


@pytest.fixture(scope="module")
def rendered():
    import bpy

    values = render_variants(CASES)
    nodes = {}
    for index, variant in enumerate(CASES):
        tree = bpy.data.materials[f"oracle_{index}"].node_tree
        nodes[variant.name] = tree.nodes[variant.name]
    return values, nodes


def test_compiled_textures_match_cycles(rendered):
    values, nodes = rendered
    report = []
    for variant, cycles in zip(CASES, values):
        node = nodes[variant.name]
        compiler = StandInCompiler()
        registers = TEXTURE_NODE_COMPILERS[node.type](compiler, node)
        assert not compiler.warnings
        program = compiler.builder.build()
        x, y, z, _ = point_inputs(variant, cycles["i"], cycles["j"])
        points = np.column_stack([x, y, z]).astype(np.float64)
        for aov, identifier in variant.params["outputs"].items():
            width = 3 if aov.startswith("c") else 1
            out = np.zeros((len(points), width))
            run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                             np.zeros((2, 3, 4)), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)), points, out,
                             registers[identifier], width, empty_image_table())
            expected = cycles[aov][:, :width] if width == 3 else cycles[aov]
            bad, worst = mismatches(out, expected)
            if bad:
                report.append(f"{variant.name}.{identifier}: {bad} of {len(points)} differ (worst {worst:.3g})")
    assert not report, "\n".join(report)


def test_unlinked_color_is_skipped(rendered):
    """Noise with only Fac linked compiles with color# = 0 (Cycles skips the colour noises)."""
    _, nodes = rendered
    compiler = StandInCompiler()
    TEXTURE_NODE_COMPILERS["TEX_NOISE"](compiler, nodes["noise_3d_fac_only"])
    code = compiler.builder.build().code
    assert code[0] == P.OPS["TEX_NOISE"].code and code[1 + 3] == 0
