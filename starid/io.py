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


#: CSV rows per forked process at least: a frame of twice as many rows or more is formatted in slices
PARALLEL_CSV_ROWS = 50_000
_CSV_FRAME: dict = {}       # the frame the forked processes of frame_csv format slices of


def _csv_rows(bounds: tuple[int, int]) -> str:
    start, stop = bounds
    return _CSV_FRAME["df"].iloc[start:stop].to_csv(index=False, header=start == 0, lineterminator="\n")


def frame_csv(df: pd.DataFrame) -> str:
    """``df.to_csv(index=False, lineterminator="\\n")``: a large frame's rows are formatted in slices by forked
    processes, one per core, and joined -- the same text (pandas formats each value on its own), in about half the
    time on two cores (Table 6's ``trials.csv``, 280,000 rows x 245 columns: 13.9 -> 8.6 s), where the parent
    would otherwise format alone with the engine's workers done. Without ``fork``, in a daemonic process or for
    a small frame: one ``to_csv``."""
    import multiprocessing as mp

    jobs = min(os.cpu_count() or 1, len(df) // PARALLEL_CSV_ROWS)
    if jobs < 2 or "fork" not in mp.get_all_start_methods() or mp.current_process().daemon:
        return df.to_csv(index=False, lineterminator="\n")
    bounds = np.linspace(0, len(df), jobs + 1).astype(np.int64).tolist()
    _CSV_FRAME["df"] = df        # before the fork: the processes read it, nothing is pickled to them
    try:
        with mp.get_context("fork").Pool(jobs) as pool:
            return "".join(pool.map(_csv_rows, list(zip(bounds[:-1], bounds[1:], strict=True))))
    finally:
        _CSV_FRAME.clear()


def write_frame(df: pd.DataFrame, path: str | Path) -> list[Path]:
    """Write ``df`` as CSV at ``path`` (:func:`frame_csv`) and, if pyarrow is installed, as Parquet beside it."""
    path = Path(path)
    atomic_write_text(path, frame_csv(df))
    written = [path]
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return written
    pq = path.with_suffix(".parquet")
    atomic_write_bytes(pq, df.to_parquet(index=False))
    written.append(pq)
    return written


def write_frames(folder: str | Path, frames: dict, remove: list[str] | tuple = ()) -> list[Path]:
    """Write several frames as one set: every file is staged first, then all are renamed into place,
    and ``remove`` (files a previous run may have left that would now be inconsistent) deleted."""
    folder = Path(folder)
    written = []
    for name, df in frames.items():
        written += write_frame(df, folder / name)
    for name in remove:
        (folder / name).unlink(missing_ok=True)
    return written


#: Longest CSV field accepted (a catalog or centroid value is a few dozen characters).
MAX_FIELD_CHARS = 10_000


def _open_text(path: Path, error):
    """Open a CSV as text: a UTF-8 BOM is read, binary or compressed files are refused."""
    try:
        head = path.open("rb").read(4096)
    except OSError as exc:
        raise error(f"cannot read {path}: {exc.strerror or exc}") from None
    if b"\0" in head or head[:2] == b"\x1f\x8b" or head[:4] == b"PK\x03\x04":
        raise error(f"{path}: not a text CSV file (binary, gzip or zip/npz content)")
    return path.open(newline="", encoding="utf-8-sig")


def _integer(text: str):
    """``text`` as an exact integer (``"12"``, ``"12.0"``, ``"1e3"``), or ``None`` when it is not one."""
    t = text.strip()
    try:
        return int(t)
    except ValueError:
        pass
    try:
        value = float(t)
    except ValueError:
        return None
    if not np.isfinite(value) or value != int(value) or abs(value) >= 2**53:
        return None
    return int(value)


def read_numeric_csv(path: str | Path, required: list, optional: tuple[str, ...] = (),
                     error: type[Exception] = ValueError, lower: bool = False, integer: tuple[str, ...] = ()):
    """Read numeric columns of a CSV file with a header, refusing bad input line by line.

    ``required`` names the columns that must be there; an entry may be a tuple of alternative
    names (the first present is used). Returns ``(columns, lines)``: ``columns`` maps each found
    name (required first, then present optional ones) to a float64 array -- int64 for the names
    in ``integer``, parsed exactly (no rounding through floats; values outside int64 refused) --
    and ``lines`` holds each row's line number in the file, for later checks to cite. Raises
    ``error`` naming the file and line for a missing column, a wrong field count, a non-numeric,
    non-integer, NaN or infinite value, an over-long field, or content that is not text.
    """
    path = Path(path)
    fh = _open_text(path, error)
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip().lower() if lower else h.strip() for h in next(reader)]
        except StopIteration:
            raise error(f"{path}: empty file, expected a header line") from None
        except (csv.Error, UnicodeDecodeError) as exc:
            raise error(f"{path}, line 1: not a readable CSV header ({exc})") from None
        names, missing = [], []
        for entry in required:
            options = entry if isinstance(entry, tuple) else (entry,)
            found = next((c for c in options if c in header), None)
            (names if found else missing).append(found or " or ".join(options))
        if missing:
            raise error(f"{path}, line 1: missing column(s) {', '.join(missing)}; header is {header}")
        names += [c for c in optional if c in header]
        index = [header.index(c) for c in names]
        is_int = [n in integer for n in names]
        columns: list[list] = [[] for _ in names]
        lines = []
        lineno = 1
        try:
            for lineno, row in enumerate(reader, start=2):
                if not row or all(not cell.strip() for cell in row):
                    continue
                if len(row) != len(header):
                    raise error(f"{path}, line {lineno}: expected {len(header)} fields, got {len(row)}")
                if any(len(cell) > MAX_FIELD_CHARS for cell in row):
                    raise error(f"{path}, line {lineno}: a field is longer than {MAX_FIELD_CHARS:,} characters")
                for k, i in enumerate(index):
                    cell = row[i]
                    if is_int[k]:
                        value = _integer(cell)
                        if value is None or not -2**63 <= value < 2**63:
                            raise error(f"{path}, line {lineno}: {names[k]} must be a whole number that fits in "
                                        f"64 bits, got {cell.strip()!r}")
                    else:
                        try:
                            value = float(cell)
                        except ValueError:
                            raise error(f"{path}, line {lineno}: non-numeric {names[k]} {cell.strip()[:40]!r}") \
                                from None
                        if not np.isfinite(value):
                            raise error(f"{path}, line {lineno}: NaN or infinite {names[k]}")
                    columns[k].append(value)
                lines.append(lineno)
        except csv.Error as exc:
            raise error(f"{path}, line {lineno + 1}: unreadable CSV ({exc})") from None
        except UnicodeDecodeError:
            raise error(f"{path}, after line {lineno}: not UTF-8 text") from None
    out = {name: np.asarray(col, dtype=np.int64 if is_int[k] else np.float64)
           for k, (name, col) in enumerate(zip(names, columns, strict=True))}
    return out, np.asarray(lines, dtype=np.int64)
