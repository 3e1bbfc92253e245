"""Fixtures shared by every test folder: tests/, each plugin's algorithms/<name>/tests/, benchmarks/."""

import pytest

from starid import Camera, load_hipparcos


@pytest.fixture(scope="session")
def catalog():
    return load_hipparcos()


@pytest.fixture(scope="session")
def camera():
    return Camera()
