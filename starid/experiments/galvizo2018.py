"""Galvizo & Lim (2018), arXiv 1808.08686: six subgraph-isomorphism methods on one framework.

The paper (LaTeX in ``glennga/hoku`` at commit :data:`HOKU_COMMIT`, ``doc/arxiv-paper.tex``,
Section IV "Empirical Evaluation") ran Angle (ANG), Interior Angle (INT), Spherical Triangle
(SPH), Planar Triangle (PLN), Pyramid (PYR) and Composite Pyramid (COM) on artificial images:

* catalog: Hipparcos stars with m < 6.0 (4,560), pairs and trios within 20 deg of each other;
* images: a random attitude and centre, every such star within psi / 2 = 10 deg of the centre
  (at least five), no pixels, no magnitudes used; Gaussian noise moves each star by N(0, rho^2)
  degrees along a random great circle; false stars ("spikes") are uniform in the field;
* accuracy: a(h), the share of the returned map h that is right (0 when nothing is returned),
  averaged over 2,000 runs per point, with a 500 catalog-access limit;
* studies: false stars 0 / 6 / 12 (no noise) and noise rho = 0 / 1e-4 / 1e-2 deg (no false
  stars); accuracy and mean time of each; the query step's figures without noise; the catalog
  accesses its text gives (:func:`access_table`).

Here the field is a square camera of the same solid angle as the paper's 20 deg cone
(:data:`FOV_DEG`), 1024 px, the sky and detection limit V 6.0, no magnitude noise, no merging
of close stars; rho is turned into per-axis centroid noise of the same mean square displacement
(:func:`sigma_px_of`). Each printed method runs as the paper ran it (``NAME:galvizo2018``, the
plugin's published reading) when its plugin is registered and declares that reading; every
registered algorithm also runs with starid's defaults on the same images. Every accuracy is
scored by the paper's rule (:func:`starid.scoring.bijection_accuracy`) and by starid's (3 right
ids, none wrong).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pandas as pd

from ..camera import Camera
from ..experiment import Experiment, Grid, Study, Variant
from ..registry import available_algorithms, get_algorithm
from ..report.tables import Table, markdown, rate_ci
from ..scoring import bijection_accuracy
from ..stats import summarize
from . import registered_beyond

NAME = "galvizo2018"
TITLE = "Galvizo & Lim (2018), arXiv 1808.08686"
DESCRIPTION = "Galvizo & Lim (2018): six methods vs false stars and noise, the paper's rule and starid's"
DEFAULT_TRIALS = 500
#: The hoku commit whose doc/arxiv-paper.tex and doc/include/floats/*.tex the printed values are from.
HOKU_COMMIT = "0cb340eca0e9af891acfa8a069776530b111c863"
#: The source name of the plugins' readings (``NAME:galvizo2018``).
SOURCE = "galvizo2018"
#: The paper's abbreviations and the plugin that implements each.
PAPER_METHODS = {"ANG": "angle", "INT": "interior_angle", "SPH": "spherical_triangle", "PLN": "planar_triangle",
                 "PYR": "pyramid", "COM": "composite_pyramid"}
#: The paper's field: a cone of 20 deg; here the square of the same solid angle (2 pi (1 - cos 10 deg) sr).
PAPER_FOV_DEG = 20.0
FOV_DEG = round(math.degrees(math.sqrt(2 * math.pi * (1 - math.cos(math.radians(PAPER_FOV_DEG / 2))))), 2)
CAMERA = {"fov_deg": FOV_DEG, "resolution_px": 1024, "pixel_um": 12.0}
SIM = {"sky_mag_limit": 6.0, "mag_limit": 6.0, "sigma_mag": 0.0, "min_stars": 5, "merge_radius_px": 0.0}
FALSE_STARS = (0, 6, 12)
NOISE_DEG = (0.0, 1e-4, 1e-2)

#: Fig. "falseNoise" right (doc/include/floats/false-acc.tex): accuracy a(h) at 0 / 6 / 12 false stars.
PAPER_FALSE_ACC = {"angle": (0.977, 0.979, 0.960), "interior_angle": (1.0, 0.982, 0.965),
                   "spherical_triangle": (1.0, 0.840, 0.696), "planar_triangle": (1.0, 0.845, 0.703),
                   "pyramid": (0.999, 0.999, 0.995), "composite_pyramid": (1.0, 0.994, 0.973)}
#: Fig. "falseNoise" left: mean time (ms; C++ at -O0 on an i7-7700, SQLite catalog) at 0 / 6 / 12 false stars.
PAPER_FALSE_MS = {"angle": (1197.43, 1737.94, 2431.58), "interior_angle": (160.68, 209.36, 280.54),
                  "spherical_triangle": (323.94, 355.54, 386.20), "planar_triangle": (324.35, 350.60, 390.41),
                  "pyramid": (170.79, 183.71, 195.53), "composite_pyramid": (405.53, 685.07, 972.04)}
#: Accuracy at rho = 0 / 1e-4 / 1e-2 deg: the data the pinned text fits its trend lines to (the
#: commented arrays beside Fig. "gaussianNoise"; 0 deg: the no-noise bars of the false-star figure),
#: printed as bars, rounded, in doc/include/floats/gaussian-acc.tex (hoku commit 22c2eb42).
PAPER_NOISE_ACC = {"angle": (0.977, 0.9725, 0.0035), "interior_angle": (1.0, 1.0, 0.7055),
                   "spherical_triangle": (1.0, 0.8135, 0.0253), "planar_triangle": (1.0, 0.8615, 0.0245),
                   "pyramid": (0.999, 0.9993, 0.0), "composite_pyramid": (1.0, 0.0035, 0.0)}
#: Fig. "gaussianNoise" left: mean time (ms) at rho = 0 / 1e-4 / 1e-2 deg.
PAPER_NOISE_MS = {"angle": (1197.43, 1349.07, 6509.00), "interior_angle": (160.68, 161.80, 872.22),
                  "spherical_triangle": (323.94, 339.23, 392.29), "planar_triangle": (324.35, 328.85, 352.24),
                  "pyramid": (170.79, 171.53, 364.04), "composite_pyramid": (405.53, 1545.45, 362.30)}
#: Table "queryExperimentResults" (no noise, 2,000 runs): share of runs whose candidates R hold the
#: right catalog set, runs whose first query met |R| = 1 (S, of 2,000), mean query time (ms).
PAPER_QUERY = {"angle": (1.0, 32, 138.00), "interior_angle": (1.0, 1440, 171.80),
               "spherical_triangle": (1.0, 1984, 139.60), "planar_triangle": (1.0, 1994, 139.05),
               "pyramid": (0.99, 1501, 149.69), "composite_pyramid": (1.0, 1994, 139.05)}
#: hoku's access limit (the paper: "a 500 catalog access limit"; ``nu_max``): its counter ``nu`` is
#: raised before the test ``nu > nu_max``, so a run that reaches the limit logs 501.
ACCESS_LIMIT = 500
#: Catalog accesses the text prints (Section V; hoku's ``ComparisonCount`` / ``QueryCount``, the shared
#: counter ``nu``): ``(what, paper's method, point, printed mean, printed runs)``. "h": accesses of the
#: identification experiment (``Experiment::Map``), "r": of the reduction experiment
#: (``Experiment::Reduction``: the query step until the first |R| = 1, pivoting included). Fig. "rPivot"
#: averages only the runs whose count exceeds 1 (its SQL: ``QueryCount > 1``), of which it gives the
#: number (of 2,000); the false-star figures are over the text's spikes 3 / 6 / 9 / 12 (its timing
#: queries beside them take ``FalseStars > 0``).
PAPER_ACCESSES = (("h", "angle", "no noise", 69.85, None), ("r", "angle", "no noise", 68.10, None),
                  ("h", "angle", "rho 1e-2 deg", 399.66, None), ("r", "angle", "rho 1e-2 deg", 36.72, None),
                  ("h", "angle", "false stars", 114.23, None), ("r", "angle", "false stars", 54.85, None),
                  ("r, count > 1", "spherical_triangle", "rho 1e-4 deg", 56.93, 1952),
                  ("r, count > 1", "planar_triangle", "rho 1e-4 deg", 52.71, 1946),
                  ("r, count > 1", "composite_pyramid", "rho 1e-4 deg", 47.18, 1957))
#: The trial-row counter of each plugin that counts hoku's accesses to a map h (every one of these
#: plugins reports ``n_to_r``, the accesses to r).
ACCESS_H = {"angle": "n_pairs"}


def sigma_px_of(rho_deg: float, camera: Camera | None = None) -> float:
    """Per-axis centroid noise (px) with the mean square displacement of the paper's noise: a move
    of N(0, rho^2) degrees in a random direction has E[d^2] = rho^2 = 2 sigma^2 (pixel angle at the centre)."""
    camera = camera or Experiment(NAME, (Study("s", ("pyramid",)),), camera=dict(CAMERA)).make_camera()
    return round(rho_deg / math.sqrt(2.0) * camera.f_px * math.pi / 180.0, 9)


def _registered() -> set[str]:
    return {i.name for i in available_algorithms() if i.status == "ok"}


def paper_readings() -> tuple[tuple[Variant, ...], list[str], list[str]]:
    """The paper's methods as it ran them (``NAME:galvizo2018``) for those registered with that
    reading; the names not registered; the names registered without the reading."""
    present = _registered()
    missing = [n for n in PAPER_METHODS.values() if n not in present]
    plain = [n for n in PAPER_METHODS.values() if n in present and SOURCE not in get_algorithm(n).published_readings]
    readings = tuple(Variant.as_reading(n, SOURCE) for n in PAPER_METHODS.values()
                     if n in present and n not in plain)
    return readings, missing, plain


def coverage_line() -> str:
    """One line saying which of the paper's six methods run here and which do not (and why)."""
    readings, missing, plain = paper_readings()
    labels = ", ".join(v.label for v in readings) or "none"
    line = f"galvizo2018: {len(readings)} of the paper's {len(PAPER_METHODS)} methods run as published ({labels})"
    if missing:
        line += f"; not registered, so absent: {', '.join(missing)}"
    if plain:
        line += f"; registered without a '{SOURCE}' reading (defaults only): {', '.join(plain)}"
    return line + "."


