"""Attitudes: uniform random rotations and Wahba's problem.

An attitude ``A`` is a 3x3 rotation matrix mapping ICRS vectors to the camera frame.
"""

from __future__ import annotations

import numpy as np


def random_attitude(rng: np.random.Generator) -> np.ndarray:
    """A rotation drawn uniformly over SO(3) (Shoemake, Graphics Gems III, 1992)."""
    u1, u2, u3 = rng.random(3)
    a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
    x, y = a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2)
    z, w = b * np.sin(2 * np.pi * u3), b * np.cos(2 * np.pi * u3)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def solve_wahba(b_cam: np.ndarray, r_icrs: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Optimal attitude from matched unit vectors by SVD (Markley 1988).

    Minimises ``sum w_i |b_i - A r_i|^2`` with ``B = sum w_i b_i r_i^T = U S V^T`` and
    ``A = U diag(1, 1, det U det V) V^T``. Needs at least two non-parallel pairs.
    """
    b_cam = np.asarray(b_cam, dtype=np.float64).reshape(-1, 3)
    r_icrs = np.asarray(r_icrs, dtype=np.float64).reshape(-1, 3)
    w = np.ones(len(b_cam)) if weights is None else np.asarray(weights, dtype=np.float64)
    B = (b_cam * w[:, None]).T @ r_icrs
    U, _, Vt = np.linalg.svd(B)
    d = np.linalg.det(U) * np.linalg.det(Vt)
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def rotation_angle_rad(A_est: np.ndarray, A_true: np.ndarray) -> float:
    """Angle of the rotation ``A_est A_true^T``: ``arccos((tr - 1) / 2)``."""
    R = A_est @ A_true.T
    # atan2 form: accurate at small angles, unlike arccos of the trace.
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return float(np.arctan2(0.5 * np.linalg.norm(skew), 0.5 * (np.trace(R) - 1.0)))
