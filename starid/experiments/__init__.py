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

from ..errors import ConfigError
from ..registry import available_algorithms

MODULES = ("table6", "zhou2015")


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
