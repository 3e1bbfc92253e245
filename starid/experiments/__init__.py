"""Built-in experiments: published comparisons as data, each with its paper's printed values.

Each module defines ``NAME``, ``TITLE``, ``DESCRIPTION``, ``DEFAULT_TRIALS``,
``experiment(trials, seed)`` (an :class:`~starid.experiment.Experiment`), ``tables(frame,
experiment)`` (a list of :class:`~starid.report.tables.Table`, every measured value beside the
paper's where it prints one) and ``paper_points()`` (the paper's printed points of its swept
figures, for plots: ``study, axis, value, algorithm, paper_id_rate``).
``starid experiment list`` names them; ``starid reproduce NAME`` runs one.
"""

from __future__ import annotations

from importlib import import_module

import numpy as np
import pandas as pd

from ..errors import ConfigError
from ..registry import available_algorithms
from ..report.tables import Table, markdown, pct, rate_ci
from ..stats import summarize

MODULES = ("table6", "zhou2015", "luo2015", "galvizo2018", "realism", "cameras")


def get(name: str):
    """The experiment module called ``name``."""
    if name not in MODULES:
        raise ConfigError(f"unknown experiment {name!r}; built-in: {', '.join(MODULES)} (see 'starid experiment list')")
    return import_module(f".{name}", __name__)


def all_experiments():
    return [get(n) for n in MODULES]


def registered_beyond(paper: tuple[str, ...]) -> tuple[str, ...]:
    """Every working registered algorithm not in ``paper`` (the "beyond the paper" rows), by name."""
    return tuple(i.name for i in available_algorithms() if i.status == "ok" and i.name not in paper)


def rate_cells(s: pd.DataFrame) -> list[str]:
    """Each summary row's id rate with its interval, and the paper's (``paper_id_rate``) beside where it gives one."""
    return [rate_ci(r, lo, hi) + (f" (paper {pct(p)})" if not np.isnan(p) else "")
            for r, lo, hi, p in zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], s["paper_id_rate"], strict=True)]


def sweep_table(frame: pd.DataFrame, study: str, axis: str, paper: dict, unit: str, title: str,
                name: str) -> Table:
    """Id rate (with its interval) of every label at every value of ``axis`` in ``study``; the
    paper's printed ``{(value, algorithm): rate}`` beside ours where it gives one."""
    part = frame[frame["study"] == study]
    s = summarize(part, by=(f"grid_{axis}", "label")).rename(columns={f"grid_{axis}": axis})
    s["paper_id_rate"] = [paper.get((float(v), a), np.nan) for v, a in zip(s[axis], s["algorithm"], strict=True)]
    cells = s.assign(cell=rate_cells(s))
    wide = cells.pivot(index="label", columns=axis, values="cell").reindex(index=list(dict.fromkeys(s["label"])))
    wide.columns = [f"{unit} = {c:g}" for c in wide.columns]
    return Table(name, title, s, markdown(wide.reset_index()))


def sweep_points(sweeps: dict) -> pd.DataFrame:
    """A module's ``SWEEPS`` (name -> (axis, values, fixed, paper, unit)) as paper points for plots."""
    rows = []
    for name, (axis, _, _, paper, _) in sweeps.items():
        rows += [{"study": name, "axis": axis, "value": v, "algorithm": a, "paper_id_rate": r}
                 for (v, a), r in paper.items()]
    return pd.DataFrame(rows, columns=["study", "axis", "value", "algorithm", "paper_id_rate"])
