"""``benchmarks/tools/targets.py``: issue #25's report from its measurements, and the row comparison it uses.

The measurements themselves take minutes on an idle machine (the benchmark suite's business); these
tests feed the report's pure parts with made-up measurements whose verdicts are known.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pandas as pd
import pytest

TOOL = Path(__file__).resolve().parents[1] / "benchmarks" / "tools" / "targets.py"


def _load_tool():
    spec = importlib.util.spec_from_file_location("starid_targets_tool", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


TARGETS = _load_tool()


@pytest.fixture(scope="module")
def targets():
    return TARGETS


def _run(tetra_us, ptp_us, ptp_p95_us, others=True):
    """One ratio run as the tool's subprocess prints it: {sky: {name: [median_us, p95_us]}}; every plugin
    with a ratio target but ptp (``others``) at tetra's times."""
    sky = {"tetra": [tetra_us, 2 * tetra_us], "ptp": [ptp_us, ptp_p95_us]}
    if others:
        sky.update({n: [tetra_us, 2 * tetra_us] for n in TARGETS.RATIO_TO_TETRA if n != "ptp"})
    return {"paper": sky, "real": {k: [v[0] * 1.1, v[1] * 1.1] for k, v in sky.items()}}


def test_ratios_are_per_run_then_the_median_over_runs(targets):
    # per run: ptp / tetra = 2.5, 1.5, 1.9 -> median 1.9; the ratio of the medians (44 / 21) would be 2.1
    runs = [_run(20.0, 50.0, 100.0, False), _run(30.0, 45.0, 90.0, False), _run(21.0, 39.9, 80.0, False)]
    r = targets.summarise_ratios(runs)
    assert r["paper"]["ptp"]["ratio"] == pytest.approx(1.9)
    assert r["paper"]["ptp"]["median_us"] == pytest.approx(45.0)
    assert r["paper"]["ptp"]["ratio_runs"] == [2.5, 1.5, 1.9]
    assert targets._spread(r["paper"]["ptp"]["ratio_runs"]) == "1.50-2.50"
    assert r["paper"]["ptp"]["p95_to_median"] == pytest.approx(2.0)
    assert r["real"]["tetra"]["ratio"] == pytest.approx(1.0)


def _report(targets, ptp_us, ptp_p95_us, cold_wall_s=35.0, lost=0, others=True):
    runs = [_run(20.0, ptp_us, ptp_p95_us, others)]
    plugins = [{"plugin": "ptp", "compile_s": 9.0, "cpu_s": 10.0, "build_s": 0.5, "error": "", "process": 0}]
    return {"machine": {"commit": "abc1234", "uncommitted_changes": False, "cpu": "cpu", "cores": 2,
                        "python": "3", "numpy": "2", "numba": "0", "llvm": "1", "date_utc": "now", "load": 0.5},
            "first_command": {"wall_s": 150.0, "install_s": 25.0, "load": 0.5, "written": True},
            "cold_compile": [{"wall_s": cold_wall_s, "load": 0.5, "expected": 1, "plugins": plugins}],
            "zhou2015": {"wall_s": 200.0, "user_s": 300.0, "system_s": 10.0, "returncode": 0},
            "ratio_runs": runs, "ratios": targets.summarise_ratios(runs),
            "rows_compared": {"table6": {"rows": (10, 10, 10), "compared": 5, "differing": [], "only_before": [],
                                         "only_after": [], "lost": lost, "gained": 0, "correct": []}}}


def bad_report_names(targets):
    return {"tetra", "ptp", *targets.RATIO_TO_TETRA}


def _verdict(lines, start):
    (line,) = [v for v in lines if v["target"].startswith(start)]
    return line


