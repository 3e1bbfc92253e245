"""3x3 SVD, determinants and matrix products for the Wahba kernels, straight from scipy's BLAS / LAPACK.

numba's ``np.linalg.svd``, ``np.linalg.det`` and ``@`` call the same Fortran routines (scipy's
``cython_lapack.dgesdd`` / ``dgetrf`` and ``cython_blas.dgemm`` / ``ddot``), but each use compiles
numba's generic overloads for every array layout, with their checks and copies: ~3 CPU s of a cold
compile in every process that scores trials, and the SVD again inside every kernel that links
:func:`starid.kernels.wahba_rows`. These kernels make the same calls with the same arguments (the
same ``jobz``, the same optimal ``lwork`` from the workspace query, the same transposes and leading
dimensions numba derives from the layouts), so they give the same numbers to the last bit
(``tests/test_lapack_kernels.py`` compares them with numba's and numpy's on random, rank-deficient and
mirrored matrices).

The routines are reached through scipy's documented ``__pyx_capi__`` function pointers
(:func:`numba.extending.get_cython_function_address`), registered with LLVM under our own symbol names
(``llvmlite.binding.add_symbol``) and declared as :class:`numba.types.ExternalFunction`: a compiled
kernel refers to them by name, so it can be cached, and the names are bound again at import.
Every argument is a pointer (the Fortran convention); all matrices here are 3x3, stored as numba
lays them out (a C array ``u`` holding the Fortran-ordered ``U = u.T``).
"""

from __future__ import annotations

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

from .jit import inner

_P = types.voidptr


def _bind(module: str, name: str, restype, n_args: int):
    """An ExternalFunction for scipy's ``module.name``, whose arguments are all pointers."""
    symbol = f"starid_{name}"
    llvm.add_symbol(symbol, get_cython_function_address(f"scipy.linalg.{module}", name))
    return types.ExternalFunction(symbol, restype(*([_P] * n_args)))


#: dgemm(transa, transb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc)
_dgemm = _bind("cython_blas", "dgemm", types.void, 13)
#: ddot(n, x, incx, y, incy) -> double
_ddot = _bind("cython_blas", "ddot", types.float64, 5)
#: dgesdd(jobz, m, n, a, lda, s, u, ldu, vt, ldvt, work, lwork, iwork, info)
_dgesdd = _bind("cython_lapack", "dgesdd", types.void, 14)
#: dgetrf(m, n, a, lda, ipiv, info)
_dgetrf = _bind("cython_lapack", "dgetrf", types.void, 6)

#: dgemm's transpose flags
NOTRANS, TRANS = ord("n"), ord("t")
_A = ord("A")


# one explicit signature: the transpose flags are constants at every call, and numba would otherwise compile
# one specialisation per combination of literal arguments
@njit("void(int64, int64, int64, float64[:, ::1], float64[:, ::1], float64[:, ::1])", cache=True,
      no_cpython_wrapper=True, no_cfunc_wrapper=True)   # kernels call it only
def gemm3(transa, transb, k, a, b, c):
    """``dgemm(transa, transb, 3, 3, k, 1, a, 3, b, 3, 0, c, 3)``: the call numba makes for a
    product of two 3-wide matrices into a C-ordered 3x3 ``c`` (``a`` is the right-hand operand's
    memory, ``b`` the left-hand one's; ``'n'`` where an operand's layout is the output's, ``'t'``
    otherwise; every leading dimension is 3 here)."""
    chars = np.empty(2, dtype=np.uint8)
    chars[0] = transa
    chars[1] = transb
    ints = np.empty(3, dtype=np.int32)
    ints[0] = 3
    ints[1] = k
    ints[2] = 3
    scal = np.empty(2)
    scal[0] = 1.0
    scal[1] = 0.0
    _dgemm(chars[0:].ctypes, chars[1:].ctypes, ints[0:].ctypes, ints[0:].ctypes, ints[1:].ctypes,
           scal[0:].ctypes, a.ctypes, ints[2:].ctypes, b.ctypes, ints[2:].ctypes, scal[1:].ctypes, c.ctypes,
           ints[2:].ctypes)


