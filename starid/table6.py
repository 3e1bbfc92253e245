"""Table 6 of Zhou & Ye (2015): PTP vs P-vector vs planar triangle at 1 px / 0.5 Mv noise.

The paper's conditions (section 3.6 and Table 4): 10 x 10 deg FOV, 1024 x 1024 px, stars to
6.0 Mv, centroid noise sigma = 1 px, magnitude noise sigma = 0.5 Mv, 10,000 random attitudes,
images with more than five stars. All three algorithms run on the same trials; the id_rates are
compared pairwise with McNemar's exact test (the discordant trials are binomial(1/2) under the
hypothesis of equal rates).

The paper's absolute times (MATLAB on an i5-2400) are not comparable with ours; they are shown
for the orderings only.
"""

from __future__ import annotations

import itertools
import math

import pandas as pd
from scipy.stats import binomtest

from .harness import summarize

ALGORITHMS = ("ptp", "pvector", "planar_triangle")

#: Table 6 as printed: identification rate, average identification time (ms), memory (MB).
PAPER = {
    "ptp": {"paper_id_rate": 0.9679, "paper_time_ms": 3.28, "paper_db_mb": 0.784},
    "pvector": {"paper_id_rate": 0.9491, "paper_time_ms": 7.63, "paper_db_mb": 0.537},
    "planar_triangle": {"paper_id_rate": 0.9325, "paper_time_ms": 583.75, "paper_db_mb": 178.0},
}

SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


def mcnemar(trials: pd.DataFrame, a: str, b: str) -> dict:
    """Exact McNemar test of ``a`` vs ``b`` on the trials both ran (correct vs anything else)."""
    wide = trials.assign(ok=trials["status"] == "correct").pivot(index="trial", columns="algorithm", values="ok")
    only_a = int((wide[a] & ~wide[b]).sum())
    only_b = int((wide[b] & ~wide[a]).sum())
    p = binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
    return {"a": a, "b": b, "only_a_correct": only_a, "only_b_correct": only_b, "p_value": float(p)}


def table(trials: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The summary with the paper's columns, and the pairwise McNemar tests."""
    summary = summarize(trials)
    paper = pd.DataFrame([{"algorithm": k, **v} for k, v in PAPER.items()])
    summary = summary.merge(paper, on="algorithm", how="left")
    names = list(summary["algorithm"])
    tests = pd.DataFrame([mcnemar(trials, a, b) for a, b in itertools.combinations(names, 2)])
    return summary, tests


def _pct(x: float) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.2f}%"


def markdown(summary: pd.DataFrame, tests: pd.DataFrame, header: str) -> str:
    """Table 6, measured next to printed, then the McNemar tests, as Markdown."""
    lines = [header, "",
             "| Algorithm | id rate [95% CI] | paper | misid rate | median time | mean time | paper time "
             "| DB (MB) | paper DB (MB) | build (s) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary.itertuples():
        lines.append(
            f"| {r.algorithm} | {_pct(r.id_rate)} [{_pct(r.id_rate_lo)}, {_pct(r.id_rate_hi)}] "
            f"| {_pct(r.paper_id_rate)} | {_pct(r.misid_rate)} | {r.time_median_us / 1e3:.3f} ms "
            f"| {r.time_mean_us / 1e3:.3f} ms | {r.paper_time_ms:g} ms | {r.db_mb:.3f} | {r.paper_db_mb:g} "
            f"| {r.build_s:.2f} |")
    lines += ["", "Paired comparison of id rates on the same trials (McNemar's exact test):", "",
              "| A | B | only A correct | only B correct | p-value |", "|---|---|---|---|---|"]
    for r in tests.itertuples():
        p = f"{r.p_value:.3g}" if r.p_value > 0 else "< 1e-300"
        lines.append(f"| {r.a} | {r.b} | {r.only_a_correct} | {r.only_b_correct} | {p} |")
    return "\n".join(lines) + "\n"
