"""Zhou & Ye (2015), section 3 in full: Tables 5 and 6, Figures 10-13, and false / lost stars.

* Table 5: PTP with 3, 4, 5 and 6 slave stars (database size, rate, mean time), as published
  and with starid's defaults, noise-free (its 4-slave rate, 99.3 %, is Fig. 12's noise-free
  point), paper's sky;
* Table 6: see :mod:`starid.experiments.table6`, in the paper's, the real and the ``fig10`` sky,
  and each of the paper's three also as published (``NAME:paper``: the plugin's ``published``
  overrides switch starid's extensions off), so the rate and time of the paper's method and of
  starid's default are both in the table;
* Fig. 10: the number of stars in the field (min, max, mean, share above 8) in each sky of
  Table 6, beside the paper's 2, 45, 14.18 and 96.47 %;
* Fig. 11: id rate against the number of stars in the field (Table 6's images, paper's sky; the
  paper prints no values, only that planar triangle leads in sparse fields and PTP and P-vector
  reach about 100 % above seven stars);
* Fig. 12: id rate against centroid noise 0-2 px (no magnitude noise), paper's endpoints (the
  three methods' 0 and 2 px rates);
* Fig. 13: id rate against magnitude noise 0-1 Mv (no centroid noise), paper's endpoints (P-vector
  only; of PTP and planar triangle it says only that they fall less);
* beyond the paper: id rate against 0-5 false stars and 0-5 lost stars at 1 px / 0.5 Mv.

Table 6 and Figs. 11-13 have the paper's three both with starid's defaults and as published
(``NAME:paper``), on the same images; the beyond-the-paper sweeps have starid's defaults only.

Every registered algorithm runs in every sweep, not only the paper's three; all in the paper's
sky (its simulator imaged its guide stars only) except Table 6's second sky.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..experiment import Experiment, Grid, Study, Variant
from ..registry import get_algorithm
from ..report.tables import Table, markdown, pct, rate_ci
from ..stats import split_by_stars, summarize, wilson_interval
from . import registered_beyond, sweep_points, sweep_table, table6

NAME = "zhou2015"
TITLE = "Zhou & Ye (2015), section 3"
DESCRIPTION = "Zhou & Ye (2015) section 3: Tables 5-6, Figs. 10-13, false and lost stars, every algorithm"
DEFAULT_TRIALS = 2000
BASE = {"mag_limit": 6.0, "min_stars": 6, "sky": "paper"}

#: Table 5 as printed: slaves -> (memory MB, id rate, mean time ms).
PAPER_TABLE5 = {3: (0.436, 0.9792, 2.52), 4: (0.784, 0.993, 3.11), 5: (1.128, 0.9932, 3.86),
                6: (1.643, 0.9934, 4.94)}
#: Fig. 10 as printed (section 3.3).
PAPER_FIG10 = {"min": 2, "max": 45, "mean": 14.18, "share_above_8": 0.9647}
FIG10_SKIES = ("paper", "fig10", "real")
#: Fig. 11 is plotted without printed values; what section 3.3 says of it.
PAPER_FIG11 = ("The paper prints no Fig. 11 values; its text: with few stars in the field planar triangle "
               "identifies more than PTP, and PTP more than P-vector; above seven stars PTP and P-vector reach "
               "about 100 %; planar triangle tends to 100 % with some fluctuation.")
#: Figs. 12 and 13: the endpoints the text gives, (axis value, algorithm) -> id rate.
PAPER_FIG12 = {(0.0, "ptp"): 0.993, (2.0, "ptp"): 0.955, (0.0, "pvector"): 0.989, (2.0, "pvector"): 0.937,
               (0.0, "planar_triangle"): 0.991, (2.0, "planar_triangle"): 0.921}
PAPER_FIG13 = {(0.0, "pvector"): 0.989, (1.0, "pvector"): 0.937}

SWEEPS = {
    "fig12": ("sigma_px", [0.0, 0.5, 1.0, 1.5, 2.0], {"sigma_mag": 0.0}, PAPER_FIG12, "centroid noise (px)"),
    "fig13": ("sigma_mag", [0.0, 0.25, 0.5, 0.75, 1.0], {"sigma_px": 0.0}, PAPER_FIG13, "magnitude noise (Mv)"),
    "false_stars": ("false_stars", [0, 1, 2, 3, 4, 5], {"sigma_px": 1.0, "sigma_mag": 0.5}, {}, "false stars"),
    "lost_stars": ("lost_stars", [0, 1, 2, 3, 4, 5], {"sigma_px": 1.0, "sigma_mag": 0.5}, {}, "lost stars"),
}
#: The sweeps that are the paper's figures: their rows include the paper's three as published.
PAPER_SWEEPS = ("fig12", "fig13")


def _beyond_paper() -> tuple[str, ...]:
    """The rows of the sweeps the paper does not have: every registered algorithm, starid's defaults."""
    return table6.PAPER_ALGORITHMS + registered_beyond(table6.PAPER_ALGORITHMS)