def variants() -> tuple:
    """The paper's methods as it ran them, then every registered algorithm with starid's defaults."""
    readings, _, _ = paper_readings()
    return readings + registered_beyond(())


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0) -> Experiment:
    _, missing, plain = paper_readings()
    if missing or plain:
        print(coverage_line(), file=sys.stderr)
    noisy = [sigma_px_of(r) for r in NOISE_DEG[1:]]
    studies = (Study("false_stars", variants(), Grid({"false_stars": list(FALSE_STARS), "sigma_px": [0.0]})),
               Study("noise", variants(), Grid({"sigma_px": noisy, "false_stars": [0]})))
    return Experiment(NAME, studies, trials=trials, seed=seed, camera=dict(CAMERA), sim=dict(SIM),
                      description=DESCRIPTION)


def with_paper_accuracy(frame: pd.DataFrame) -> pd.DataFrame:
    """The trial rows with ``paper_accuracy``: each image scored by the paper's rule."""
    return frame.assign(paper_accuracy=bijection_accuracy(frame["n_correct"], frame["n_identified"]))


def _mean_ci(x: np.ndarray) -> tuple[float, float]:
    """Mean and the half-width of its normal 95 % interval."""
    if x.size == 0:
        return float("nan"), float("nan")
    return float(x.mean()), float(1.96 * x.std(ddof=1) / math.sqrt(x.size)) if x.size > 1 else float("nan")


