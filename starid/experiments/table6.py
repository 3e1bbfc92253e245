"""Table 6 of Zhou & Ye (2015): PTP vs P-vector vs planar triangle at 1 px / 0.5 Mv, in two skies.

The paper's conditions (section 3.6, Table 4): 10 x 10 deg field of view, 1024 x 1024 px, stars
to 6.0 Mv, centroid noise 1 px, magnitude noise 0.5 Mv, 10,000 random attitudes, images with
more than five stars. Two skies: the paper's (only its guide stars, V <= 6, are imaged, so
magnitude noise can only drop stars; compared with the paper) and the real one (every catalog
star to V 8 is imaged and noise lets fainter ones in). Every other registered algorithm runs on
the same images as "beyond the paper" rows. Id rates are compared pairwise with McNemar's exact
test. The paper's times (MATLAB on an i5-2400) are shown for the orderings only.
"""

from __future__ import annotations

import pandas as pd

from ..experiment import Experiment, Grid, Study
from ..report.tables import Table, markdown, mcnemar_markdown, pct, rate_ci
from ..stats import mcnemar, summarize
from . import registered_beyond

NAME = "table6"
TITLE = "Table 6 (Zhou & Ye 2015)"
DESCRIPTION = "Zhou & Ye (2015) Table 6: PTP, P-vector, planar triangle at 1 px / 0.5 Mv, paper's and real sky"
DEFAULT_TRIALS = 10_000
PAPER_ALGORITHMS = ("ptp", "pvector", "planar_triangle")
SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}
SKIES = ("paper", "real")

#: Table 6 as printed: identification rate, average identification time (ms), memory (MB).
PAPER = {
    "ptp": {"paper_id_rate": 0.9679, "paper_time_ms": 3.28, "paper_db_mb": 0.784},
    "pvector": {"paper_id_rate": 0.9491, "paper_time_ms": 7.63, "paper_db_mb": 0.537},
    "planar_triangle": {"paper_id_rate": 0.9325, "paper_time_ms": 583.75, "paper_db_mb": 178.0},
}


def study(name: str = "table6") -> Study:
    return Study(name, PAPER_ALGORITHMS + registered_beyond(PAPER_ALGORITHMS), Grid({"sky": list(SKIES)}))


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0) -> Experiment:
    return Experiment(NAME, (study(),), trials=trials, seed=seed, sim=dict(SIM), description=DESCRIPTION)


def summary(frame: pd.DataFrame) -> pd.DataFrame:
    """Table 6's summary columns for each sky, with the paper's values beside (paper rows first)."""
    s = summarize(frame, by=("grid_sky", "label"))
    s = s.rename(columns={"grid_sky": "sky"})
    paper = pd.DataFrame([{"algorithm": k, **v} for k, v in PAPER.items()])
    s = s.merge(paper, on="algorithm", how="left")
    s.loc[s["sky"] == "real", ["paper_id_rate", "paper_time_ms", "paper_db_mb"]] = float("nan")
    return s


def pairwise(frame: pd.DataFrame, sky: str) -> pd.DataFrame:
    """McNemar for every pair of the paper's three, and every other algorithm against PTP."""
    rows = frame[frame["grid_sky"] == sky]
    labels = list(dict.fromkeys(rows["label"]))
    paper = [x for x in labels if x in PAPER_ALGORITHMS]
    pairs = [(a, b) for i, a in enumerate(paper) for b in paper[i + 1:]]
    pairs += [("ptp", x) for x in labels if x not in PAPER_ALGORITHMS and "ptp" in labels]
    return pd.DataFrame([mcnemar(rows, a, b) for a, b in pairs],
                        columns=["a", "b", "only_a_correct", "only_b_correct", "p_value"])


def _shown(s: pd.DataFrame, with_paper: bool) -> pd.DataFrame:
    out = pd.DataFrame({
        "algorithm": s["label"],
        "id rate [95% CI]": [rate_ci(r, lo, hi)
                             for r, lo, hi in zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], strict=True)],
    })
    if with_paper:
        out["paper"] = s["paper_id_rate"].map(pct)
    out["misid"] = s["misid_rate"].map(pct)
    out["failed"] = (s["error_rate"] + s["timeout_rate"] + s["crash_rate"]).map(pct)
    out["median time"] = s["time_median_us"].map(lambda v: f"{v / 1e3:.3f} ms")
    out["mean time"] = s["time_mean_us"].map(lambda v: f"{v / 1e3:.3f} ms")
    if with_paper:
        out["paper time"] = s["paper_time_ms"].map(lambda v: "" if pd.isna(v) else f"{v:g} ms")
    out["DB (MB)"] = s["db_mb"].map(lambda v: f"{v:.3f}")
    if with_paper:
        out["paper DB (MB)"] = s["paper_db_mb"].map(lambda v: "" if pd.isna(v) else f"{v:g}")
    return out


def paper_points() -> pd.DataFrame:
    """Table 6 has no swept figure: no points to overlay."""
    return pd.DataFrame(columns=["study", "axis", "value", "algorithm", "paper_id_rate"])


def tables(frame: pd.DataFrame, experiment: Experiment, study_name: str = "table6") -> list[Table]:
    frame = frame[frame["study"] == study_name]
    s = summary(frame)
    n = int(frame["trial"].nunique())
    out = []
    words = {"paper": "the paper's sky: only guide stars (V <= 6) imaged, compared with the paper",
             "real": "the real sky: every catalog star to V 8 imaged, noise lets fainter stars in",
             "fig10": "the Fig. 10-calibrated sky: stars to V 6.15 imaged and detected"}
    for sky in dict.fromkeys(s["sky"]):
        part = s[s["sky"] == sky].reset_index(drop=True)
        what = words.get(sky, f"sky {sky}")
        notes = ("McNemar's exact test on the same images:\n\n" + mcnemar_markdown(pairwise(frame, sky)),)
        out.append(Table(f"table6_{sky}", f"Table 6, {what} ({n} images, 1 px / 0.5 Mv)",
                         part, markdown(_shown(part, sky != "real")), notes))
    return out