@inner   # kernels call it only
def dot3(x, y):
    """``np.dot(x, y)`` of two contiguous 3-vectors as numba computes it (``ddot``, unit strides)."""
    ints = np.empty(2, dtype=np.int32)
    ints[0] = x.shape[0]
    ints[1] = 1
    return _ddot(ints[0:].ctypes, x.ctypes, ints[1:].ctypes, y.ctypes, ints[1:].ctypes)


@inner   # kernels call it only
def svd3(B):
    """``(u, vt)`` with ``U, _, Vt = np.linalg.svd(B)`` being ``U = u.T``, ``Vt = vt.T``, exactly as
    numba computes them: ``B`` (C-ordered 3x3) copied to Fortran order, ``dgesdd`` with ``jobz='A'``
    and the ``lwork`` its workspace query returns. Raises like numba's for non-finite ``B`` or no
    convergence."""
    for a in range(3):
        for b in range(3):
            if not np.isfinite(B[a, b]):
                raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
    acpy = np.empty((3, 3))        # Fortran order of B: acpy[j, i] = B[i, j]
    for a in range(3):
        for b in range(3):
            acpy[b, a] = B[a, b]
    u = np.empty((3, 3))
    vt = np.empty((3, 3))
    s = np.empty(3)
    ints = np.empty(3, dtype=np.int32)   # m = n = ld = 3, lwork, info
    ints[0] = 3
    ints[1] = -1
    ints[2] = 0
    jobz = np.empty(1, dtype=np.uint8)
    jobz[0] = _A
    query = np.empty(1)
    iwork = np.empty(24, dtype=np.int32)   # 8 min(m, n)
    _dgesdd(jobz.ctypes, ints[0:].ctypes, ints[0:].ctypes, acpy.ctypes, ints[0:].ctypes, s.ctypes, u.ctypes,
            ints[0:].ctypes, vt.ctypes, ints[0:].ctypes, query.ctypes, ints[1:].ctypes, iwork.ctypes,
            ints[2:].ctypes)
    ints[1] = np.int32(query[0])     # numba's cast_from_X: (F_INT) of the double
    work = np.empty(max(ints[1], 1))
    _dgesdd(jobz.ctypes, ints[0:].ctypes, ints[0:].ctypes, acpy.ctypes, ints[0:].ctypes, s.ctypes, u.ctypes,
            ints[0:].ctypes, vt.ctypes, ints[0:].ctypes, work.ctypes, ints[1:].ctypes, iwork.ctypes,
            ints[2:].ctypes)
    if ints[2] > 0:
        raise ValueError("Internal algorithm failed to converge.")
    return u, vt


@inner   # kernels call it only
def det3_lapack(m):
    """``np.linalg.det(m.T)`` for a C-ordered 3x3 ``m`` (``m.T`` being the Fortran-ordered matrix
    :func:`svd3` returns as ``u`` or ``vt``), as numba computes it: ``dgetrf`` on a copy, the
    permutation's sign, then ``sign * exp(sum log |diagonal|)``."""
    acpy = m.copy()
    ipiv = np.empty(3, dtype=np.int32)
    ints = np.empty(2, dtype=np.int32)   # m = n = lda = 3, info
    ints[0] = 3
    ints[1] = 0
    _dgetrf(ints[0:].ctypes, ints[0:].ctypes, acpy.ctypes, ints[0:].ctypes, ipiv.ctypes, ints[1:].ctypes)
    if ints[1] > 0:
        return 0.0 * np.exp(-np.inf)
    sgn = 1
    for k in range(3):
        sgn = sgn + (ipiv[k] != (k + 1))
    sgn = sgn & 1
    if sgn == 0:
        sgn = -1
    acc = 0.0
    for k in range(3):
        v = acpy[k, k]
        if v < 0.0:
            sgn = -sgn
            v = -v
        acc = acc + np.log(v)
    return (sgn + 0.0) * np.exp(acc)
