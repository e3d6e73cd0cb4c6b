"""Whole materials through the add-on's ShaderCompiler against Cycles (cycles_oracle renders them).

Each variant's plane material is compiled as VolPath compiles a material: the AOV Output nodes'
inputs are compiled by ShaderCompiler (addon/export/shader_compiler.py) with the socket
conversions of their input type, and the program is run by the interpreter at the pixel centres
with the plane object's frame (world -> object, object -> Generated). The node inputs in the
materials are built from the pixel's cell (i, j) through Texture Coordinate -> Separate XYZ ->
Math nodes, so the compiled program reproduces that chain too (Generated coordinates included).

Node inputs are dyadic numbers (i * 0.25 - 2, ...) so float32 (Cycles) and float64 (VolPath)
agree exactly on them and on every discontinuity (floor, compare, snap, modulo) they reach.
"""
from __future__ import annotations

import numpy as np

from cycles_oracle import BLOCK, render_variants  # noqa: F401  (re-exported for the tests)

VALUE_AOVS = tuple(f"v{k}" for k in range(8))
COLOR_AOVS = tuple(f"c{k}" for k in range(6))
#: float32 (Cycles, SSE order) vs float64 (VolPath) on the same float32 inputs: relative to
#: max(1, |value|) per element
RELATIVE_TOLERANCE = 2e-5


class CollectingReporter:
    def __init__(self):
        self.warnings = []

    def warn(self, message):
        self.warnings.append(message)


def frame_of(obj) -> np.ndarray:
    """The (2, 3, 4) frame ShaderProgram evaluation needs: world -> object, object -> Generated."""
    from addon.export.procedural_media import generated_transform

    world = np.array(obj.matrix_world, dtype=np.float64)
    vertices = np.array([v.co[:] for v in obj.data.vertices], dtype=np.float64)
    frame = np.zeros((2, 3, 4))
    frame[0] = np.linalg.inv(world)[:3]
    frame[1] = generated_transform(obj, vertices)
    return frame


def compile_aovs(material):
    """(program, {aov name: (register, width)}, warnings) of a material's AOV Output nodes."""
    from addon.export.shader_compiler import ShaderCompiler

    reporter = CollectingReporter()
    compiler = ShaderCompiler(f"material '{material.name}'", reporter)
    registers = {}
    for node in material.node_tree.nodes:
        if node.type != "OUTPUT_AOV" or not node.aov_name or node.aov_name == "ij":
            continue
        if node.aov_name.startswith("c"):
            registers[node.aov_name] = (compiler.color_input(node, "Color"), 3)
        else:
            registers[node.aov_name] = (compiler.float_input(node, "Value"), 1)
    return compiler.builder.build(), registers, reporter.warnings


def evaluate(program, frame, points, register, width) -> np.ndarray:
    from volpath_native.shading.images import empty_image_table
    from volpath_native.shading.interpreter import run_program_many

    out = np.zeros((len(points), width))
    run_program_many(program.code, program.init, program.tables, np.zeros(program.n_registers),
                     np.ascontiguousarray(frame), np.zeros((1, 1, 1, 1), np.float32), np.zeros((3, 4)),
                     np.ascontiguousarray(points, dtype=np.float64), out, register, width, empty_image_table())
    return out


def disagreements(ours, cycles, tolerance=RELATIVE_TOLERANCE, absolute=0.0):
    """(count of elements that differ, the worst difference, an example) between ours (float64,
    compared after rounding to float32 as Cycles stores it) and Cycles' float32 values. Equal
    infinities and NaN against NaN agree."""
    with np.errstate(over="ignore"):  # beyond float32: inf, as Cycles' float32 arithmetic
        ours32 = np.asarray(ours, np.float64).astype(np.float32).astype(np.float64).reshape(len(ours), -1)
    cycles = np.asarray(cycles, np.float64).reshape(len(cycles), -1)
    same = (ours32 == cycles) | (np.isnan(ours32) & np.isnan(cycles))
    with np.errstate(invalid="ignore"):
        diff = np.where(same, 0.0, np.abs(ours32 - cycles))
    diff[np.isnan(diff)] = np.inf
    bound = np.maximum(tolerance * np.maximum(1.0, np.abs(np.nan_to_num(cycles, posinf=0, neginf=0))), absolute)
    bad = diff > bound
    if not bad.any():
        return 0, float(diff.max()) if diff.size else 0.0, None
    k = np.argwhere(bad)[0]
    return int(bad.any(axis=1).sum()), float(diff.max()), (int(k[0]), ours32[k[0]].tolist(), cycles[k[0]].tolist())