def sweep(frame: pd.DataFrame, axis: str, values: list, paper_acc: dict, paper_ms: dict, unit: str) -> pd.DataFrame:
    """One row per (label, axis value): both accuracies, mean time, the paper's beside."""
    rows = []
    for (label, value), g in frame.groupby(["label", axis], sort=False):
        name = g["algorithm"].iloc[0]
        k = values.index(value)
        s = summarize(g).iloc[0]
        acc, half = _mean_ci(g["paper_accuracy"].to_numpy())
        rows.append({"label": label, "algorithm": name, unit: value, "trials": len(g), "paper_accuracy": acc,
                     "paper_accuracy_ci": half, "printed_accuracy": paper_acc.get(name, (np.nan,) * 3)[k],
                     "id_rate": s["id_rate"], "id_rate_lo": s["id_rate_lo"], "id_rate_hi": s["id_rate_hi"],
                     "misid_rate": s["misid_rate"], "time_mean_ms": s["time_mean_us"] / 1e3,
                     "printed_time_ms": paper_ms.get(name, (np.nan,) * 3)[k]})
    return pd.DataFrame(rows)


def _cell(r) -> str:
    ours = f"{r.paper_accuracy:.3f}" + (f" +-{r.paper_accuracy_ci:.3f}" if not np.isnan(r.paper_accuracy_ci) else "")
    printed = f" (paper {r.printed_accuracy:.3f})" if not np.isnan(r.printed_accuracy) else ""
    return f"{ours}{printed}; starid {rate_ci(r.id_rate, r.id_rate_lo, r.id_rate_hi)}"


