"""The kernels' one-signature policy (jit.py, _get_call_template): a kernel called from a kernel
compiles once per parameter kind, not once per literal value or integer/float width its callers
happen to pass -- each extra signature recompiled the callee and everything it calls."""
import types

import numba
import numpy as np
import pytest
from numba import types as nt

import volpath_native  # noqa: F401  (installs the policy)
from volpath_native import jit

_PROBE = '''
import numba

@numba.njit
def callee(a, b):
    return a + b

@numba.njit
def caller(n, narrow_int, narrow_float):
    total = 0                      # Literal[int](0) until the loop's phi is typed
    for i in range(n):
        total = callee(total, 3)   # a constant argument: Literal[int](3)
    return total + callee(narrow_int, 2) + callee(narrow_float, 1.5)
'''


def _probe(module_name):
    module = types.ModuleType(module_name)
    exec(compile(_PROBE, f"<{module_name}>", "exec"), module.__dict__)
    assert module.caller(3, np.int32(4), np.float32(0.5)) == 9 + 6 + 2.0
    return module.callee.signatures


@pytest.mark.parametrize("given, expected", [
    (nt.literal(0), nt.int64), (nt.int32, nt.int64), (nt.int8, nt.int64),
    (nt.float32, nt.float32),  # textures compute in float32 as Cycles does
    (nt.literal(True), nt.boolean), (nt.uint64, nt.uint64), (nt.float64, nt.float64),
    (nt.Array(nt.float32, 2, "C"), nt.Array(nt.float32, 2, "C")),
    (nt.UniTuple(nt.float64, 3), nt.UniTuple(nt.float64, 3)),
])
def test_widened_scalar(given, expected):
    assert jit.widened_scalar(given) == expected


def test_a_kernel_called_from_kernels_compiles_once_per_parameter_kind():
    signatures = _probe(jit._OUR_MODULES + "_signature_probe")
    assert len(signatures) == 2, signatures  # one per parameter kind: ints, and float32 + float64
    assert set(signatures) == {(nt.int64, nt.int64), (nt.float32, nt.float64)}


def test_functions_outside_the_package_keep_numbas_behaviour():
    # the planted contrast: numba alone compiles the transient literal and narrow signatures too
    signatures = _probe("not_volpath_signature_probe")
    assert len(signatures) > 2, signatures
