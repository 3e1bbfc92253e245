""":mod:`starid.kernels.lapack` gives numba's ``np.linalg.svd`` / ``det`` / ``@`` / ``np.dot`` results to the
last bit, on the 3x3 problems the Wahba kernels solve: well-conditioned, rank-deficient (two stars),
mirrored (``det < 0``) and exactly singular matrices, and on ``k x 3`` star matrices for ``b.T @ r``."""

import numpy as np
import pytest
from numba import njit

from starid.kernels.lapack import NOTRANS, TRANS, det3_lapack, dot3, gemm3, svd3


@njit(cache=False)
def _numba_linalg(B, b, r, At):
    """What the kernels computed before, with numba's generic overloads."""
    M = b.T @ r
    U, _, Vt = np.linalg.svd(B)
    d = np.linalg.det(U) * np.linalg.det(Vt)
    D = np.zeros((3, 3))
    D[0, 0] = 1.0
    D[1, 1] = 1.0
    D[2, 2] = d
    A = U @ D @ Vt
    R = A @ At
    for a in range(3):
        U[a, 2] *= d
    W = U @ Vt
    s = R[0].copy()
    return M, U, Vt, A, R, W, np.dot(s, s), d


@njit(cache=False)
def _direct(B, b, r, At):
    """The same through :mod:`starid.kernels.lapack`."""
    M = np.empty((3, 3))
    gemm3(NOTRANS, TRANS, b.shape[0], r, b, M)
    u, vt = svd3(B)
    d = det3_lapack(u) * det3_lapack(vt)
    D = np.zeros((3, 3))
    D[0, 0] = 1.0
    D[1, 1] = 1.0
    D[2, 2] = d
    UD = np.empty((3, 3))
    gemm3(NOTRANS, TRANS, 3, D, u, UD)
    A = np.empty((3, 3))
    gemm3(TRANS, NOTRANS, 3, vt, UD, A)
    R = np.empty((3, 3))
    gemm3(NOTRANS, NOTRANS, 3, At, A, R)
    for a in range(3):
        u[2, a] *= d
    W = np.empty((3, 3))
    gemm3(TRANS, TRANS, 3, vt, u, W)
    s = R[0].copy()
    return M, u.T.copy(), vt.T.copy(), A, R, W, dot3(s, s), d


def _cases(n):
    rng = np.random.default_rng(20261205)
    for t in range(n):
        kind = t % 5
        if kind == 0:
            B = rng.normal(size=(3, 3))
        elif kind == 1:                               # two stars: rank 2
            B = rng.normal(size=(3, 2)) @ rng.normal(size=(2, 3))
        elif kind == 2:                               # mirrored
            B = -np.linalg.qr(rng.normal(size=(3, 3)))[0] * rng.uniform(0.1, 3.0, 3)
        elif kind == 3:                               # rank 1
            B = np.outer(rng.normal(size=3), rng.normal(size=3))
        else:                                         # near-rotation, as identified stars give
            q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
            B = q + 1e-6 * rng.normal(size=(3, 3))
        k = int(rng.integers(2, 14))
        b, r = rng.normal(size=(k, 3)), rng.normal(size=(k, 3))
        At = np.ascontiguousarray(np.linalg.qr(rng.normal(size=(3, 3)))[0].T)
        yield np.ascontiguousarray(B), b, r, At


def test_direct_calls_match_numba_linalg_bit_for_bit():
    for B, b, r, At in _cases(3000):
        for x, y in zip(_numba_linalg(B, b, r, At), _direct(B, b, r, At), strict=True):
            assert np.array_equal(np.asarray(x), np.asarray(y)), (B, b, r)


@njit(cache=False)
def _gemm(transa, transb, k, a, b):
    c = np.empty((3, 3))
    gemm3(transa, transb, k, a, b, c)
    return c


@njit(cache=False)
def _svd_det(B):
    u, vt = svd3(B)
    return u, vt, det3_lapack(u), det3_lapack(vt), det3_lapack(np.zeros((3, 3)))


def test_transpose_flags_matter():
    """The comparison above can fail: the wrong flag for ``b.T @ r`` gives another product."""
    B, b, r, At = next(_cases(1))
    np.testing.assert_array_equal(_gemm(NOTRANS, TRANS, b.shape[0], r, b), b.T @ r)
    b3, r3 = b[:3].copy(), r[:3].copy()
    assert not np.allclose(_gemm(NOTRANS, NOTRANS, 3, r3, b3), b3.T @ r3)


def test_singular_and_non_finite():
    u, vt, det_u, det_vt, det_zero = _svd_det(np.zeros((3, 3)))
    assert det_zero == 0.0
    assert abs(abs(det_u) - 1.0) < 1e-12 and abs(abs(det_vt) - 1.0) < 1e-12
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        _svd_det(np.full((3, 3), np.nan))
