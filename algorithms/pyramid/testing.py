"""Test helpers shared by the ``pyramid`` and ``geometric_voting`` test files (one copy, imported by both).

Not part of the algorithm: plain functions the two plugins' tests call with their own class,
database and thresholds. What the central conformance suite (``starid.testing.CHECKS``) already
covers (random fields, coincident stars, ids beyond 2^31, explain, determinism, order
invariance) is not repeated here.
"""

from __future__ import annotations

import numpy as np

from starid import Camera, Observation, SimConfig, Simulator


def noisy_results(algo, db, catalog, camera, n: int, seed: int = 12):
    """``n`` trials with 1 px / 0.5 Mv noise on the V <= 6 sky: ``[(obs, result, true attitude)]``.

    Asserts that no star is misidentified in any of them.
    """
    config = SimConfig(sigma_px=1.0, sigma_mag=0.5)
    trials = Simulator(catalog.brighter_than(6.0), camera, config, seed=seed).generate(n)
    out = []
    for t in range(len(trials)):
        obs = trials.observation(t)
        result = algo.identify(db, obs)
        found = result.hip >= 0
        assert np.all(result.hip[found] == obs.truth_hip[found])
        out.append((obs, result, trials.attitude[t]))
    return out


def wide_field_work(cls, catalog) -> tuple[dict, object]:
    """The work counters of one identify of 300 random points on a 170 deg camera (database built for
    it), and the algorithm: what bounds the search there is a counter, not a clock (a time limit would
    measure the machine's load)."""
    cam = Camera.from_fov(170.0)
    algo = cls()
    db = algo.build(catalog, cam)
    rng = np.random.default_rng(5)
    obs = Observation(rng.uniform(0, 1024, 300), rng.uniform(0, 1024, 300), rng.uniform(0, 6, 300), cam)
    result = algo.identify(db, obs)
    assert result.hip.shape == (300,)
    return result.counters, algo
