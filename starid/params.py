"""Parameter checks shared by the simulator and every algorithm: one rule, one wording.

Each check raises :class:`starid.errors.ConfigError` naming the parameter, the rule and the
value it got. Booleans are not numbers here (``True`` is no valid ``sigma_px``).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_number(name: str, value, lo: float = -math.inf, hi: float = math.inf, lo_open: bool = False,
                 hi_open: bool = False) -> None:
    """A finite number in the interval from ``lo`` to ``hi`` (each end closed unless ``*_open``)."""
    ok = _is_number(value) and math.isfinite(value)
    if ok:
        ok = (value > lo if lo_open else value >= lo) and (value < hi if hi_open else value <= hi)
    if not ok:
        rule = []
        if lo > -math.inf:
            rule.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi < math.inf:
            rule.append(f"{'<' if hi_open else '<='} {hi:g}")
        raise ConfigError(f"{name} must be a finite number{' ' + ' and '.join(rule) if rule else ''}, got {value!r}")


def check_whole(name: str, value, lo: int, hi: int | None = None) -> None:
    """An integer (not a float, not a bool) with ``lo <= value`` (and ``value <= hi``)."""
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        upper = "" if hi is None else f" and <= {hi}"
        raise ConfigError(f"{name} must be an integer >= {lo}{upper}, got {value!r}")


def check_flag(name: str, value) -> None:
    """True or False."""
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{name} must be True or False, got {value!r}")


def check_choice(name: str, value, choices) -> None:
    """One of ``choices``."""
    if value not in choices:
        raise ConfigError(f"{name} must be one of {tuple(choices)}, got {value!r}")


def param(default, *, help: str = "", unit: str = ""):
    """An algorithm parameter: a dataclass field with its default and, for ``starid info`` and the
    docs, its meaning (``help``, one sentence) and unit (``unit``, e.g. ``"px"``, ``"deg"``; ``""``
    for a count or flag). Without them ``info`` falls back to the conventions of docs/plugins.md
    (the unit from the name's suffix, the meaning from the class docstring's sentence naming the
    parameter in double back-quotes)::

        n_bright: int = param(8, help="stars of the image that vote, brightest first")
        d_max_deg: float = param(6.0, help="largest pair separation stored", unit="deg")
    """
    import dataclasses

    return dataclasses.field(default=default, metadata={"help": help, "unit": unit})


def integer_columns(frames, prefix: str = "param_") -> set[str]:
    """The ``prefix`` columns that hold integers in every frame that has them (a bool is no integer)."""
    seen: dict[str, bool] = {}
    for df in frames:
        for col in df.columns:
            if col.startswith(prefix):
                kind = df[col].dtype.kind
                seen[col] = seen.get(col, True) and kind in "iu"
    return {col for col, ok in seen.items() if ok}


def keep_integers(frame, columns):
    """``frame`` with ``columns`` as nullable integers (``Int64``): concatenating the rows of algorithms
    that lack a parameter fills it with NaN and turns its integers into floats (``param_n_bright = 8.0``);
    here they stay ``8`` in the frame, the CSV and the Parquet files, blank where the algorithm has none."""
    cast = [c for c in columns if c in frame.columns and frame[c].dtype.kind == "f"]
    if not cast:
        return frame
    import pandas as pd

    # one new frame, not a column at a time: hundreds of in-place casts fragment it (pandas warns)
    return pd.concat([frame.drop(columns=cast), frame[cast].astype("Int64")], axis=1)[frame.columns]
