import os

import pandas as pd
import pytest

from starid.io import atomic_write_text, write_frame


def test_atomic_write_replaces_and_leaves_no_temp(tmp_path):
    path = tmp_path / "a.txt"
    atomic_write_text(path, "one")
    atomic_write_text(path, "two")
    assert path.read_text() == "two"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_failed_write_keeps_old_file(tmp_path, monkeypatch):
    path = tmp_path / "a.txt"
    atomic_write_text(path, "old")

    def boom(*args):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        atomic_write_text(path, "new")
    assert path.read_text() == "old"
    assert os.listdir(tmp_path) == ["a.txt"]


def test_write_frame_csv_and_parquet(tmp_path):
    df = pd.DataFrame({"a": [1, 2], "b": ["x", "y"]})
    written = write_frame(df, tmp_path / "t.csv")
    assert pd.read_csv(tmp_path / "t.csv").equals(df)
    if len(written) == 2:
        assert pd.read_parquet(tmp_path / "t.parquet").equals(df)


def test_a_large_frame_is_formatted_in_slices_to_the_same_text(monkeypatch):
    # every dtype a trial frame holds, with the values whose text could differ: NaN, -0.0, inf, NA, quoting
    import numpy as np

    from starid import io

    n = 90
    rng = np.random.default_rng(2)
    x = rng.normal(size=n) * 10.0 ** rng.integers(-300, 300, size=n)
    x[::7], x[1::11], x[2::13] = np.nan, -0.0, np.inf
    df = pd.DataFrame({
        "f": x, "f_const": np.full(n, 0.1), "i": np.arange(n) * 10**12,
        "I": pd.array([None if k % 5 == 0 else k for k in range(n)], dtype="Int64"),
        "b": np.arange(n) % 3 == 0, "o": [None if k % 4 == 0 else (k if k % 2 else f"p{k}") for k in range(n)],
        "s": pd.array([None if k % 6 == 0 else f'a,b "{k}"\nc' for k in range(n)], dtype="string"),
    })
    want = df.to_csv(index=False, lineterminator="\n")
    monkeypatch.setattr(io, "PARALLEL_CSV_ROWS", 20)
    monkeypatch.setattr(io.os, "cpu_count", lambda: 4)          # four slices, on any machine
    whole = pd.DataFrame.to_csv

    def slices_only(self, *args, **kwargs):     # the parallel path never formats the whole frame at once
        assert len(self) < n, "the frame was formatted whole, not in slices"
        return whole(self, *args, **kwargs)

    monkeypatch.setattr(pd.DataFrame, "to_csv", slices_only)
    assert io.frame_csv(df) == want and not io._CSV_FRAME
