"""Prefetch hints: ask the CPU for a cache line a kernel will read soon, without waiting for it.

A kernel whose reads each wait for the one before (a k-vector, then its values, then an index, then
rows of a table) pays a memory latency per link when its database is not in cache -- as in the
benchmark, where every plugin's call follows thirteen others'. Computing the next addresses first and
prefetching them lets those loads overlap. :func:`prefetch` and :func:`prefetch_at` emit LLVM's
``llvm.prefetch`` (read, keep in every cache level, data): no load, no fault, no value changes, only
when a later load finds its line. The index need not be valid for the hint itself, but callers keep it
inside the array (an address outside it is still only a hint, yet meaningless).
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


def _emit(context, builder, aryty, ary_value, indices):
    """``llvm.prefetch`` of the address ``data + sum(index * stride)`` of the given leading indices."""
    ary = context.make_array(aryty)(context, builder, ary_value)
    strides = cgutils.unpack_tuple(builder, ary.strides, aryty.ndim)
    addr = builder.ptrtoint(ary.data, strides[0].type)
    for k, (value, ty) in enumerate(indices):
        index = context.cast(builder, value, ty, types.intp)
        addr = builder.add(addr, builder.mul(index, strides[k]))
    i8p = ir.IntType(8).as_pointer()
    i32 = ir.IntType(32)
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                                        "llvm.prefetch")
    builder.call(fn, [builder.inttoptr(addr, i8p), i32(0), i32(3), i32(1)])   # read, keep, data cache


@intrinsic
def prefetch(typingctx, arr, i):
    """Prefetch ``arr[i]``: the element of a 1-D array, the start of row ``i`` of an n-D one."""
    if not isinstance(arr, types.Array) or not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        _emit(context, builder, sig.args[0], args[0], [(args[1], sig.args[1])])
        return context.get_dummy_value()
    return types.void(arr, i), codegen


@intrinsic
def prefetch_at(typingctx, arr, i, j):
    """Prefetch ``arr[i, j]`` of an array of two or more dimensions."""
    if not isinstance(arr, types.Array) or arr.ndim < 2 or not isinstance(i, types.Integer) \
            or not isinstance(j, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        _emit(context, builder, sig.args[0], args[0], [(args[1], sig.args[1]), (args[2], sig.args[2])])
        return context.get_dummy_value()
    return types.void(arr, i, j), codegen