def _time_cell(r) -> str:
    printed = f" (paper {r.printed_time_ms:g})" if not np.isnan(r.printed_time_ms) else ""
    return f"{r.time_mean_ms:.2f}{printed}"


def _wide(df: pd.DataFrame, unit: str, cell, heading) -> str:
    shown = df.assign(cell=[cell(r) for r in df.itertuples()])
    wide = shown.pivot(index="label", columns=unit, values="cell").reindex(index=list(dict.fromkeys(df["label"])))
    wide.columns = [heading(c) for c in wide.columns]
    return markdown(wide.reset_index())


def false_star_frame(frame: pd.DataFrame) -> pd.DataFrame:
    part = with_paper_accuracy(frame[frame["study"] == "false_stars"])
    return sweep(part, "grid_false_stars", list(FALSE_STARS), PAPER_FALSE_ACC, PAPER_FALSE_MS, "false_stars")


def noise_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """The noise study's points, with rho = 0 taken from the false-star study's 0 point (the same images)."""
    zero = frame[(frame["study"] == "false_stars") & (frame["grid_false_stars"] == 0)]
    part = with_paper_accuracy(pd.concat([zero, frame[frame["study"] == "noise"]], ignore_index=True))
    rho = {0.0: 0.0, **{sigma_px_of(r): r for r in NOISE_DEG[1:]}}
    part = part.assign(rho_deg=[rho.get(round(float(v), 9), np.nan) for v in part["grid_sigma_px"]])
    return sweep(part, "rho_deg", list(NOISE_DEG), PAPER_NOISE_ACC, PAPER_NOISE_MS, "rho_deg")


NOTE_RULES = ("Each cell: the paper's accuracy a(h) (share of the reported ids that are right, 0 when none; mean "
              "over images +- its 95 % interval), the printed value in brackets, then starid's id rate (at least 3 "
              "right ids and no wrong one) with its Wilson interval. The printed values are beside every row of "
              "the method, the paper's reading ('NAME:galvizo2018') and starid's defaults alike.")
NOTE_TIME = ("The paper's times are C++ compiled at -O0 querying an SQLite catalog on an i7-7700; only the "
             "ordering compares (times here are per image, the machine's load included).")


def setup_table(experiment: Experiment) -> Table:
    camera = experiment.make_camera()
    rows = [("source", f"glennga/hoku @ {HOKU_COMMIT}: doc/arxiv-paper.tex, doc/include/floats/*.tex"),
            ("field", f"paper: cone of {PAPER_FOV_DEG:g} deg; here: {FOV_DEG:g} x {FOV_DEG:g} deg square of the "
                      f"same solid angle, {camera.width_px} px"),
            ("stars", "paper: Hipparcos m < 6.0, all imaged, at least 5; here: sky and detection V <= 6.0, "
                      "no magnitude noise, no merging, at least 5"),
            ("noise", "paper: each star moved N(0, rho^2) deg on a random great circle; here: centroid noise "
                      + ", ".join(f"{sigma_px_of(r):.4g} px for rho {r:g} deg" for r in NOISE_DEG[1:])
                      + " (same mean square displacement)"),
            ("false stars", "uniform in the field: 0 / 6 / 12"),
            ("methods", coverage_line())]
    df = pd.DataFrame(rows, columns=["item", "set-up"])
    return Table("galvizo_setup", "Set-up (paper's Section IV) and the methods present", df, markdown(df))