def test_verdicts_name_what_is_over_its_target(targets):
    ok = targets.verdicts(_report(targets, ptp_us=39.0, ptp_p95_us=80.0))
    assert all(v["met"] for v in ok), ok
    # ptp at 2.5x tetra on both skies (2.0x allowed), p95 5x its median, compile 41 s, one image lost
    bad = targets.verdicts(_report(targets, ptp_us=50.0, ptp_p95_us=250.0, cold_wall_s=41.0, lost=1))
    assert not _verdict(bad, "cold compile")["met"]
    ratio = _verdict(bad, "grid, lpt_improved, ptp, pvector, pyramid")   # the 2x group, named in sorted order
    assert not ratio["met"] and "ptp paper 2.50x (2.50)" in ratio["measured"] and "ptp real 2.50x" in ratio["measured"]
    assert _verdict(bad, "geometric_voting, triangle_voting")["met"]   # at tetra's time
    p95 = _verdict(bad, "every p95")
    n = 2 * len(bad_report_names(targets))
    assert not p95["met"] and p95["measured"].startswith(f"{n - 2} of {n}") and "ptp paper 5.00" in p95["measured"]
    # a plugin with a target that was not measured is not a target met
    partial = targets.verdicts(_report(targets, ptp_us=39.0, ptp_p95_us=80.0, others=False))
    line = _verdict(partial, "geometric_voting, triangle_voting")
    assert not line["met"] and line["measured"] == "not measured: geometric_voting, triangle_voting"
    assert not _verdict(bad, "no correct identification lost")["met"]
    assert _verdict(bad, "first command")["met"] and _verdict(bad, "starid reproduce zhou2015")["met"]
    # a cold compile that prepared fewer plugins than there are is not a target met, however fast
    short = _report(targets, ptp_us=39.0, ptp_p95_us=80.0, cold_wall_s=20.0)
    short["cold_compile"][0]["expected"] = 2
    assert not _verdict(targets.verdicts(short), "cold compile")["met"]
    # per-image runs that failed are a line of their own, not met
    failed = {"ratio_runs": [{"error": "ValueError: broken plugin"}]}
    line = _verdict(targets.verdicts(failed), "per image")
    assert not line["met"] and line["measured"] == "not measured: ValueError: broken plugin"


def test_markdown_gives_every_target_and_the_per_image_table(targets):
    report = _report(targets, ptp_us=50.0, ptp_p95_us=250.0)
    report["verdicts"] = targets.verdicts(report)
    text = targets.markdown(report)
    assert text.count("\n| ") >= len(report["verdicts"]) + 1 + 2 + 1   # targets, compile, per image, rows
    assert "| ptp | 50.0 | 2.50x | 5.00 | 55.0 | 2.50x | 5.00 |" in text
    assert "| tetra | 20.0 | 1.00x | 2.00 | 22.0 | 1.00x | 2.00 |" in text
    assert "| ptp | 9.0 / 10.0 |" in text and "**35.0 s**" in text and "| CPU s per process | 10.0 |" in text


def _results(folder: Path, status: list[str], extra: list[int]) -> Path:
    folder.mkdir()
    pd.DataFrame({"study": "run", "label": "ptp", "point": 0, "trial": range(len(status)), "status": status,
                  "n_identified": extra, "time_us": [float(k) for k in range(len(status))]}
                 ).to_parquet(folder / "results.parquet")
    return folder


def test_row_comparison_counts_lost_and_gained_images_and_differing_columns(targets, tmp_path):
    before = _results(tmp_path / "before", ["correct", "correct", "no_result", "correct"], [5, 6, 0, 7])
    after = _results(tmp_path / "after", ["correct", "no_result", "correct", "correct"], [5, 0, 4, 7])
    r = targets.compare(before, after)
    assert r["rows"] == (4, 4, 4) and r["compared"] == 2                  # status, n_identified; not time_us
    assert r["differing"] == [("status", 2), ("n_identified", 2)]
    assert r["groups"] == [(("run", "ptp", 0), 3, 3, 1, 1)]
    (tmp_path / "rows").mkdir()
    (tmp_path / "ref").mkdir()
    before.rename(tmp_path / "ref" / "table6")
    after.rename(tmp_path / "rows" / "table6")
    _results(tmp_path / "ref" / "paper", ["correct"], [3])               # not in the new rows: reported missing
    summary = targets.compare_rows(tmp_path / "rows", tmp_path / "ref")
    assert summary["table6"]["lost"] == 1 and summary["table6"]["gained"] == 1
    assert summary["paper"] == {"missing": True}
    verdict = _verdict(targets.verdicts({"rows_compared": summary}), "no correct identification lost")
    assert not verdict["met"] and "missing: paper" in verdict["measured"]
    # a new run with fewer rows loses nothing it can join, and is still not the same results
    del summary["paper"]
    summary["table6"].update(lost=0, gained=0, rows=(4, 3, 3))
    verdict = _verdict(targets.verdicts({"rows_compared": summary}), "no correct identification lost")
    assert not verdict["met"] and "rows not all joined: table6" in verdict["measured"]
    summary["table6"]["rows"] = (4, 4, 4)
    assert _verdict(targets.verdicts({"rows_compared": summary}), "no correct identification lost")["met"]
