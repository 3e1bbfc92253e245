"""Published readings named by source (``NAME:SOURCE``) and the galvizo2018 experiment."""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest
from starid_algorithms.ptp import PTP

from starid.errors import ConfigError
from starid.experiment import Experiment, Study, Variant, run_experiment
from starid.experiments import galvizo2018 as g
from starid.registry import get_algorithm, register, unregister
from starid.scoring import bijection_accuracy
from starid.testing import ConformanceError, check_algorithm


@dataclass(frozen=True)
class Read(PTP):
    """PTP with a paper reading and one named by another source (a test double)."""

    name: ClassVar[str] = "read_ptp"
    published: ClassVar[dict] = {"verify": False}
    published_readings: ClassVar[dict] = {"other2020": {"n_slaves": 5, "confirm_fraction": 0.0}}


@pytest.fixture
def registered():
    register(Read)
    yield
    unregister("read_ptp")


def test_a_reading_named_by_its_source_parses_beside_paper(registered):
    v = Variant.parse("read_ptp:other2020")
    assert (v.name, v.label, dict(v.params)) == ("read_ptp", "read_ptp:other2020",
                                                 {"n_slaves": 5, "confirm_fraction": 0.0})
    on_top = Variant.parse("read_ptp:other2020[n_slaves=3]")
    assert on_top == Variant.as_reading("read_ptp", "other2020", n_slaves=3)
    assert on_top.label == "read_ptp:other2020[n_slaves=3]" and dict(on_top.params)["n_slaves"] == 3
    assert Variant.parse("read_ptp:paper") == Variant.as_published("read_ptp")
    assert dict(Variant.parse("read_ptp:paper").params) == {"verify": False}
    with pytest.raises(ConfigError, match=r"no published reading 'other'; valid: read_ptp:paper, read_ptp:other2020"):
        Variant.parse("read_ptp:other")
    with pytest.raises(ConfigError, match="declares no 'published'"):
        Variant.parse("tetra:paper")


def test_the_galvizo2018_readings_of_pyramid_and_planar_triangle():
    for name in ("pyramid", "planar_triangle"):
        cls = get_algorithm(name)
        algo = Variant.parse(f"{name}:galvizo2018").make()
        assert algo.params() != cls().params()
    assert Variant.parse("pyramid:galvizo2018").make().window_deg == 3e-4
    assert Variant.parse("planar_triangle:galvizo2018").make().sigma_deg == 5e-5
    assert cls().sigma_deg is None and get_algorithm("pyramid")().window_deg is None


def test_conformance_refuses_a_reading_that_is_wrong():
    def cls_with(readings):
        @dataclass(frozen=True)
        class Bad(PTP):
            """PTP with a broken reading (a test double)."""

            name: ClassVar[str] = "bad_ptp"
            published_readings: ClassVar[dict] = readings
        return Bad

    for readings, message in (({"x2020": {"verfiy": False}}, "names a parameter"),
                              ({"x2020": {"verify": True}}, "changes no parameter"),
                              ({"paper": {"verify": False}}, "other than 'paper'"),
                              ({"x2020": {}}, "non-empty dict")):
        with pytest.raises(ConformanceError, match=message):
            check_algorithm(cls_with(readings), checks=["default_constructible"])


def test_the_papers_accuracy_rule():
    acc = bijection_accuracy([3, 2, 0, -1, np.nan], [3, 4, 0, 0, np.nan])
    assert list(acc) == [1.0, 0.5, 0.0, 0.0, 0.0]


def test_missing_methods_are_named_and_registered_readings_run(monkeypatch, registered):
    monkeypatch.setattr(g, "PAPER_METHODS", {"ANG": "read_ptp", "INT": "no_such_plugin", "PYR": "pyramid",
                                             "PLN": "tetra"})
    readings, missing, plain = g.paper_readings()
    assert [v.label for v in readings] == ["pyramid:galvizo2018"] and missing == ["no_such_plugin"]
    assert plain == ["read_ptp", "tetra"]
    line = g.coverage_line()
    assert "not registered, so absent: no_such_plugin" in line and "defaults only): read_ptp, tetra" in line