def false_table(frame: pd.DataFrame) -> list[Table]:
    df = false_star_frame(frame)
    acc = _wide(df, "false_stars", _cell, lambda c: f"{c} false stars")
    ms = _wide(df, "false_stars", _time_cell, lambda c: f"{c} false stars (ms)")
    return [Table("galvizo_false_acc", "Accuracy vs false stars (no noise)", df, acc, (NOTE_RULES,)),
            Table("galvizo_false_time", "Mean time vs false stars (no noise)", df, ms, (NOTE_TIME,))]


def noise_table(frame: pd.DataFrame) -> list[Table]:
    df = noise_frame(frame)
    acc = _wide(df, "rho_deg", _cell, lambda c: f"rho = {c:g} deg")
    ms = _wide(df, "rho_deg", _time_cell, lambda c: f"rho = {c:g} deg (ms)")
    note = ("The paper's methods use fixed query windows (ANG / PYR sigma_theta = 1e-4 deg, INT 1e-2 deg, "
            "SPH / PLN / COM sigma_a = sigma_tau = 1e-9), so at rho = 1e-2 deg most of them find nothing "
            "(Pyramid and Composite Pyramid print 0): an artefact of the tolerances the paper chose, which its "
            "readings keep; starid's defaults size their windows from the simulator's noise.")
    return [Table("galvizo_noise_acc", "Accuracy vs Gaussian noise (no false stars)", df, acc, (NOTE_RULES, note)),
            Table("galvizo_noise_time", "Mean time vs Gaussian noise (no false stars)", df, ms, (NOTE_TIME,))]


#: The work counters every galvizo2018 plugin reports about its first query step (the image pair or
#: trio it queries first, brightest first): ``first_R`` = |R|, ``first_named`` = 1 when the
#: identification names every star of that subset, ``first_in_R`` = 1 when R holds the catalog set the
#: identification gives them.
FIRST_QUERY = ("n_first_R", "n_first_named", "n_first_in_R")


def first_query(g: pd.DataFrame) -> tuple[float, float, int, int]:
    """Our f and S from the first-query counters of one reading's rows (NaN when it reports none).

    f: of the images identified with no wrong id that name every star of the first queried subset (so
    that subset's right catalog set is known), the share whose first R held it; S: the share of images
    whose first R had exactly one member, scaled to the paper's 2,000 runs. Also returns both counts."""
    if not set(FIRST_QUERY) <= set(g.columns) or g["n_first_R"].isna().all():
        return np.nan, np.nan, 0, 0
    good = (g["n_wrong"] == 0) & (g["n_correct"] > 0) & (g["n_first_named"] == 1)
    f = float(g.loc[good, "n_first_in_R"].mean()) if good.any() else np.nan
    known = g["n_first_R"].notna()
    s = float((g.loc[known, "n_first_R"] == 1).mean() * 2000)
    return f, s, int(good.sum()), int(known.sum())


#: hoku's query step as :func:`query_table` runs it: queries per method and catalog stars (the paper's).
HOKU_QUERIES = 2000
HOKU_STARS = 4560


def hoku_step(seed: int = 0) -> pd.DataFrame:
    """hoku's query step (:func:`starid.experiments.hoku_query.query_step`) at ``seed``: one row per method."""
    from ..catalog import load_hipparcos
    from .hoku_query import query_step

    return query_step(load_hipparcos(), HOKU_QUERIES, seed, HOKU_STARS)


def _pm(v: float, ci: float, digits: int) -> str:
    return "" if np.isnan(v) else f"{v:.{digits}f} +-{ci:.{digits}f}"


