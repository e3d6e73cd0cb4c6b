"""The eight lattice corners of a 3D (or one w-slice of a 4D) Perlin cell in one pass: lookup3 hash
and gradient dot product of all corners as 8-lane vector code (Cycles src/kernel/svm/noise.h
`perlin_3d` / `perlin_4d`, whose SSE/AVX2 paths also hash the corners together).

The scalar code hashed the corners one by one (hash ~45 % of a Perlin evaluation) and numba did not
vectorise it; here an @intrinsic writes the LLVM vector operations directly. The integer arithmetic
is lookup3's (util/hash.h `final`, `mix`) on 32-bit lanes and the gradient selects and sign flips
are exact, so the values are bit-identical to the scalar `hash_uint3`/`grad3` (tests/shading/
test_perlin_corners.py). Called from plain Python (the uncompiled planted-error tests) the same
functions run the scalar code.
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

from .hash import MASK32, hash_uint3, hash_uint4

LANES = 8
_I32 = ir.IntType(32)
_I64 = ir.IntType(64)
_F32 = ir.FloatType()
_F64 = ir.DoubleType()
_VI32 = ir.VectorType(_I32, LANES)
_VF32 = ir.VectorType(_F32, LANES)
_VF64 = ir.VectorType(_F64, LANES)

# util/hash.h: (rotated-into, xor-with, rotation) per line of `final` and `mix`
_FINAL_STEPS = (("c", "b", 14), ("a", "c", 11), ("b", "a", 25), ("c", "b", 16), ("a", "c", 4), ("b", "a", 14),
                ("c", "b", 24))
_MIX_STEPS = (("a", "c", 4, "c", "b"), ("b", "a", 6, "a", "c"), ("c", "b", 8, "b", "a"),
              ("a", "c", 16, "c", "b"), ("b", "a", 19, "a", "c"), ("c", "b", 4, "b", "a"))


def _splat_i32(value):
    return ir.Constant(_VI32, [value & MASK32] * LANES)


def _rot(builder, x, k):
    return builder.or_(builder.shl(x, _splat_i32(k)), builder.lshr(x, _splat_i32(32 - k)))


def _final(builder, state):
    """hash.h `final`: c ^= b; c -= rot(b, 14); ..."""
    for target, source, k in _FINAL_STEPS:
        mixed = builder.xor(state[target], state[source])
        state[target] = builder.sub(mixed, _rot(builder, state[source], k))
    return state


def _mix(builder, state):
    """hash.h `mix`: a -= c; a ^= rot(c, 4); c += b; ..."""
    for target, source, k, added_to, addend in _MIX_STEPS:
        state[target] = builder.sub(state[target], state[source])
        state[target] = builder.xor(state[target], _rot(builder, state[source], k))
        state[added_to] = builder.add(state[added_to], state[addend])
    return state


def _lanes(builder, vector_type, per_lane):
    vec = ir.Constant(vector_type, ir.Undefined)
    for i, value in enumerate(per_lane):
        vec = builder.insert_element(vec, value, ir.Constant(_I32, i))
    return vec


def _corner_keys(builder, lattice_pairs, init):
    """init + (lattice coordinate of each corner) per axis: corner i takes the axis' second value
    where bit `axis` of i is set (noise.h's corner order: x fastest, then y, then z)."""
    keys = []
    for axis, (low, high) in enumerate(lattice_pairs):
        low32, high32 = builder.trunc(low, _I32), builder.trunc(high, _I32)
        vec = _lanes(builder, _VI32, [high32 if (i >> axis) & 1 else low32 for i in range(LANES)])
        keys.append(builder.add(vec, _splat_i32(init)))
    return keys


def _corner_offsets(builder, frac, axis, scalar=_F64, vector=_VF64):
    """The corner's offset along an axis: frac, or frac - 1 at the cell's far side."""
    far = builder.fsub(frac, ir.Constant(scalar, 1.0))
    return _lanes(builder, vector, [far if (i >> axis) & 1 else frac for i in range(LANES)])


def _negate_where(builder, h, bit, x):
    flagged = builder.icmp_unsigned("!=", builder.and_(h, _splat_i32(bit)), _splat_i32(0))
    return builder.select(flagged, builder.fneg(x), x)


def _to_tuple(context, builder, tuple_type, vec):
    out = context.get_constant_undef(tuple_type)
    for i in range(LANES):
        out = builder.insert_value(out, builder.extract_element(vec, ir.Constant(_I32, i)), i)
    return out


_GRADIENTS = types.UniTuple(types.float64, LANES)


@intrinsic
def _corner_gradients_3d_x8(typingctx, X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    sig = _GRADIENTS(types.int64, types.int64, types.int64, types.int64, types.int64, types.int64,
                     types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        x, y, z = (_corner_offsets(builder, args[6 + axis], axis) for axis in range(3))
        g = _grad3_lanes(builder, _corner_hashes_3d(builder, args), x, y, z)
        return _to_tuple(context, builder, signature.return_type, g)

    return sig, codegen


def _corner_hashes_3d(builder, args):
    """hash_uint3 of the 8 corners (args: X0, X1, Y0, Y1, Z0, Z1, ...), masked to grad3's 4 bits."""
    init = 0xDEADBEEF + (3 << 2) + 13  # hash.h hash_uint3
    a, b, c = _corner_keys(builder, ((args[0], args[1]), (args[2], args[3]), (args[4], args[5])), init)
    return builder.and_(_final(builder, {"a": a, "b": b, "c": c})["c"], _splat_i32(15))


def _grad3_lanes(builder, h, x, y, z):
    """noise.h grad3 on 8 lanes: u = h < 8 ? x : y; vt = (h == 12 || h == 14) ? x : z;
    v = h < 4 ? y : vt; (h & 1 ? -u : u) + (h & 2 ? -v : v)."""
    lt = lambda k: builder.icmp_unsigned("<", h, _splat_i32(k))  # noqa: E731
    eq = lambda k: builder.icmp_unsigned("==", h, _splat_i32(k))  # noqa: E731
    u = builder.select(lt(8), x, y)
    v = builder.select(lt(4), y, builder.select(builder.or_(eq(12), eq(14)), x, z))
    return builder.fadd(_negate_where(builder, h, 1, u), _negate_where(builder, h, 2, v))


def _fade32(builder, t):
    """noise.h fade in float32: (t * t * t) * (t * (t * 6 - 15) + 10)."""
    c = lambda v: ir.Constant(_F32, v)  # noqa: E731
    cube = builder.fmul(builder.fmul(t, t), t)
    return builder.fmul(cube, builder.fadd(builder.fmul(t, builder.fsub(builder.fmul(t, c(6.0)), c(15.0))), c(10.0)))


def _mix_lanes(builder, g, count, t):
    """mix(a, b, t) = a + t (b - a) of the lane pairs (2i, 2i + 1) of g (count lanes -> count / 2)."""
    even = builder.shuffle_vector(g, g, ir.Constant(ir.VectorType(_I32, count // 2), list(range(0, count, 2))))
    odd = builder.shuffle_vector(g, g, ir.Constant(ir.VectorType(_I32, count // 2), list(range(1, count, 2))))
    splat = _lanes(builder, ir.VectorType(_F32, count // 2), [t] * (count // 2))
    return builder.fadd(even, builder.fmul(splat, builder.fsub(odd, even)))


@intrinsic
def _perlin_cell_3d_x8(typingctx, X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    """perlin_3d of one lattice cell in float32 as Cycles' SSE path computes it (noise.h
    `perlin_3d`, `grad`, `tri_mix`: mix along x, then y, then z): the 8 corners' hashes and
    gradients and the three mixes as vector code."""
    sig = types.float32(types.int64, types.int64, types.int64, types.int64, types.int64, types.int64,
                        types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        x, y, z = (_corner_offsets(builder, args[6 + axis], axis, _F32, _VF32) for axis in range(3))
        g = _grad3_lanes(builder, _corner_hashes_3d(builder, args), x, y, z)
        u, v, w = (_fade32(builder, args[6 + axis]) for axis in range(3))
        along_y = _mix_lanes(builder, _mix_lanes(builder, g, 8, u), 4, v)
        z0 = builder.extract_element(along_y, ir.Constant(_I32, 0))
        z1 = builder.extract_element(along_y, ir.Constant(_I32, 1))
        return builder.fadd(z0, builder.fmul(w, builder.fsub(z1, z0)))

    return sig, codegen


@intrinsic
def _corner_gradients_4d_x8(typingctx, X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw):
    sig = _GRADIENTS(types.int64, types.int64, types.int64, types.int64, types.int64, types.int64, types.int64,
                     types.float64, types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        init = 0xDEADBEEF + (4 << 2) + 13  # hash.h hash_uint4: mix after x, y, z; w joins a; final
        a, b, c = _corner_keys(builder, ((args[0], args[1]), (args[2], args[3]), (args[4], args[5])), init)
        state = _mix(builder, {"a": a, "b": b, "c": c})
        w_key = _lanes(builder, _VI32, [builder.trunc(args[6], _I32)] * LANES)
        state["a"] = builder.add(state["a"], w_key)
        h = builder.and_(_final(builder, state)["c"], _splat_i32(31))
        x, y, z = (_corner_offsets(builder, args[7 + axis], axis) for axis in range(3))
        w = _lanes(builder, _VF64, [args[10]] * LANES)
        lt = lambda k: builder.icmp_unsigned("<", h, _splat_i32(k))  # noqa: E731
        # noise.h grad4: u = h < 24 ? x : y; v = h < 16 ? y : z; s = h < 8 ? z : w
        u, v, s = builder.select(lt(24), x, y), builder.select(lt(16), y, z), builder.select(lt(8), z, w)
        g = builder.fadd(builder.fadd(_negate_where(builder, h, 1, u), _negate_where(builder, h, 2, v)),
                         _negate_where(builder, h, 4, s))
        return _to_tuple(context, builder, signature.return_type, g)

    return sig, codegen


def _corners(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz, one=1.0):
    """(X, Y, Z, offsets) of the 8 corners, x fastest then y then z (uncompiled)."""
    for i in range(LANES):
        offsets = (fx - one if i & 1 else fx), (fy - one if i & 2 else fy), (fz - one if i & 4 else fz)
        yield (X1 if i & 1 else X0), (Y1 if i & 2 else Y0), (Z1 if i & 4 else Z0), offsets


def corner_gradients_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    """grad3(hash_uint3(corner), offsets) of the 8 corners (uncompiled)."""
    from .perlin import grad3
    return tuple(grad3.py_func(hash_uint3.py_func(X, Y, Z), *offsets)
                 for X, Y, Z, offsets in _corners(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz))


def corner_gradients_4d(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw):
    """grad4(hash_uint4(corner, W), offsets) of the 8 corners of one w-slice (uncompiled)."""
    from .perlin import grad4
    return tuple(grad4.py_func(hash_uint4.py_func(X, Y, Z, W), *offsets, fw)
                 for X, Y, Z, offsets in _corners(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz))


@overload(corner_gradients_3d, jit_options={"cache": True})
def _compiled_corner_gradients_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    def impl(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
        return _corner_gradients_3d_x8(X0, X1, Y0, Y1, Z0, Z1, float(fx), float(fy), float(fz))
    return impl


@overload(corner_gradients_4d, jit_options={"cache": True})
def _compiled_corner_gradients_4d(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw):
    def impl(X0, X1, Y0, Y1, Z0, Z1, W, fx, fy, fz, fw):
        return _corner_gradients_4d_x8(X0, X1, Y0, Y1, Z0, Z1, W, float(fx), float(fy), float(fz), float(fw))
    return impl


def _fade32_scalar(t):
    t = np.float32(t)
    return (t * t * t) * (t * (t * np.float32(6.0) - np.float32(15.0)) + np.float32(10.0))


def perlin_cell_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    """perlin_3d of one lattice cell, float32 (uncompiled; the operations of the compiled vector
    code in its order -- float64 arithmetic on float32 values rounded back is float32 arithmetic for
    + - *, as 53 >= 2 x 24 + 2 bits -- so the two agree bit for bit)."""
    from .perlin import grad3
    f32 = np.float32
    fx, fy, fz = f32(fx), f32(fy), f32(fz)
    g = [f32(grad3.py_func(hash_uint3.py_func(X, Y, Z), *offsets))
         for X, Y, Z, offsets in _corners(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz, one=f32(1.0))]
    u, v, w = _fade32_scalar(fx), _fade32_scalar(fy), _fade32_scalar(fz)
    along_x = [g[2 * i] + u * (g[2 * i + 1] - g[2 * i]) for i in range(4)]
    along_y = [along_x[2 * i] + v * (along_x[2 * i + 1] - along_x[2 * i]) for i in range(2)]
    return along_y[0] + w * (along_y[1] - along_y[0])


@overload(perlin_cell_3d, jit_options={"cache": True})
def _compiled_perlin_cell_3d(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
    def impl(X0, X1, Y0, Y1, Z0, Z1, fx, fy, fz):
        return _perlin_cell_3d_x8(X0, X1, Y0, Y1, Z0, Z1, np.float32(fx), np.float32(fy), np.float32(fz))
    return impl
