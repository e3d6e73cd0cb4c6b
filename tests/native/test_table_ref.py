"""Tables passed by reference (table_ref): a callee reading fields through a TableRef sees exactly
what it would see in the NamedTuple itself -- every field, of every type, nested tables and tuples
of tables -- and a kernel's call no longer pushes the tables' flattened fields onto the stack.

Planted error: a reference that reads field i + 1 (an off-by-one in the field address) must fail
the field-by-field comparison."""
from collections import namedtuple

import numba
import numpy as np
import pytest
from llvmlite import ir
from numba.core.datamodel import models
from numba.core.errors import TypingError
from numba.core.imputils import impl_ret_borrowed, lower_getattr_generic
from numba.extending import intrinsic, register_model

from volpath_native import table_ref as tr
from volpath_native.table_ref import table_ref

Inner = namedtuple("Inner", "weights scale")
Tables = namedtuple("Tables", "flag rows offsets inner count epsilon")


def _tables(shift=0.0):
    return Tables(flag=True, rows=np.arange(12, dtype=np.int32).reshape(4, 3) + int(shift),
                  offsets=np.linspace(0.0, 1.0, 5) + shift, inner=Inner(np.array([0.25, 0.5, 0.75]) + shift, 3.0 + shift),
                  count=np.int64(7), epsilon=1e-4 + shift)


@numba.njit(cache=False)
def _read(t, i):
    """Every field once, through whatever t is (a table or a reference to one)."""
    return (t.flag, t.rows[i % 4, i % 3], t.offsets[i % 5], t.inner.weights[i % 3], t.inner.scale, t.count,
            t.epsilon)


@numba.njit(cache=False)
def _through_ref(t, i):
    return _read(table_ref(t), i)


@numba.njit(cache=False)
def _through_tuple_ref(tt, k, i):
    refs = table_ref(tt)
    return _read(refs[k], i)


@numba.njit(cache=False)
def _twice(t, i):
    return _read(table_ref(table_ref(t)), i)  # a reference passes through unchanged


def test_fields_read_through_a_reference_are_the_tables_fields():
    t = _tables()
    for i in range(12):
        assert _through_ref(t, i) == _read(t, i) == _twice(t, i)


def test_a_tuple_of_tables_becomes_a_tuple_of_references():
    tt = (_tables(), _tables(10.0))
    for k in range(2):
        for i in range(6):
            assert _through_tuple_ref(tt, k, i) == _read(tt[k], i)


def test_writes_through_a_reference_reach_the_tables_arrays():
    @numba.njit(cache=False)
    def write(t):
        r = table_ref(t)
        r.offsets[0] = 42.0
        r.inner.weights[2] = -1.0

    t = _tables()
    write(t)
    assert t.offsets[0] == 42.0 and t.inner.weights[2] == -1.0


def test_anything_but_attribute_access_is_a_typing_error():
    @numba.njit(cache=False)
    def index(t):
        return table_ref(t)[0]

    with pytest.raises(TypingError):
        index(_tables())


class ShiftedRef(tr.TableRef):
    """The planted error: a reference whose field address is off by one (same typing)."""

    def __init__(self, table_type):
        super().__init__(table_type)
        self.name = f"ShiftedRef({table_type})"


def test_planted_off_by_one_field_address_is_caught():
    """The comparison must fail for a reference that reads the neighbouring field."""
    register_model(ShiftedRef)(models.PointerModel)

    @lower_getattr_generic(ShiftedRef)
    def shifted_getattr(context, builder, ref_type, ref, attr):
        table_type = ref_type.table_type
        index = table_type.fields.index(attr)
        wrong = min(index + 1, len(table_type.fields) - 1)
        if table_type.types[wrong] != table_type.types[index]:
            wrong = index  # keep it compilable: shift only between fields of one type
        zero = ir.Constant(ir.IntType(32), 0)
        ptr = builder.gep(ref, [zero, ir.Constant(ir.IntType(32), wrong)], inbounds=True)
        field_type = table_type.types[index]
        value = context.data_model_manager[field_type].from_data(builder, builder.load(ptr))
        return impl_ret_borrowed(context, builder, field_type, value)

    Pair = namedtuple("Pair", "first second")

    @numba.njit(cache=False)
    def read_first(p):
        return p.first[0]

    @intrinsic
    def shifted_ref(typingctx, table):
        def codegen(context, builder, signature, args):
            return tr._store(context, builder, table, args[0])
        return ShiftedRef(table)(table), codegen

    @numba.njit(cache=False)
    def read_first_shifted(p):
        return read_first(shifted_ref(p))

    @numba.njit(cache=False)
    def read_first_ref(p):
        return read_first(table_ref(p))

    p = Pair(np.array([1.0]), np.array([2.0]))
    assert read_first_ref(p) == read_first(p) == 1.0
    assert read_first_shifted(p) != read_first(p)  # the planted error shows
