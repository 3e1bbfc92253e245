"""Which pictures a results folder gets, and writing them as PNG + SVG.

:func:`report_figures` picks, for a trial-row frame of any experiment:

* a rate curve per swept axis per study (an axis with more than one value), with the paper's
  printed points where the experiment module has them (``paper_points()``);
* at the *main condition* (the study point that runs the most different algorithms; the first
  such): identify-time distributions, the rate-vs-time / rate-vs-memory trade-off and the
  pairwise McNemar matrix;
* the star-count histogram (Fig. 10), one outline per sky when a study sweeps the sky, and the
  rate by stars in the field (Fig. 11).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from .. import plots
from ..stats import summarize


@dataclass(eq=False)
class ReportFigure:
    """One picture of a report: ``name`` is its file stem under ``figures/``."""

    name: str
    title: str
    caption: str
    figure: Figure


def label_order(frame: pd.DataFrame) -> list[str]:
    """Labels by the number of studies they run in (most first), then first appearance: the
    algorithms compared everywhere get the first (plainest) styles."""
    first = list(dict.fromkeys(frame["label"]))
    count = frame.groupby("label")["study"].nunique()
    return sorted(first, key=lambda x: (-count[x], first.index(x)))


def grid_axes(frame: pd.DataFrame) -> list[str]:
    """The swept axes of a frame (``grid_<axis>`` columns with more than one value), as axis names."""
    return [c[5:] for c in frame.columns if c.startswith("grid_") and frame[c].nunique(dropna=True) > 1]


def _where(frame: pd.DataFrame) -> str:
    study = frame["study"].iloc[0]
    grid = [c for c in frame.columns if c.startswith("grid_") and frame[c].notna().any()]
    vals = ", ".join(f"{c[5:]} = {frame[c].iloc[0]}" for c in grid)
    return f"study {study}" + (f", {vals}" if vals else "")


def main_condition(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows of the study point with the most distinct algorithms (then the most labels; first wins)."""
    stats = frame.groupby(["study", "point"], sort=False).agg(names=("algorithm", "nunique"),
                                                               labels=("label", "nunique")).reset_index()
    best = stats.sort_values(["names", "labels"], ascending=False, kind="stable").iloc[0]
    part = frame[(frame["study"] == best["study"]) & (frame["point"] == best["point"])]
    return part.dropna(axis=1, how="all")


def report_figures(frame: pd.DataFrame, paper: pd.DataFrame | None = None, paper_fig10: dict | None = None,
                   paper_name: str = "paper") -> list[ReportFigure]:
    """Every picture of the report of ``frame`` (see the module docstring)."""
    styles = plots.label_styles(label_order(frame))
    out: list[ReportFigure] = []
    for study, part in frame.groupby("study", sort=False):
        part = part.dropna(axis=1, how="all")
        for axis in grid_axes(part):
            pts = None
            if paper is not None and len(paper):
                pts = paper[(paper["study"] == study) & (paper["axis"] == axis)]
            title = f"{study}: identification rate vs {plots.axis_name(axis)}"
            n = part["trial"].nunique()
            fixed = _fixed(part, axis)
            caption = (f"Study {study}: share of images correctly identified at each {axis} value ({n} images per "
                       f"point, the same attitudes at every point), one line per algorithm label with its 95 % "
                       f"Wilson band" + (f"; {fixed}" if fixed else "") +
                       ("; large open markers: the paper's printed values" if pts is not None and len(pts) else "")
                       + ".")
            out.append(ReportFigure(f"rate_{_slug(study)}_{_slug(axis)}", title, caption,
                                    plots.rate_curve(part, axis, pts, title, styles, paper_name)))
    main = main_condition(frame)
    where = _where(main)
    n = main["trial"].nunique()
    out.append(ReportFigure(
        "time", "Identify time per image",
        f"Identify time per image at the main condition ({where}; {n} images), log scale: box 25-75 %, whiskers "
        f"5-95 %, dots beyond; the median printed above each box. Times are noisy on a shared machine: compare "
        f"ratios within one run.", plots.time_distributions(main, f"identify time per image ({where})", styles)))
    summary = summarize(main)
    out.append(ReportFigure(
        "tradeoff", "Rate vs time and vs memory",
        f"Trade-off at the main condition ({where}): identification rate (95 % Wilson interval) against the median "
        f"identify time and against the database size the identify step reads.",
        plots.tradeoff(summary, f"trade-off ({where})", styles)))
    if main["label"].nunique() > 1:
        out.append(ReportFigure(
            "mcnemar", "Pairwise McNemar tests",
            f"McNemar's exact test for every pair of labels on the same {n} images ({where}): each cell is row A's "
            f"rate minus column B's in percentage points with its p-value; bold with * where p < 0.05; darker "
            f"cells are more significant. The diagonal gives each label's rate.",
            plots.mcnemar_matrix(main, f"McNemar on the same images ({where})")))
    hist_rows, by = _histogram_rows(frame, main)
    out.append(ReportFigure(
        "stars", "Stars in the field (Fig. 10)",
        "How many true stars each image holds (one count per image; the dotted line is at 8.5 stars)"
        + (", one outline per sky" if by else f" ({_where(hist_rows)})")
        + ("; the paper's Fig. 10 statistics in the legend" if paper_fig10 else "") + ".",
        plots.star_histogram(hist_rows, by, paper_fig10, "stars in the field of view")))
    out.append(ReportFigure(
        "rate_by_stars", "Rate vs stars in the field (Fig. 11)",
        f"Identification rate by the number of true stars in the image ({_where(hist_rows) if not by else where}), "
        f"with 95 % Wilson intervals; bins with few images have wide intervals.",
        plots.rate_by_stars(main if by else hist_rows, title="rate vs stars in the field", styles=styles)))
    return out


def _histogram_rows(frame: pd.DataFrame, main: pd.DataFrame) -> tuple[pd.DataFrame, str | None]:
    """A study sweeping only the sky gives one histogram per sky (a study named ``fig10`` first: the
    star counts as Fig. 10 counts them); else the main condition."""
    if "grid_sky" in frame.columns:
        studies = sorted(frame.groupby("study", sort=False), key=lambda item: item[0] != "fig10")
        for _study, part in studies:
            if part["grid_sky"].nunique() > 1 and grid_axes(part) == ["sky"]:
                return part, "grid_sky"
    return main, None


def _fixed(part: pd.DataFrame, axis: str) -> str:
    cols = [c for c in part.columns if c.startswith("grid_") and c != f"grid_{axis}" and part[c].nunique() == 1]
    return ", ".join(f"{c[5:]} = {part[c].iloc[0]}" for c in cols)


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in str(text)).strip("_") or "x"


def save(figures: list[ReportFigure], folder: Path, svg: bool = True) -> list[Path]:
    """Each figure as ``folder/<name>.png`` (150 dpi) and ``.svg``; the PNG paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for f in figures:
        png = folder / f"{f.name}.png"
        f.figure.savefig(png, dpi=150, facecolor="white", bbox_inches="tight", pad_inches=0.1)
        if svg:
            f.figure.savefig(folder / f"{f.name}.svg", facecolor="white")
        paths.append(png)
    return paths