def test_tables_put_the_printed_values_beside_ours(monkeypatch):
    monkeypatch.setattr(g, "PAPER_METHODS", {"PYR": "pyramid"})
    monkeypatch.setattr(g, "HOKU_QUERIES", 30)
    monkeypatch.setattr(g, "HOKU_STARS", 600)
    full = g.experiment(trials=2, seed=2)
    assert [v.label for v in full.studies[0].variants][:1] == ["pyramid:galvizo2018"]
    assert g.FOV_DEG == 17.7 and g.sigma_px_of(1e-2) == pytest.approx(0.4058, abs=1e-4)
    variants = ("pyramid:galvizo2018", "pyramid")
    studies = tuple(Study(s.name, variants, s.grid) for s in full.studies)
    exp = Experiment(full.name, studies, trials=2, seed=2, camera=full.camera, sim=full.sim)
    frame = run_experiment(exp, None, jobs=1, progress=False)
    tables = {t.name: t for t in g.tables(frame, exp)}
    false = tables["galvizo_false_acc"].frame
    row = false[(false["label"] == "pyramid:galvizo2018") & (false["false_stars"] == 12)].iloc[0]
    part = frame[(frame["study"] == "false_stars") & (frame["grid_false_stars"] == 12)
                 & (frame["label"] == "pyramid:galvizo2018")]
    assert row["printed_accuracy"] == 0.995 and row["trials"] == 2
    assert row["paper_accuracy"] == bijection_accuracy(part["n_correct"], part["n_identified"]).mean()
    noise = tables["galvizo_noise_acc"].frame
    assert sorted(set(noise["rho_deg"])) == [0.0, 1e-4, 1e-2]
    assert noise[noise["rho_deg"] == 1e-2]["printed_accuracy"].tolist() == [0.0, 0.0]
    assert "(paper 0.995)" in tables["galvizo_false_acc"].markdown
    assert "1501" in tables["galvizo_query"].markdown
    query = tables["galvizo_query"].frame.set_index("label")
    assert query.loc["pyramid:galvizo2018", "S_ours_of_2000"] >= 0  # pyramid reports its first query
    hoku = g.hoku_step(2).set_index("method")     # hoku's step at the experiment's seed, on both pyramid rows
    for label in ("pyramid:galvizo2018", "pyramid"):
        assert query.loc[label, "hoku_S_of_2000"] == hoku.loc["PYR", "S_rows"]
        assert query.loc[label, "hoku_f"] == hoku.loc["PYR", "f"]
    assert f"{hoku.loc['PYR', 'S_rows']:.0f} +-" in tables["galvizo_query"].markdown
    assert "30 queries per method on the brightest 600 stars" in tables["galvizo_query"].notes[0]
    assert "1 of the paper's 1 methods run as published (pyramid:galvizo2018)" in tables["galvizo_setup"].markdown


def test_our_f_and_s_from_the_first_query_counters():
    """f: among images identified with no wrong id that name the first queried subset, the share whose
    first R held it; S: the share with |R| = 1, scaled to the paper's 2,000 runs."""
    import pandas as pd
    rows = pd.DataFrame({"n_wrong": [0, 0, 0, 1, 0], "n_correct": [5, 4, 6, 3, 0],
                         "n_first_R": [1, 3, 1, 1, 0], "n_first_named": [1, 1, 0, 1, 0],
                         "n_first_in_R": [1, 0, 0, 1, 0]})
    f, s, n_f, n_s = g.first_query(rows)
    assert (f, s, n_f, n_s) == (0.5, 1200.0, 2, 5)
    assert np.isnan(g.first_query(rows.drop(columns="n_first_R"))[0])


def test_access_counts_on_hokus_definition():
    """The access table: counts capped at 501 (hoku logs a run stopped by its 500-access limit so),
    the 'count > 1' rows averaged over the images that needed more than one access and counted per
    2,000, the false-star point pooling 6 and 12 false stars, each printed value beside its method."""
    import pandas as pd
    sig = g.sigma_px_of(1e-4)
    rows = [{"study": "false_stars", "grid_false_stars": f, "grid_sigma_px": 0.0, "algorithm": "angle",
             "label": "angle:galvizo2018", "n_pairs": p, "n_to_r": r}
            for f, p, r in ((0, 10, 10), (0, 900, 40), (6, 30, 3), (12, 50, 5))]
    rows += [{"study": "noise", "grid_false_stars": 0, "grid_sigma_px": sig, "algorithm": "spherical_triangle",
              "label": "spherical_triangle:galvizo2018", "n_pairs": np.nan, "n_to_r": r} for r in (1, 1, 7, 600)]
    df = g.access_frame(pd.DataFrame(rows)).set_index(["accesses_to", "point"])
    assert df.loc[("h", "no noise"), "mean"] == (10 + 501) / 2 and df.loc[("h", "no noise"), "paper_mean"] == 69.85
    assert df.loc[("r", "no noise"), "mean"] == 25
    assert df.loc[("h", "false stars"), "mean"] == 40 and df.loc[("h", "false stars"), "images"] == 2
    assert ("h", "rho 1e-2 deg") not in df.index  # no rows at that point
    sph = df.loc[("r, count > 1", "rho 1e-4 deg")]
    assert sph["mean"] == (7 + 501) / 2 and sph["runs_of_2000"] == 1000 and sph["paper_runs_of_2000"] == 1952
    assert sph["images"] == 4 and "(Fig. rPivot)" in g.access_table(pd.DataFrame(rows)).notes[0]