def query_table(frame: pd.DataFrame, seed: int = 0, hoku: pd.DataFrame | None = None) -> Table:
    """The query step's printed figures (no noise) beside hoku's step redone here (:func:`hoku_step` at
    ``seed``, or ``hoku`` when given) and our first query on the same images."""
    hoku = hoku_step(seed) if hoku is None else hoku
    by_name = {PAPER_METHODS[m]: r for m, r in hoku.set_index("method").iterrows() if m in PAPER_METHODS}
    part = frame[(frame["study"] == "false_stars") & (frame["grid_false_stars"] == 0)]
    counters = [c for c in part.columns if c.startswith("n_") and c not in
                ("n_identified", "n_correct", "n_wrong", "n_true_stars", "n_stars", "n_false", "n_lost", "n_redraws")
                and c not in FIRST_QUERY]
    rows = []
    for label, g in part.groupby("label", sort=False):
        name = g["algorithm"].iloc[0]
        f, s, t = PAPER_QUERY.get(name, (np.nan, np.nan, np.nan))
        h = by_name.get(name)
        our_f, our_s, n_f, n_s = first_query(g)
        work = {c[2:]: float(g[c].mean()) for c in counters if g[c].notna().any()}
        rows.append({"label": label, "algorithm": name, "trials": len(g), "paper_f_correct_in_R": f,
                     "hoku_f": np.nan if h is None else h["f"], "hoku_f_ci95": np.nan if h is None else h["f_ci95"],
                     "f_ours": our_f, "f_images": n_f, "paper_S_of_2000": s,
                     "hoku_S_of_2000": np.nan if h is None else h["S_rows"],
                     "hoku_S_ci95": np.nan if h is None else h["S_rows_ci95"], "S_ours_of_2000": our_s,
                     "paper_query_ms": t, "time_mean_ms": float(g["time_us"].mean() / 1e3),
                     "work_counters": ", ".join(f"{k} {v:.1f}" for k, v in work.items())})
    df = pd.DataFrame(rows)
    shown = df.assign(**{c: df[c].map(lambda v: "" if np.isnan(v) else f"{v:g}")
                         for c in ("paper_f_correct_in_R", "paper_S_of_2000", "paper_query_ms")},
                      hoku_f=[_pm(v, c, 3) for v, c in zip(df["hoku_f"], df["hoku_f_ci95"], strict=True)],
                      hoku_S_of_2000=[_pm(v, c, 0) for v, c in zip(df["hoku_S_of_2000"], df["hoku_S_ci95"],
                                                                   strict=True)],
                      f_ours=df["f_ours"].map(lambda v: "" if np.isnan(v) else f"{v:.3f}"),
                      S_ours_of_2000=df["S_ours_of_2000"].map(lambda v: "" if np.isnan(v) else f"{v:.0f}"),
                      time_mean_ms=df["time_mean_ms"].map(lambda v: f"{v:.2f}")).drop(columns=["hoku_f_ci95",
                                                                                               "hoku_S_ci95"])
    n_q = int(hoku["n_queries"].iloc[0]) if len(hoku) else 0
    notes = ("f: the share of query steps whose candidates R hold the right catalog set; S: the number with "
             "|R| = 1, of 2,000. paper_*: printed (hoku's query experiment: a random 2 or 3 stars of a 10 deg "
             "cone field, the method's own query and table, the paper's fixed windows). hoku_*: that step redone "
             f"here ({n_q:,} queries per method on the brightest {HOKU_STARS:,} stars with V < 6, seed {seed}, "
             "+- 95 %; starid.experiments.hoku_query), the paper's method whatever the row's reading. f_ours / "
             "S_ours: each image's first query step (its brightest pair or trio; PLN the start triangle of its "
             "first chain) from the plugins' first-query counters; f_ours among the images identified with no "
             "wrong id that name that subset (f_images); blank when the plugin reports no such counters. The "
             "paper's time is per query step, starid's per identification. See docs/experiments.md, "
             "\"The query table\".",)
    return Table("galvizo_query", "Query step (no noise, no false stars): printed figures beside ours", df,
                 markdown(shown), notes)


def _access_point(frame: pd.DataFrame, point: str) -> pd.DataFrame:
    """The rows of one point of :data:`PAPER_ACCESSES` (the false-star point pools 6 and 12 false stars)."""
    if point in ("no noise", "false stars"):
        part = frame[frame["study"] == "false_stars"]
        zero = part["grid_false_stars"] == 0
        return part[zero] if point == "no noise" else part[~zero]
    rho = {"rho 1e-4 deg": 1e-4, "rho 1e-2 deg": 1e-2}[point]
    part = frame[frame["study"] == "noise"]
    return part[np.isclose(part["grid_sigma_px"].astype(float), sigma_px_of(rho))]


