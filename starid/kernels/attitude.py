"""Wahba's problem in numba (the twin of :func:`starid.attitude.solve_wahba`)."""

from __future__ import annotations

import numpy as np

from .jit import inner, kernel
from .lapack import TRANS, det3_lapack, gemm3, svd3


@inner   # kernels call it only
def _det3(M):
    """Determinant of a 3x3 matrix."""
    return (M[0, 0] * (M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1])
            - M[0, 1] * (M[1, 0] * M[2, 2] - M[1, 2] * M[2, 0])
            + M[0, 2] * (M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]))


@inner   # kernels call it only
def identity3():
    """``np.eye(3)``, written out: numba's ``np.eye`` compiles its own overload (with ``min`` and its
    ``None`` handler, ~0.2 CPU s cold), which no kernel needs otherwise; the attitude of "no answer"."""
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = 1.0 if i == j else 0.0
    return A


@kernel
def wahba_rows(v, rows, unit):
    """ICRS -> camera rotation from the stars with ``rows >= 0`` (Wahba's problem, equal weights).

    ``v[i]`` is the camera-frame unit vector of star ``i`` and ``unit[rows[i]]`` its catalog
    (ICRS) unit vector; the numba twin of :func:`starid.attitude.solve_wahba`.

    The optimum is the orthogonal polar factor of ``B = sum b r^T`` when ``det B > 0`` (the SVD
    solution of Markley 1988 without the sign flip); it is found by Newton's iteration
    ``X <- (X + X^-T) / 2`` (quadratic convergence, a few 3x3 steps, much cheaper than a LAPACK
    SVD call). When ``det B <= 0`` (degenerate or mirrored data) the SVD solution is used.
    """
    B = np.zeros((3, 3))
    for i in range(v.shape[0]):
        if rows[i] < 0:
            continue
        for a in range(3):
            for b in range(3):
                B[a, b] += v[i, a] * float(unit[rows[i], b])
    det = _det3(B)
    big = 0.0   # max |B|, a loop: np.abs(B).max() compiles numpy's reduction machinery (~0.5 CPU s)
    for a in range(3):
        for b in range(3):
            big = max(big, abs(B[a, b]))
    if not det > 1e-12 * (big ** 3 + 1e-300):
        # numba's U, _, Vt = np.linalg.svd(B); U[:, 2] *= det U det Vt; U @ Vt, as the same LAPACK / BLAS
        # calls (starid.kernels.lapack: numba's generic linalg overloads cost ~2 CPU s to compile)
        u, vt = svd3(B)                   # U = u.T, Vt = vt.T
        d = det3_lapack(u) * det3_lapack(vt)
        for a in range(3):
            u[2, a] *= d
        out = np.empty((3, 3))
        gemm3(TRANS, TRANS, 3, vt, u, out)
        return out
    X = B / abs(det) ** (1.0 / 3.0)
    for _ in range(50):
        d = _det3(X)
        # inverse transpose = cofactor matrix / det
        C = np.empty((3, 3))
        C[0, 0] = X[1, 1] * X[2, 2] - X[1, 2] * X[2, 1]
        C[0, 1] = X[1, 2] * X[2, 0] - X[1, 0] * X[2, 2]
        C[0, 2] = X[1, 0] * X[2, 1] - X[1, 1] * X[2, 0]
        C[1, 0] = X[0, 2] * X[2, 1] - X[0, 1] * X[2, 2]
        C[1, 1] = X[0, 0] * X[2, 2] - X[0, 2] * X[2, 0]
        C[1, 2] = X[0, 1] * X[2, 0] - X[0, 0] * X[2, 1]
        C[2, 0] = X[0, 1] * X[1, 2] - X[0, 2] * X[1, 1]
        C[2, 1] = X[0, 2] * X[1, 0] - X[0, 0] * X[1, 2]
        C[2, 2] = X[0, 0] * X[1, 1] - X[0, 1] * X[1, 0]
        change = 0.0
        for a in range(3):
            for b in range(3):
                new = 0.5 * (X[a, b] + C[a, b] / d)
                change = max(change, abs(new - X[a, b]))
                X[a, b] = new
        if change < 1e-14:
            break
    return X


@inner   # kernels call it only
def guide_rows_f64(rows, guide_unit, idx, cat):
    """Fill ``idx`` (row i or -1) and ``cat`` (float64 guide vectors) so that ``wahba_rows(v, idx, cat)``
    is ``wahba_rows(v, rows, guide_unit)``: the signature :func:`starid.kernels.refine_explained` compiles,
    so numba compiles ``wahba_rows`` (and its SVD) once, not also for float32 ``guide_unit``. The same sums
    in the same order (float32 -> float64 is exact): the same attitude to the last bit."""
    for i in range(rows.shape[0]):
        idx[i] = -1
        if rows[i] >= 0:
            idx[i] = i
            for a in range(3):
                cat[i, a] = guide_unit[rows[i], a]
