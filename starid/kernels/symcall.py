"""Shared kernels called through a registered symbol instead of linked into every caller.

numba links each callee's finished LLVM module into its caller's module and optimises and emits the
whole again (``numba/core/codegen.py``, ``CPUCodeLibrary.finalize``), so a core kernel called by many
plugin kernels (:func:`starid.kernels.wahba_rows`, ...) is optimised once for itself and once more
inside every kernel above it, on every cold cache. A kernel exported here is compiled once per process
as a C function (``numba.cfunc(sig, cache=True)``: arrays go in as pointers and sizes and are rebuilt
inside with ``numba.carray``), its address registered with LLVM under a ``starid_`` symbol at import
(``llvmlite.binding.add_symbol``) and declared to callers as a :class:`numba.types.ExternalFunction`,
the way :mod:`starid.kernels.lapack` calls scipy's LAPACK: a caller's code refers to the symbol by
name, so it is cached, and the name is bound again when a new process imports this package. A call
through a symbol cannot be inlined, so only large callees pay (``benchmarks/tools/symcall_census.py``
estimates which).
"""

from __future__ import annotations

import llvmlite.binding as llvm
from numba import cfunc, types
from numba.core.errors import TypingError

_P = types.voidptr


def _abi(t):
    """The caller's view of a cfunc argument: every pointer is a ``void*`` (``arr.ctypes``)."""
    return _P if isinstance(t, types.CPointer) else t


def export(symbol: str, sig, func):
    """Compile ``func`` as ``cfunc(sig, cache=True)``, register its address as ``symbol`` and return the
    :class:`numba.types.ExternalFunction` kernels call it by (pointer arguments as ``voidptr``)."""
    compiled = cfunc(sig, cache=True)(func)
    llvm.add_symbol(symbol, compiled.address)
    return types.ExternalFunction(symbol, sig.return_type(*[_abi(a) for a in sig.args]))


def require_c(what: str, *arrays):
    """At typing time: every array C-contiguous (its ``.ctypes`` pointer is then the whole array)."""
    for a in arrays:
        if not isinstance(a, types.Array) or a.layout != "C":
            raise TypingError(f"{what}: needs C-contiguous arrays, got {a}")


def require_dtype(what: str, array, dtype: str):
    """At typing time: ``array`` holds ``dtype`` (an exported C function takes no other)."""
    if str(array.dtype) != dtype:
        raise TypingError(f"{what}: needs {dtype} here, got {array}")
