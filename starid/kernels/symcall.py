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

Costs: ``import starid.kernels`` compiles the exported functions on an empty cache (~5 CPU s, all dtypes,
whether the process needs them or not) and loads them from the cache otherwise (~0.03 s); each call
passes pointers (the arrays must be C-contiguous: the shims check at typing time). The symbol names carry
a hash of the C signature: numba does not recompile a cached caller when a callee in another file
changes, and a stale caller must then fail to find its symbol rather than call one with other arguments
(clear the cache after changing an exported signature).
"""

from __future__ import annotations

import hashlib

import llvmlite.binding as llvm
from numba import cfunc, types
from numba.core.errors import TypingError

_P = types.voidptr


def _abi(t):
    """The caller's view of a cfunc argument: every pointer is a ``void*`` (``arr.ctypes``)."""
    return _P if isinstance(t, types.CPointer) else t


def export(symbol: str, sig, func):
    """Compile ``func`` as ``cfunc(sig, cache=True)``, register its address as ``symbol`` plus a hash of
    ``sig`` and return the :class:`numba.types.ExternalFunction` kernels call it by (pointer arguments as
    ``voidptr``). The hash: numba does not recompile a cached caller when a callee in another file
    changes, so a caller cached against another signature must find no symbol, not the wrong one."""
    compiled = cfunc(sig, cache=True)(func)
    name = f"{symbol}_{hashlib.sha1(str(sig).encode()).hexdigest()[:10]}"
    llvm.add_symbol(name, compiled.address)
    return types.ExternalFunction(name, sig.return_type(*[_abi(a) for a in sig.args]))


def require_c(what: str, *arrays):
    """At typing time: every array C-contiguous (its ``.ctypes`` pointer is then the whole array)."""
    for a in arrays:
        if not isinstance(a, types.Array) or a.layout != "C":
            raise TypingError(f"{what}: needs C-contiguous arrays, got {a}")


def require_dtype(what: str, array, dtype: str):
    """At typing time: ``array`` holds ``dtype`` (an exported C function takes no other)."""
    if str(array.dtype) != dtype:
        raise TypingError(f"{what}: needs {dtype} here, got {array}")
