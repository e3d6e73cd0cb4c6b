"""Pass a kernel's tables to its callees by reference.

numba passes a NamedTuple argument by value, flattened: every array field becomes its meminfo,
parent, size, item size, data pointer, shape and strides, so a call that takes the closure scratch
and the materials' node tables pushes ~4 KB of arguments onto the stack (`shade` -> `_node_closures`:
`add $0xfc0, %rsp` after the call). Measured with perf on the bench rows, those stack copies were
15-50 % of the compiled code's time (sun through a window 31 %, glass of liquid 28 %, the coloured
absorber 53 %). A kernel wraps its tables once, `S = table_ref(S)`, and every callee then receives
one pointer and reads only the fields it uses; the tables do not change while a kernel runs.

A TableRef reads like its table (`S.epsilon`, `S.rows[i]`; a nested table is read as a reference
into it); anything else a NamedTuple allows (indexing, unpacking) is a typing error at compile
time, not a silent copy.
"""
from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.datamodel import models
from numba.core.imputils import impl_ret_borrowed, lower_getattr_generic
from numba.core.typing.templates import AttributeTemplate
from numba.extending import infer_getattr, intrinsic, register_model


class TableRef(types.Type):
    """A pointer to a NamedTuple of tables living in the frame of the kernel that made it."""

    def __init__(self, table_type):
        self.table_type = table_type
        super().__init__(name=f"TableRef({table_type})")

    @property
    def dtype(self):  # PointerModel's pointee
        return self.table_type


register_model(TableRef)(models.PointerModel)


def _field_type(field_type):
    return TableRef(field_type) if isinstance(field_type, types.BaseNamedTuple) else field_type


@infer_getattr
class _TableRefAttributes(AttributeTemplate):
    key = TableRef

    def generic_resolve(self, ref, attr):
        fields = ref.table_type.fields
        if attr in fields:
            return _field_type(ref.table_type.types[fields.index(attr)])
        return None


@lower_getattr_generic(TableRef)
def _table_ref_getattr(context, builder, ref_type, ref, attr):
    table_type = ref_type.table_type
    index = table_type.fields.index(attr)
    field_type = table_type.types[index]
    zero = ir.Constant(ir.IntType(32), 0)
    field_ptr = builder.gep(ref, [zero, ir.Constant(ir.IntType(32), index)], inbounds=True)
    if isinstance(field_type, types.BaseNamedTuple):  # a nested table: a reference into this one
        return field_ptr
    value = context.data_model_manager[field_type].from_data(builder, builder.load(field_ptr))
    return impl_ret_borrowed(context, builder, field_type, value)


@intrinsic
def table_ref(typingctx, table):
    """The tables by reference (a TableRef passes through unchanged; a tuple of tables becomes a
    tuple of references). The copy lives in the calling function's frame: use the reference only
    in that function and its callees."""
    if isinstance(table, TableRef):
        return table(table), lambda context, builder, signature, args: args[0]
    if isinstance(table, types.BaseNamedTuple):
        return TableRef(table)(table), lambda context, builder, signature, args: _store(context, builder, table,
                                                                                          args[0])
    if isinstance(table, types.UniTuple) and isinstance(table.dtype, types.BaseNamedTuple):  # e.g. the grid slots
        def codegen(context, builder, signature, args):
            refs = [_store(context, builder, table.dtype, builder.extract_value(args[0], i)) for i in range(table.count)]
            return context.make_tuple(builder, signature.return_type, refs)
        return types.UniTuple(TableRef(table.dtype), table.count)(table), codegen
    return None


def _store(context, builder, table_type, value):
    """A copy of `value` in the function's entry-block frame; its address."""
    model = context.data_model_manager[table_type]
    slot = cgutils.alloca_once(builder, model.get_data_type())
    builder.store(model.as_data(builder, value), slot)
    return slot
