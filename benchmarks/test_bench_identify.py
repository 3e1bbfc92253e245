"""Per-image identification time of every registered algorithm, and the simulator's speed."""

import time

import numpy as np
import pytest

from starid import SimConfig, Simulator
from starid.registry import available_algorithms

from .conftest import N_IMAGES

#: The speed targets are ratios against tetra on the same images (issue #25): benchmarks/test_ratios.py.
#: This file reports each plugin's time per image (pytest-benchmark) without asserting on it.
ALGORITHMS = [i for i in available_algorithms() if i.status == "ok"]


@pytest.mark.parametrize("info", ALGORITHMS, ids=[i.name for i in ALGORITHMS])
def test_identify_per_image(benchmark, info, catalog, camera, table6_trials):
    algorithm = info.cls()
    db = algorithm.build(catalog, camera)
    observations = [table6_trials.observation(i, truth=False) for i in range(len(table6_trials))]
    algorithm.identify(db, observations[0])           # JIT warm-up, not timed
    per_image_ns = []

    def identify_all():
        for obs in observations:
            t0 = time.perf_counter_ns()
            algorithm.identify(db, obs)
            per_image_ns.append(time.perf_counter_ns() - t0)

    benchmark.pedantic(identify_all, rounds=3, iterations=1)
    median_us = float(np.median(per_image_ns)) / 1e3
    benchmark.extra_info.update({"images": N_IMAGES, "median_us_per_image": median_us,
                                 "mean_us_per_image": float(np.mean(per_image_ns)) / 1e3,
                                 "db_mb": db.nbytes / 1e6})


def test_simulator_10k_trials(benchmark, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=1)
    sim.generate(10)                                  # JIT warm-up of the merge kernel
    trials = benchmark.pedantic(sim.generate, args=(10_000,), rounds=1, iterations=1)
    assert len(trials) == 10_000
    assert benchmark.stats.stats.max <= 5.0, "10,000 trials must be generated in <= 5 s on one core"
