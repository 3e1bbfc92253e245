import numpy as np
import pytest

from starid.attitude import random_attitude, rotation_angle_rad, solve_wahba


def test_random_attitudes_are_rotations():
    rng = np.random.default_rng(0)
    for _ in range(50):
        A = random_attitude(rng)
        assert np.allclose(A @ A.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(A) == pytest.approx(1.0)


def test_random_boresights_are_uniform_on_the_sphere():
    rng = np.random.default_rng(1)
    z = np.array([random_attitude(rng)[2] for _ in range(8000)])
    # uniform on the sphere: each coordinate is uniform on [-1, 1] (Archimedes)
    for k in range(3):
        counts, _ = np.histogram(z[:, k], bins=8, range=(-1, 1))
        chi2 = ((counts - 1000) ** 2 / 1000).sum()
        assert chi2 < 24.3          # chi-square, 7 dof, p = 0.001
    assert np.abs(z.mean(axis=0)).max() < 0.04


def test_wahba_recovers_rotation():
    rng = np.random.default_rng(2)
    A = random_attitude(rng)
    r = rng.normal(size=(5, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    b = r @ A.T
    assert rotation_angle_rad(solve_wahba(b, r), A) < 1e-9


def test_rotation_angle():
    t = 1e-5
    R = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    assert rotation_angle_rad(R, np.eye(3)) == pytest.approx(t, rel=1e-9)


def test_wahba_solvers_agree_with_scipy_align_vectors():
    """scipy's Rotation.align_vectors as the oracle for both Wahba solvers, on noisy vectors."""
    from scipy.spatial.transform import Rotation

    from starid.kernels import wahba_rows

    rng = np.random.default_rng(5)
    for _ in range(20):
        A = random_attitude(rng)
        r = rng.normal(size=(8, 3))
        r /= np.linalg.norm(r, axis=1, keepdims=True)
        b = r @ A.T + rng.normal(scale=1e-3, size=(8, 3))
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        oracle = Rotation.align_vectors(b, r)[0].as_matrix()
        assert rotation_angle_rad(solve_wahba(b, r), oracle) < 1e-9
        assert rotation_angle_rad(wahba_rows(b, np.arange(8), r), oracle) < 1e-9
