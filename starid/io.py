"""Atomic output: a file is either fully written or not there at all."""

from __future__ import annotations

import csv
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same folder and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def write_frame(df: pd.DataFrame, path: str | Path) -> list[Path]:
    """Write ``df`` as CSV at ``path`` and, if pyarrow is installed, as Parquet beside it."""
    path = Path(path)
    atomic_write_text(path, df.to_csv(index=False, lineterminator="\n"))
    written = [path]
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return written
    pq = path.with_suffix(".parquet")
    atomic_write_bytes(pq, df.to_parquet(index=False))
    written.append(pq)
    return written


def read_numeric_csv(path: str | Path, required: list, optional: tuple[str, ...] = (),
                     error: type[Exception] = ValueError, lower: bool = False):
    """Read numeric columns of a CSV file with a header, refusing bad input line by line.

    ``required`` names the columns that must be there; an entry may be a tuple of alternative
    names (the first present is used). Returns ``(columns, lines)``: ``columns`` maps each found
    name (required first, then present optional ones) to a float64 array, ``lines`` holds each
    row's line number in the file, for later checks to cite. Raises ``error`` naming the file
    and line for a missing column, a wrong field count, a non-numeric, NaN or infinite value.
    """
    path = Path(path)
    try:
        fh = path.open(newline="")
    except OSError as exc:
        raise error(f"cannot read {path}: {exc.strerror}") from None
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() if lower else h.strip() for h in next(reader)]
        except StopIteration:
            raise error(f"{path}: empty file, expected a header line") from None
        names, missing = [], []
        for entry in required:
            options = entry if isinstance(entry, tuple) else (entry,)
            found = next((c for c in options if c in header), None)
            (names if found else missing).append(found or " or ".join(options))
        if missing:
            raise error(f"{path}, line 1: missing column(s) {', '.join(missing)}; header is {header}")
        names += [c for c in optional if c in header]
        index = [header.index(c) for c in names]
        rows, lines = [], []
        for lineno, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise error(f"{path}, line {lineno}: expected {len(header)} fields, got {len(row)}")
            try:
                values = [float(row[i]) for i in index]
            except ValueError:
                raise error(f"{path}, line {lineno}: non-numeric value in {row}") from None
            if not all(np.isfinite(values)):
                raise error(f"{path}, line {lineno}: NaN or infinite value in {row}")
            rows.append(values)
            lines.append(lineno)
    table = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(names))
    return {name: table[:, k] for k, name in enumerate(names)}, np.asarray(lines, dtype=np.int64)