def access_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """hoku's catalog-access counts beside the printed ones (:data:`PAPER_ACCESSES`): per printed value,
    one row per label of its method whose rows carry the counter, the counts capped as hoku logs them
    (at :data:`ACCESS_LIMIT` + 1)."""
    rows = []
    for what, method, point, printed, printed_runs in PAPER_ACCESSES:
        column = ACCESS_H.get(method) if what == "h" else "n_to_r"
        part = _access_point(frame, point)
        for label, g in part[part["algorithm"] == method].groupby("label", sort=False):
            if column is None or column not in g.columns or g[column].isna().all():
                continue
            x = np.minimum(g[column].dropna().to_numpy(dtype=float), ACCESS_LIMIT + 1)
            n_images = x.size
            if printed_runs is not None:
                x = x[x > 1]
            mean, half = _mean_ci(x)
            rows.append({"label": label, "algorithm": method, "accesses_to": what, "point": point,
                         "paper_mean": printed, "mean": mean, "mean_ci95": half, "images": n_images,
                         "paper_runs_of_2000": np.nan if printed_runs is None else float(printed_runs),
                         "runs_of_2000": np.nan if printed_runs is None else x.size / n_images * 2000})
    return pd.DataFrame(rows, columns=["label", "algorithm", "accesses_to", "point", "paper_mean", "mean",
                                       "mean_ci95", "images", "paper_runs_of_2000", "runs_of_2000"])


def access_table(frame: pd.DataFrame) -> Table:
    """The catalog-access counts the text prints, beside ours on hoku's definition of an access."""
    df = access_frame(frame)
    shown = df.assign(mean=[_pm(v, c, 2) for v, c in zip(df["mean"], df["mean_ci95"], strict=True)],
                      paper_runs_of_2000=df["paper_runs_of_2000"].map(lambda v: "" if np.isnan(v) else f"{v:.0f}"),
                      runs_of_2000=df["runs_of_2000"].map(lambda v: "" if np.isnan(v) else f"{v:.0f}")
                      ).drop(columns=["mean_ci95"])
    notes = ("An access is one catalog query as hoku counts it (its counter nu): for ANG an image pair tried, "
             "for SPH / PLN / COM a trio queried, each pivot's query included. h: the accesses of a whole "
             "identification (ANG: the image pairs it tried); r: those up to the first query that left exactly "
             "one candidate set, pivoting included (hoku's reduction experiment; every query made when none "
             f"did). Counts are capped at {ACCESS_LIMIT + 1}, as hoku logs a run stopped by its "
             f"{ACCESS_LIMIT}-access limit. 'r, count > 1' (Fig. rPivot): the mean over the runs that needed "
             "more than one access, and how many there are (scaled to 2,000). The false-star row pools 6 and 12 "
             "false stars (the text's mean is over 3 / 6 / 9 / 12). Mean +- its 95 % interval. See "
             "docs/experiments.md, \"The catalog-access counts\".",)
    return Table("galvizo_access", "Catalog accesses: printed beside ours", df, markdown(shown), notes)


def paper_points() -> pd.DataFrame:
    """The printed accuracies: ``study, axis, value, algorithm, paper_id_rate`` (the paper's rule, not starid's)."""
    rows = [{"study": "false_stars", "axis": "false_stars", "value": v, "algorithm": a, "paper_id_rate": r[k]}
            for a, r in PAPER_FALSE_ACC.items() for k, v in enumerate(FALSE_STARS)]
    rows += [{"study": "noise", "axis": "sigma_px", "value": sigma_px_of(v), "algorithm": a, "paper_id_rate": r[k]}
             for a, r in PAPER_NOISE_ACC.items() for k, v in enumerate(NOISE_DEG)]
    return pd.DataFrame(rows, columns=["study", "axis", "value", "algorithm", "paper_id_rate"])


def tables(frame: pd.DataFrame, experiment: Experiment) -> list[Table]:
    return [setup_table(experiment), *false_table(frame), *noise_table(frame),
            query_table(frame, experiment.seed), access_table(frame)]
