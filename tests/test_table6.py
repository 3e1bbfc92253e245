import pandas as pd
import pytest

from starid.cli import main
from starid.experiments.table6 import PAPER, PAPER_ALGORITHMS
from starid.stats import mcnemar

SUMMARY = ["algorithm", "trials", "id_rate", "id_rate_lo", "id_rate_hi", "misid_rate", "no_result_rate",
           "star_recall", "star_precision", "time_median_us", "time_mean_us", "time_p95_us", "db_mb", "build_s",
           "compile_s"]


def test_mcnemar_exact():
    rows = []
    for t in range(20):   # A right on 0-14, B right on 10-19: 10 discordant for A, 5 for B
        rows.append({"trial": t, "label": "a", "status": "correct" if t < 15 else "no_result"})
        rows.append({"trial": t, "label": "b", "status": "correct" if t >= 10 else "misidentified"})
    r = mcnemar(pd.DataFrame(rows), "a", "b")
    assert (r["only_a_correct"], r["only_b_correct"]) == (10, 5)
    assert r["p_value"] == pytest.approx(0.3017578125)     # 2 * P(X <= 5), X ~ Binomial(15, 1/2)


def test_table6_files_two_skies(tmp_path, capsys):
    # --jobs 1 against --jobs 2 is tests/test_engine.py::test_jobs_do_not_change_results (the same engine)
    assert main(["table6", "--trials", "24", "--seed", "5", "--jobs", "2", "--quiet",
                 "--out", str(tmp_path / "j1")]) == 0
    out = capsys.readouterr().out
    assert "| ptp |" in out and "McNemar" in out
    assert out.index("paper's sky") < out.index("real sky")
    t1 = pd.read_csv(tmp_path / "j1" / "trials.csv")
    table = pd.read_csv(tmp_path / "j1" / "table6.csv")
    assert list(table.columns[:len(SUMMARY)]) == SUMMARY
    assert {"paper_id_rate", "paper_time_ms", "paper_db_mb", "sky"} <= set(table.columns)
    paper_rows = table[table["sky"] == "paper"]
    assert list(paper_rows["algorithm"][:3]) == list(PAPER_ALGORITHMS)
    assert paper_rows.set_index("algorithm").loc["ptp", "paper_id_rate"] == PAPER["ptp"]["paper_id_rate"]
    assert table[table["sky"] == "real"]["paper_id_rate"].isna().all()
    assert (table["trials"] == 24).all()
    assert set(t1["grid_sky"]) == {"paper", "real"}
    # the paper's sky images guide stars only
    assert (t1.loc[t1["grid_sky"] == "paper", "sim_sky_mag_limit"] == 6.0).all()
    assert (tmp_path / "j1" / "table6.md").read_text().startswith("Table 6")
