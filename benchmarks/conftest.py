"""Fixtures of the benchmark suite: ``python -m pytest benchmarks`` (pytest-benchmark).

Speed targets live here, never in the unit tests. Each per-image benchmark times ``identify``
over the same fixed trials (seed 0, 1 px / 0.5 Mv noise, Table 6's conditions), after a
warm-up so JIT compilation is excluded.
"""

import pytest

from starid import SimConfig, Simulator

N_IMAGES = 200


@pytest.fixture(scope="session")
def table6_trials(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=0)
    return sim.generate(N_IMAGES)
