"""Per-image identification time of every registered algorithm, and the simulator's speed."""

import time

import numpy as np
import pytest

from starid import SimConfig, Simulator
from starid.registry import available_algorithms

from .conftest import N_IMAGES

#: Median identify time targets in microseconds per image, as the issues set them: PTP and P-vector
#: 50, triangle voting 200, planar triangle 5 ms (issues #2-#4); pyramid, geometric voting and
#: improved LPT within 2x of PTP's target, tetra faster than PTP's (issues #14, #15).
MEDIAN_TARGET_US = {"ptp": 50, "pvector": 50, "planar_triangle": 5000, "triangle_voting": 200, "pyramid": 100,
                    "geometric_voting": 100, "tetra": 50, "lpt_improved": 100}
#: The same targets as the issues state them, relative to PTP on the same images: pyramid, geometric
#: voting and improved LPT within 2x of PTP's median, tetra faster (issues #14, #15).
RATIO_TO_PTP = {"pyramid": 2.0, "geometric_voting": 2.0, "lpt_improved": 2.0, "tetra": 1.0}
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
    target = MEDIAN_TARGET_US.get(info.name)
    if target is not None:
        assert median_us <= target, f"{info.name}: median {median_us:.1f} us per image > target {target} us"


@pytest.mark.parametrize("name", sorted(RATIO_TO_PTP))
def test_median_relative_to_ptp(name, catalog, camera, table6_trials):
    """Both algorithms time each image in turn (same images, same machine load), compilation apart."""
    from starid.registry import get_algorithm

    algorithms = [get_algorithm(n)() for n in ("ptp", name)]
    dbs = [a.build(catalog, camera) for a in algorithms]
    observations = [table6_trials.observation(i, truth=False) for i in range(len(table6_trials))]
    for a, db in zip(algorithms, dbs):
        a.identify(db, observations[0])               # JIT warm-up, not timed
    times_ns = np.zeros((2, 3 * len(observations)))
    for k, obs in enumerate(observations * 3):
        for j, (a, db) in enumerate(zip(algorithms, dbs)):
            t0 = time.perf_counter_ns()
            a.identify(db, obs)
            times_ns[j, k] = time.perf_counter_ns() - t0
    ptp_us, other_us = np.median(times_ns, axis=1) / 1e3
    ratio = other_us / ptp_us
    assert ratio <= RATIO_TO_PTP[name], (f"{name}: median {other_us:.1f} us = {ratio:.2f}x PTP's {ptp_us:.1f} us "
                                         f"> {RATIO_TO_PTP[name]}x")


def test_simulator_10k_trials(benchmark, catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=1)
    sim.generate(10)                                  # JIT warm-up of the merge kernel
    trials = benchmark.pedantic(sim.generate, args=(10_000,), rounds=1, iterations=1)
    assert len(trials) == 10_000
    assert benchmark.stats.stats.max <= 5.0, "10,000 trials must be generated in <= 5 s on one core"