def check_variant(variant, index, cycles, tolerance=RELATIVE_TOLERANCE, absolute=0.0, mutate=None):
    """Compile variant `index`'s material and compare every AOV; returns a list of failure lines
    (empty: it agrees) and the warnings of the compile. mutate(program), if given, plants an
    error in the compiled program first (the comparison must then fail)."""
    import bpy

    material = bpy.data.materials[f"oracle_{index}"]
    obj = bpy.data.objects[f"oracle_{index}"]
    program, registers, warnings = compile_aovs(material)
    if mutate is not None:
        mutate(program)
    frame = frame_of(obj)
    points = cycles["pixel_world"]
    failures = []
    for aov, (register, width) in registers.items():
        ours = evaluate(program, frame, points, register, width)
        expected = cycles[aov] if width == 3 else cycles[aov].reshape(-1, 1)
        tol = variant.params.get("tolerance", {}).get(aov, tolerance)
        atol = variant.params.get("absolute", {}).get(aov, absolute)
        bad, worst, example = disagreements(ours, expected, tol, atol)
        if bad:
            label = variant.params.get("labels", {}).get(aov, aov)
            failures.append(f"{variant.name}.{label}: {bad} of {len(points)} pixels differ (worst {worst:.3g}; "
                            f"pixel {example[0]} i={cycles['i'][example[0]]} j={cycles['j'][example[0]]}: "
                            f"ours {example[1]} Cycles {example[2]})")
    return failures, warnings


def check_positions(results):
    """The pixel-centre positions agree with the (i, j) cells of the untouched planes."""
    for index, entry in enumerate(results):
        local = entry["pixel_world"][:, :2] - np.array([index % 8, -(index // 8)])
        cells = np.floor(local * BLOCK)
        if not (np.array_equal(cells[:, 0], entry["i"]) and np.array_equal(cells[:, 1], entry["j"])):
            return index
    return None


# ---------------------------------------------------------------------------------------------
# Building blocks for variants
# ---------------------------------------------------------------------------------------------
def split(nodes, links, vector):
    """x, y, z float sockets of the oracle's input vector."""
    sep = nodes.new("ShaderNodeSeparateXYZ")
    links.new(vector, sep.inputs[0])
    return sep.outputs[0], sep.outputs[1], sep.outputs[2]


def connect(links, socket, value):
    """Link a socket to value (an output socket) or set its default value."""
    if hasattr(value, "links") and hasattr(value, "node"):
        links.new(value, socket)
    elif isinstance(value, (tuple, list)):
        socket.default_value = tuple(value) if len(socket.default_value) == len(value) else tuple(value) + (1.0,)
    else:
        socket.default_value = value


def combine(nodes, links, x, y, z):
    node = nodes.new("ShaderNodeCombineXYZ")
    for k, value in enumerate((x, y, z)):
        connect(links, node.inputs[k], value)
    return node.outputs[0]


def math(nodes, links, operation, a, b=0.0, c=0.0, use_clamp=False):
    node = nodes.new("ShaderNodeMath")
    node.operation = operation
    node.use_clamp = use_clamp
    for k, value in enumerate((a, b, c)):
        connect(links, node.inputs[k], value)
    return node.outputs[0]


def by_identifier(sockets, identifier):
    for socket in sockets:
        if socket.identifier == identifier:
            return socket
    raise KeyError(identifier)


def replace_operand(program, opcode_name, operand, old, new):
    """Planted error: every `opcode_name` instruction whose literal `operand` is old gets new
    (e.g. a Math node's operation or a Mix node's blend mode). Returns how many changed."""
    from volpath_native.shading.program import OPERAND_COUNT, OPS

    spec = OPS[opcode_name]
    k = spec.operands.index(operand)
    changed, pc = 0, 0
    while pc < len(program.code):
        op = int(program.code[pc])
        if op == spec.code and program.code[pc + 1 + k] == old:
            program.code[pc + 1 + k] = new
            changed += 1
        pc += 1 + int(OPERAND_COUNT[op])
    return changed
