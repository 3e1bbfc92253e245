"""``starid.kernels.attitude.svd3`` and ``lu_det3`` against numba's ``np.linalg.svd`` / ``np.linalg.det``
(what ``wahba_rows`` and ``attitude_error_terms`` called before): the same LAPACK calls on the same data,
so the same bits. Random 3x3 matrices, full-rank, rank 2, rank 1, with zero rows, near -I; and the
errors for non-finite input.

    python benchmarks/tools/compilecut_lapack_check.py [N]

Prints the number of matrices compared and of differing bits (0 expected), and exits 1 on a difference.
"""

from __future__ import annotations

import sys

import numpy as np
from numba import njit

from starid.kernels.attitude import lu_det3, svd3


@njit
def _numba_linalg(B):
    U, _, Vt = np.linalg.svd(B)
    return U.copy(), Vt.copy(), np.linalg.det(U), np.linalg.det(Vt), np.linalg.det(np.asfortranarray(B))


@njit
def _direct(B):
    U, Vt = svd3(B)
    return U.copy(), Vt.copy(), lu_det3(U), lu_det3(Vt), lu_det3(np.asfortranarray(B))


def _matrix(rng, t):
    k = t % 5
    if k == 0:
        return rng.normal(size=(3, 3))
    if k == 1:
        return rng.normal(size=(2, 3)).T @ rng.normal(size=(2, 3))         # rank 2 (two stars)
    if k == 2:
        return np.outer(rng.normal(size=3), rng.normal(size=3))            # rank 1
    if k == 3:
        B = np.round(rng.normal(size=(3, 3)), 1)
        B[rng.integers(0, 3)] = 0.0
        return B
    return -np.eye(3) + 1e-9 * rng.normal(size=(3, 3))                     # mirrored


def main(n: int) -> int:
    rng = np.random.default_rng(0)
    bad = 0
    for t in range(n):
        B = np.ascontiguousarray(_matrix(rng, t))
        for x, y in zip(_numba_linalg(B), _direct(B), strict=True):
            if np.asarray(x).tobytes() != np.asarray(y).tobytes():
                bad += 1
                print("differs:", B.tolist(), x, y)
                break
    for B in (np.full((3, 3), np.nan), np.array([[np.inf, 0, 0], [0, 1, 0], [0, 0, 1.0]])):
        errors = []
        for f in (_numba_linalg, _direct):
            try:
                f(B)
                errors.append(None)
            except Exception as e:   # noqa: BLE001 -- the exception itself is compared
                errors.append((type(e).__name__, str(e)))
        if errors[0] != errors[1]:
            bad += 1
            print("errors differ:", errors)
    print(f"{n} matrices, {bad} differing")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000))
