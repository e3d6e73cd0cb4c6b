"""ProgramBuilder: registers, constants, tables and instructions of one ShaderProgram.

The add-on's node compiler (addon/export/shader_compiler.py) drives it node by node; tests build
programs with it directly. It tracks which registers depend on the shading point, so a program
whose outputs do not is known to be constant (a homogeneous medium, evaluated once).
"""
from __future__ import annotations

import numpy as np

from .program import OPS, R_FIRST_FREE, R_I, R_N, R_P, R_UV, ShaderProgram

# Opcodes whose result depends on the point even when every operand is constant.
_POINT_SOURCES = {"TEXCO", "ATTRIBUTE"}


class ProgramBuilder:
    def __init__(self, name: str):
        self.name = name
        self.init: list[float] = [0.0] * R_FIRST_FREE
        self.code: list[int] = []
        self.tables: list[float] = []
        self._varying: set[int] = set(range(R_P, R_P + 3)) | set(range(R_N, R_N + 3)) | \
            set(range(R_I, R_I + 3)) | set(range(R_UV, R_UV + 3))
        self._constants: dict = {}
        self.varying_outputs = False  # a closure op read a varying register
        self.attributes: list[str] = []

    # ------------------------------------------------------------------------------------------
    def alloc(self, n: int = 1) -> int:
        reg = len(self.init)
        self.init.extend([0.0] * n)
        return reg

    def const(self, value) -> int:
        """A register (or 3 for a triple) holding a constant; equal constants share registers."""
        values = np.atleast_1d(np.asarray(value, dtype=np.float64)).reshape(-1)
        key = tuple(float(v) for v in values)
        if key not in self._constants:
            reg = self.alloc(len(key))
            self.init[reg:reg + len(key)] = list(key)
            self._constants[key] = reg
        return self._constants[key]

    def table(self, values) -> int:
        """Offset of `values` (flattened float64) in the program's lookup tables."""
        offset = len(self.tables)
        self.tables.extend(float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1))
        return offset

    def is_varying(self, reg: int, width: int = 1) -> bool:
        return any(r in self._varying for r in range(reg, reg + width))

    def emit(self, name: str, *operands: int):
        """Append one instruction; operands as program.OPS[name] lists them."""
        spec = OPS[name]
        if len(operands) != len(spec.operands):
            raise ValueError(f"{name} takes {len(spec.operands)} operands ({', '.join(spec.operands)}), "
                             f"got {len(operands)}")
        varying = name in _POINT_SOURCES
        outputs = []
        for operand_name, value in zip(spec.operands, operands):
            if operand_name.endswith("#"):
                continue
            width = 12 if operand_name.endswith("12") else 3 if operand_name.endswith("3") else 1
            if operand_name.startswith("out"):
                outputs.append((value, width))
            elif self.is_varying(int(value), width):
                varying = True
        if varying:
            for reg, width in outputs:
                self._varying.update(range(reg, reg + width))
            if not outputs:  # closures write the fixed output registers
                self.varying_outputs = True
        self.code.append(spec.code)
        self.code.extend(int(v) for v in operands)

    def attribute_channel(self, name: str, width: int) -> int:
        """Channel offset of a grid attribute in the medium's attribute array (assigned in order of
        first use; the medium stacks its grids in this order)."""
        offset = 0
        for existing, existing_width in self.attributes:
            if existing == name:
                return offset
            offset += existing_width
        self.attributes.append((name, width))
        return offset

    def build(self) -> ShaderProgram:
        program = ShaderProgram(self.name, np.array(self.code, dtype=np.int32), np.array(self.init),
                                np.array(self.tables) if self.tables else np.zeros(1),
                                varying=self.varying_outputs, attributes=list(self.attributes))
        program.validate()
        return program
