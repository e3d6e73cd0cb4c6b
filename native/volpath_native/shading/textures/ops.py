"""Texture-node opcodes (100-199 of program.py) and their execution.

run_texture_op(op, code, at, regs, tables) executes one texture instruction whose operands start at
code[at]; program.py documents the operand conventions. Each opcode is registered with
program.define(name, code, *operands) at import.
"""
from __future__ import annotations

from ..program import define  # noqa: F401
from ...jit import inline_stage_kernel


@inline_stage_kernel
def run_texture_op(op, code, at, regs, tables):
    """Execute texture opcode `op` (no texture opcodes are defined yet)."""
    return None
