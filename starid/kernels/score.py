"""The harness's per-image checks and scoring in numba: one compiled call each instead of ~15 numpy calls.

Twins of :func:`starid.plugin.check_identification` (its array part),
:func:`starid.scoring.attitude_from_ids` and :func:`starid.scoring.attitude_error_arcsec`, written
to give the same numbers to the last bit: the same LAPACK SVD and determinants, the same matrix
products (both BLAS ``dgemm``; here called directly, :mod:`starid.kernels.lapack`, as numba's ``@`` calls
it), the same atan2 form of the angle, numpy's ``arctan2`` (``tests/test_score_kernels.py`` compares them
on random and degenerate inputs). They exist for
speed alone: at ~50 us of numpy overhead per image they were a third of the harness's time
around ``identify`` (docs/performance.md, "Stop 38").
"""

from __future__ import annotations

import numpy as np

from .jit import kernel
from .lapack import NOTRANS, TRANS, det3_lapack, dot3, gemm3, svd3
from .order import search_left, sort_int_prefix

#: :func:`check_ids` codes
IDS_OK, ID_NOT_IN_CATALOG, ID_TWICE = 0, 1, 2


@kernel
def check_ids(hip, catalog_hip):
    """``(code, id)``: ``(IDS_OK, 0)`` when every id is -1 or in the sorted ``catalog_hip`` and no id
    is given twice; ``(ID_NOT_IN_CATALOG, id)`` for the first (in star order) id that is neither;
    ``(ID_TWICE, id)`` for the smallest id given to more than one star."""
    n_cat = catalog_hip.shape[0]
    k = 0
    for i in range(hip.shape[0]):
        h = hip[i]
        if h == -1:
            continue
        k += 1
        pos = search_left(catalog_hip, h)
        if pos >= n_cat:
            pos = n_cat - 1
        if n_cat == 0 or catalog_hip[pos] != h:
            return ID_NOT_IN_CATALOG, h
    if k < 2:
        return IDS_OK, 0
    reported = np.empty(k, dtype=np.int64)
    k = 0
    for i in range(hip.shape[0]):
        if hip[i] != -1:
            reported[k] = hip[i]
            k += 1
    # not reported.sort(): numpy's quicksort costs ~0.7 CPU s to compile; np.int64: k is typed
    # Literal[int](0) at one of its assignments, which compiled sort_int_prefix a second time
    sort_int_prefix(reported, np.int64(k))
    for i in range(1, k):
        if reported[i] == reported[i - 1]:
            return ID_TWICE, reported[i]
    return IDS_OK, 0


@kernel
def attitude_error_terms(hip, v_cam, catalog_hip, unit_icrs, attitude_true):
    """``(y, x)`` whose ``numpy.arctan2`` is the angle (rad) between the Wahba attitude of the identified
    stars (``hip != -1``, every id in the sorted ``catalog_hip``; rows of ``unit_icrs``) and
    ``attitude_true``; NaNs with fewer than two. The caller takes numpy's ``arctan2`` of them: numba's (libm's)
    differs from numpy's in the last bit for some angles, and numpy's is
    :func:`starid.attitude.rotation_angle_rad`'s.

    :func:`starid.attitude.solve_wahba` (``B = b^T r``, ``A = U diag(1, 1, det U det V) V^T``) and
    :func:`starid.attitude.rotation_angle_rad` (atan2 of the skew part's norm and ``(tr R - 1) / 2``)."""
    k = 0
    for i in range(hip.shape[0]):
        if hip[i] != -1:
            k += 1
    if k < 2:
        return np.nan, np.nan
    b = np.empty((k, 3))
    r = np.empty((k, 3))
    k = 0
    for i in range(hip.shape[0]):
        if hip[i] != -1:
            row = search_left(catalog_hip, hip[i])
            for a in range(3):
                b[k, a] = v_cam[i, a]
                r[k, a] = unit_icrs[row, a]
            k += 1
    # numba's b.T @ r, svd, det and @, made as the same BLAS / LAPACK calls (starid.kernels.lapack)
    B = np.empty((3, 3))
    gemm3(NOTRANS, TRANS, k, r, b, B)                 # B = b.T @ r
    u, vt = svd3(B)                           # U = u.T, Vt = vt.T
    d = det3_lapack(u) * det3_lapack(vt)
    D = np.zeros((3, 3))
    D[0, 0] = 1.0
    D[1, 1] = 1.0
    D[2, 2] = d
    UD = np.empty((3, 3))
    gemm3(NOTRANS, TRANS, 3, D, u, UD)                # U @ D
    A = np.empty((3, 3))
    gemm3(TRANS, NOTRANS, 3, vt, UD, A)               # (U @ D) @ Vt
    At = np.empty((3, 3))     # attitude_true.T, C-ordered (a loop: np.ascontiguousarray compiles its own impl)
    for a in range(3):
        for c in range(3):
            At[a, c] = attitude_true[c, a]
    R = np.empty((3, 3))
    gemm3(NOTRANS, NOTRANS, 3, At, A, R)                # A @ At
    skew = np.empty(3)        # not np.array([...]): a reflected list and its constructor to compile
    skew[0] = R[2, 1] - R[1, 2]
    skew[1] = R[0, 2] - R[2, 0]
    skew[2] = R[1, 0] - R[0, 1]
    trace = 0.0               # numba's np.trace: the diagonal summed in order from 0
    for a in range(3):
        trace += R[a, a]
    # numpy's norm of a vector is sqrt(x . x) (BLAS ddot); numba's np.linalg.norm is not, to the last bit
    return 0.5 * np.sqrt(dot3(skew, skew)), 0.5 * (trace - 1.0)


@kernel
def score_terms(hip, truth, catalog_hip, v_cam, unit_icrs, attitude_true):
    """``(n_identified, n_correct, y, x)`` of one image in one call: the ids that are not -1, those equal to
    ``truth`` (:func:`starid.scoring.score_trial`'s counts) and :func:`attitude_error_terms`. ``hip`` has passed
    :func:`check_ids`. The harness's row (``starid.harness.trial_row``) makes it its one compiled call."""
    n_identified = 0
    n_correct = 0
    for i in range(hip.shape[0]):
        if hip[i] != -1:
            n_identified += 1
            if hip[i] == truth[i]:
                n_correct += 1
    y, x = attitude_error_terms(hip, v_cam, catalog_hip, unit_icrs, attitude_true)
    return n_identified, n_correct, y, x
