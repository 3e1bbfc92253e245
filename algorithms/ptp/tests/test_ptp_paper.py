"""``ptp:paper`` against the trend of Zhou & Ye's Table 5 (noise-free, paper's sky): the id rate rises or
stays as the slave stars go from 3 to 6 (97.92 -> 99.34 %). The reading before issue #29 fell
(93.1 -> 64.2 %: 1 px windows in a noise-free world, and every conflicting star dropped)."""

import pytest

from starid import SimConfig, Simulator, run
from starid.experiment import Variant

N_IMAGES = 80


@pytest.fixture(scope="module")
def rates(catalog, camera):
    sim = Simulator(catalog, camera, SimConfig(sigma_px=0.0, sigma_mag=0.0, mag_limit=6.0, min_stars=6,
                                               sky_mag_limit=6.0), seed=11)
    trials = sim.generate(N_IMAGES)
    algos = [(f"s{k}", Variant.as_published("ptp", n_slaves=k).make()) for k in (3, 6)]
    frame = run(algos, trials, catalog, simulator=sim)
    return frame.assign(ok=frame["status"] == "correct").groupby("label")["ok"].mean()


def test_paper_rate_does_not_fall_with_slaves(rates):
    assert rates["s6"] >= rates["s3"] - 0.03, rates.to_dict()


def test_paper_rate_near_table5(rates):
    # Table 5 prints 97.92 % (3 slaves) and 99.34 % (6); 80 images: at most 2 (3 slaves) / 1 (6) missed
    assert rates["s3"] >= 0.97 and rates["s6"] >= 0.98, rates.to_dict()