def _published() -> tuple[Variant, ...]:
    """The paper's three as published, for those whose plugin declares ``published`` overrides."""
    return tuple(Variant.as_published(n) for n in table6.PAPER_ALGORITHMS if get_algorithm(n).published)


def _all() -> tuple:
    """Every sweep's rows: the paper's three, as published, then every other registered algorithm."""
    return table6.PAPER_ALGORITHMS + _published() + registered_beyond(table6.PAPER_ALGORITHMS)


def _table5_variants() -> tuple:
    """PTP as published and starid's default PTP, each with the paper's 3-6 slave stars."""
    published = tuple(Variant.as_published("ptp", n_slaves=k) for k in PAPER_TABLE5)
    return published + tuple("ptp" if k == 4 else f"ptp[n_slaves={k}]" for k in PAPER_TABLE5)


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0) -> Experiment:
    studies = [Study("table5", _table5_variants(),
                     Grid({"sigma_px": [0.0], "sigma_mag": [0.0]})),
               Study("table6", _all(),
                     Grid({"sky": list(table6.SKIES) + ["fig10"], "sigma_px": [1.0], "sigma_mag": [0.5]})),
               Study("fig10", ("ptp",), Grid({"sky": list(FIG10_SKIES), "sigma_px": [0.0], "sigma_mag": [0.0],
                                              "min_stars": [0]}))]
    for name, (axis, values, fixed, _, _) in SWEEPS.items():
        grid = {axis: values, **{k: [v] for k, v in fixed.items()}}
        studies.append(Study(name, _all() if name in PAPER_SWEEPS else _beyond_paper(), Grid(grid)))
    return Experiment(NAME, tuple(studies), trials=trials, seed=seed, sim=dict(BASE), description=DESCRIPTION)


def table5(frame: pd.DataFrame) -> Table:
    s = summarize(frame[frame["study"] == "table5"])
    slaves = frame[frame["study"] == "table5"].groupby("label", sort=False)["param_n_slaves"].first()
    rows = []
    for r in s.itertuples():
        k = int(slaves[r.label])
        mb, rate, ms = PAPER_TABLE5.get(k, (np.nan, np.nan, np.nan))
        rows.append({"slaves": k, "label": r.label, "db_mb": r.db_mb, "paper_db_mb": mb, "id_rate": r.id_rate,
                     "id_rate_lo": r.id_rate_lo, "id_rate_hi": r.id_rate_hi, "paper_id_rate": rate,
                     "misid_rate": r.misid_rate, "time_mean_us": r.time_mean_us, "paper_time_ms": ms})
    df = pd.DataFrame(rows)
    shown = pd.DataFrame({
        "algorithm": df["label"], "slave stars": df["slaves"], "DB (MB)": df["db_mb"].map(lambda v: f"{v:.3f}"),
        "paper DB (MB)": df["paper_db_mb"],
        "id rate [95% CI]": [rate_ci(a, b, c)
                             for a, b, c in zip(df["id_rate"], df["id_rate_lo"], df["id_rate_hi"], strict=True)],
        "paper": df["paper_id_rate"].map(pct), "misid": df["misid_rate"].map(pct),
        "mean time": df["time_mean_us"].map(lambda v: f"{v / 1e3:.3f} ms"),
        "paper time": df["paper_time_ms"].map(lambda v: f"{v:g} ms")})
    return Table("table5", "Table 5: PTP with 3-6 slave stars, noise-free, paper's sky", df, markdown(shown),
                 ("ptp:paper is the paper's method (the plugin's 'published' parameters); the other rows are "
                  "starid's default (6 deg slave radius and its checks), whose database is larger.",))


