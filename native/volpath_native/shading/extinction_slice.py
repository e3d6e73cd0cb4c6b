"""The part of a volume program that a medium's extinction and emission need, without what only
feeds a Principled Volume's Color.

Trackers read a medium at every tentative collision, and most collisions need only sigma_t and the
emission: the Color input (a Noise Texture's colour output costs two more fBms) matters there only
through the extinction, sigma_t = density x (c + max(1 - c, 0) x (1 - sqrt(absorption))) (C5
svm/closure.h svm_node_principled_volume), which with a black Absorption Color is density x
max(c, 1). extinction_program() compiles a copy of the program in which that Color reads 0 -- its
sigma_t is the density, its emission exact -- and every instruction left feeding nothing is dropped
(a Noise Texture whose Color output is then unread keeps its Fac only: color# 0). Wherever c <= 1 the
two programs agree on sigma_t; elsewhere the difference (full - reduced) is what a caller must add,
e.g. by Russian roulette on the full program, which keeps its estimate unbiased.

Liveness runs backward over the straight-line code: closure instructions are the roots, an
instruction is kept when a register it writes is read later by a kept one.
"""
from __future__ import annotations

import numpy as np

from .program import OPS, ShaderProgram

# closure instructions: they accumulate into the fixed output registers (no 'out' operands)
_CLOSURES = {"PRINCIPLED_VOLUME", "VOLUME_SCATTER", "VOLUME_ABSORPTION", "VOLUME_EMISSION", "VOLUME_COEFFICIENTS"}
# instructions with a colour flag that skips work when their colour output is unread
_COLOUR_FLAGS = {"TEX_NOISE": "color#", "TEX_WHITE_NOISE": "color#"}
# surface-only instructions (bump copies swap registers): no slicing
_UNSLICEABLE = {"SWAP", "BUMP"}


def _decode(program: ShaderProgram):
    """[(pc, name, {operand name: value})] of the program's instructions."""
    by_code = {spec.code: (name, spec) for name, spec in OPS.items()}
    out, pc, code = [], 0, program.code
    while pc < len(code):
        name, spec = by_code[int(code[pc])]
        values = {operand: int(code[pc + 1 + k]) for k, operand in enumerate(spec.operands)}
        out.append((pc, name, values))
        pc += 1 + len(spec.operands)
    return out


def _registers(operand: str, value: int, values: dict) -> range:
    width = 12 if operand.endswith("12") else 3 if operand.endswith("3") else 1
    if operand in ("src", "dst"):  # COPY: count# registers
        width = values["count#"]
    return range(value, value + width)


def _reads_writes(name: str, values: dict):
    reads, writes = set(), set()
    for operand, value in values.items():
        if operand.endswith("#"):
            continue
        registers = _registers(operand, value, values)
        (writes if operand.startswith("out") or operand == "dst" else reads).update(registers)
    return reads, writes


def _colour_free(values: dict, program: ShaderProgram, written: set) -> bool:
    """A Principled Volume whose Absorption Color is the constant black: its extinction reads the
    Color only as max(c, 1)."""
    absorption = range(values["absorption3"], values["absorption3"] + 3)
    return not any(r in written for r in absorption) and all(program.init[r] == 0.0 for r in absorption)


def _slice(decoded, program: ShaderProgram, written: set, redirect: bool):
    """(kept instructions as (name, operands), colour flags cleared, Colors redirected) of a backward
    liveness pass, with or without the Principled Volumes' Colors read as 0."""
    zero = program.n_registers  # three registers appended, holding 0: the redirected Color
    live, kept, cleared, redirected = set(), [], 0, 0
    for pc, name, values in reversed(decoded):
        reads, writes = _reads_writes(name, values)
        if name in _CLOSURES:
            values = dict(values)
            if redirect and name == "PRINCIPLED_VOLUME" and _colour_free(values, program, written):
                reads -= set(range(values["color3"], values["color3"] + 3))
                values["color3"] = zero
                redirected += 1
            kept.append((name, values))
            live |= reads
            continue
        if not writes & live:
            continue
        values = dict(values)
        flag = _COLOUR_FLAGS.get(name)
        if flag and values[flag] and not set(range(values["out_color3"], values["out_color3"] + 3)) & live:
            values[flag] = 0
            cleared += 1
        kept.append((name, values))
        live = (live - writes) | reads
    return kept[::-1], cleared, redirected


def extinction_program(program: ShaderProgram):
    """The reduced program (module docstring), or None when reading the Colors as 0 would save
    nothing (no Principled Volume with a black Absorption Color, or a constant Color)."""
    decoded = _decode(program)
    if any(name in _UNSLICEABLE for _, name, _ in decoded):
        return None
    written = set()
    for _, name, values in decoded:
        written |= _reads_writes(name, values)[1]
    kept, cleared, redirected = _slice(decoded, program, written, True)
    baseline, baseline_cleared, _ = _slice(decoded, program, written, False)
    if not redirected or (len(kept) == len(baseline) and cleared == baseline_cleared):
        return None
    code = []
    for name, values in kept:
        code.append(OPS[name].code)
        code.extend(values[operand] for operand in OPS[name].operands)
    reduced = ShaderProgram(program.name + " (extinction)", np.array(code, np.int32),
                            np.concatenate([program.init, np.zeros(3)]), program.tables, varying=program.varying,
                            attributes=list(program.attributes))
    reduced.validate()
    return reduced
