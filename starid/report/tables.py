"""Tables from result frames: a titled DataFrame and its Markdown, written as CSV + Markdown."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from ..io import atomic_write_text, write_frame


@dataclass(frozen=True, eq=False)
class Table:
    """One table of an experiment: ``frame`` holds the numbers, ``markdown`` their printed form."""

    name: str
    title: str
    frame: pd.DataFrame
    markdown: str
    notes: tuple = field(default_factory=tuple)

    def text(self) -> str:
        notes = "".join(f"\n{n}\n" for n in self.notes)
        return f"### {self.title}\n\n{self.markdown}{notes}"


def setting(v) -> str:
    """A setting's value as a report prints it: ``none`` for missing, floats with ``g``."""
    if v is None or v is pd.NA or (isinstance(v, float) and math.isnan(v)):
        return "none"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def pct(x, digits: int = 2) -> str:
    """``0.9679 -> '96.79%'``; blank for a missing value."""
    if x is None or (isinstance(x, float) and math.isnan(x)) or x is pd.NA:
        return ""
    return f"{100 * float(x):.{digits}f}%"


def rate_ci(rate, lo, hi) -> str:
    return f"{pct(rate)} [{pct(lo)}, {pct(hi)}]" if pct(rate) else ""


def markdown(df: pd.DataFrame) -> str:
    """A DataFrame of already formatted cells as a Markdown table."""
    cols = [str(c) for c in df.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join("" if v is None else str(v) for v in row) + " |")
    return "\n".join(lines) + "\n"


def p_value(p: float) -> str:
    return f"{p:.3g}" if p > 0 else "< 1e-300"


def mcnemar_markdown(tests: pd.DataFrame) -> str:
    shown = pd.DataFrame({"A": tests["a"], "B": tests["b"], "only A correct": tests["only_a_correct"],
                          "only B correct": tests["only_b_correct"], "p-value": tests["p_value"].map(p_value)})
    return markdown(shown)


def write_tables(tables: list[Table], folder: Path, header: str) -> str:
    """Each table as ``folder/tables/<name>.csv`` and ``.md``; returns the whole text (header + tables)."""
    out = folder / "tables"
    for t in tables:
        write_frame(t.frame, out / f"{t.name}.csv")
        atomic_write_text(out / f"{t.name}.md", t.text())
    return header + "\n\n" + "\n".join(t.text() for t in tables)