def star_counts(frame: pd.DataFrame) -> pd.DataFrame:
    """Fig. 10's statistics of the number of stars in the field (noise-free, no minimum), per sky."""
    part = frame[frame["study"] == "fig10"]
    rows = []
    for sky, g in part.groupby("grid_sky", sort=False):
        n = g["n_true_stars"].to_numpy()
        rows.append({"sky": sky, "images": n.size, "min": int(n.min()), "max": int(n.max()), "mean": float(n.mean()),
                     "share_above_8": float((n > 8).mean())})
    rows.append({"sky": "paper (Fig. 10)", "images": 10_000, **PAPER_FIG10})
    return pd.DataFrame(rows)


def fig10(frame: pd.DataFrame) -> Table:
    df = star_counts(frame)
    shown = df.assign(mean=df["mean"].map(lambda v: f"{v:.2f}"), share_above_8=df["share_above_8"].map(pct))
    shown = shown.rename(columns={"share_above_8": "more than 8 stars"})
    return Table("fig10", "Fig. 10: stars in the field (noise-free, every attitude kept)", df, markdown(shown),
                 ("Skies: paper = V <= 6 imaged; fig10 = V <= 6.15, calibrated on the paper's mean; real = every "
                  "catalog star to V 8 that is brighter than the 6.0 detection limit.",))


def fig11(frame: pd.DataFrame) -> Table:
    t6 = frame[(frame["study"] == "table6") & (frame["grid_sky"] == "paper")]
    bins = [(6, 8), (9, 10), (11, 13), (14, 17), (18, 1000)]
    rows = []
    for label, g in t6.groupby("label", sort=False):
        for lo, hi in bins:
            part = g[(g["n_true_stars"] >= lo) & (g["n_true_stars"] <= hi)]
            k, n = int((part["status"] == "correct").sum()), len(part)
            a, b = wilson_interval(k, n)
            rows.append({"label": label, "stars": f"{lo}-{hi}" if hi < 1000 else f">= {lo}", "trials": n,
                         "id_rate": k / n if n else np.nan, "id_rate_lo": a, "id_rate_hi": b})
    df = pd.DataFrame(rows)
    wide = df.assign(cell=[f"{pct(r)} ({n})" for r, n in zip(df["id_rate"], df["trials"], strict=True)]).pivot(
        index="label", columns="stars", values="cell").reindex(index=list(dict.fromkeys(df["label"])),
                                                               columns=list(dict.fromkeys(df["stars"])))
    split = split_by_stars(t6)
    note = ("Split at 8 stars (the share of such images differs between skies, so a difference in sky shows as "
            "what it is):\n\n" + markdown(split.assign(id_rate=[rate_ci(a, b, c) for a, b, c in zip(
                split["id_rate"], split["id_rate_lo"], split["id_rate_hi"], strict=True)]).drop(columns=["id_rate_lo",
                                                                                              "id_rate_hi"])))
    return Table("fig11", "Fig. 11: id rate by stars in the field (Table 6 images, paper's sky; images in brackets)",
                 df, markdown(wide.reset_index()), (PAPER_FIG11, note))


TITLES = {"fig12": "Fig. 12: id rate vs centroid noise", "fig13": "Fig. 13: id rate vs magnitude noise",
          "false_stars": "Beyond the paper: id rate vs false stars",
          "lost_stars": "Beyond the paper: id rate vs lost stars"}


def sweep(frame: pd.DataFrame, name: str) -> Table:
    axis, _, fixed, paper, unit = SWEEPS[name]
    conditions = ", ".join(f"{k} = {v:g}" for k, v in fixed.items())
    return sweep_table(frame, name, axis, paper, unit, f"{TITLES[name]} ({conditions}; paper's sky)", name)


def paper_points() -> pd.DataFrame:
    """The paper's printed points of its swept figures: ``study, axis, value, algorithm, paper_id_rate``."""
    return sweep_points(SWEEPS)


def tables(frame: pd.DataFrame, experiment: Experiment) -> list[Table]:
    return [table5(frame), *table6.tables(frame, experiment), fig10(frame), fig11(frame),
            *(sweep(frame, name) for name in SWEEPS)]
