"""Integer parameters stay integers in every column and file (#27): ``param_n_slaves = 6``, not 6.0,
also when another algorithm of the run has no such parameter (the concatenation used to fill NaN and
turn the column into floats)."""

from __future__ import annotations

import pandas as pd

from starid import Catalog
from starid.experiment import Experiment, Study
from starid.experiment.runner import assemble, plan
from starid.io import write_frame
from starid.params import integer_columns, keep_integers


def _chunk_rows(chunk) -> pd.DataFrame:
    n = chunk.stop - chunk.start
    rows = {"trial": range(chunk.start, chunk.stop), "label": chunk.variant.label, "status": "correct"}
    if chunk.variant.name == "ptp":
        rows |= {"param_n_slaves": 6, "param_verify": True, "param_tol_px": 0.5}
    else:
        rows |= {"param_n_bright": [8] * n}
    return pd.DataFrame(rows)


def test_integer_parameters_stay_integers_in_frame_csv_and_parquet(tmp_path):
    exp = Experiment("ints", (Study("s", ("ptp", "pvector")),), trials=4)
    placements = plan(exp, Catalog.embedded())
    chunks = {pl.chunk.key: pl.chunk for pl in placements}
    frame = assemble(placements, exp, lambda key: _chunk_rows(chunks[key]))
    assert frame["param_n_slaves"].dtype == "Int64" and frame["param_n_bright"].dtype == "Int64"
    assert frame["param_tol_px"].dtype.kind == "f"                # a float parameter stays a float
    ptp = frame[frame["label"] == "ptp"]
    assert ptp["param_n_slaves"].tolist() == [6] * 4 and frame["param_n_slaves"].isna().sum() == 4
    csv, pq = write_frame(frame, tmp_path / "trials.csv")
    text = (tmp_path / "trials.csv").read_text()
    header = text.splitlines()[0].split(",")
    first = text.splitlines()[1].split(",")
    assert first[header.index("param_n_slaves")] == "6"           # not 6.0
    back = pd.read_parquet(pq)
    assert back["param_n_bright"].dtype == "Int64" and back["param_n_bright"].dropna().tolist() == [8] * 4


def test_integer_columns_needs_integers_everywhere():
    a = pd.DataFrame({"param_n": [1, 2], "param_x": [1, 2], "param_f": [True, False]})
    b = pd.DataFrame({"param_n": [3], "param_x": [0.5]})
    assert integer_columns([a, b]) == {"param_n"}
    out = keep_integers(pd.concat([a, b.drop(columns="param_n"), b], ignore_index=True), {"param_n"})
    assert out["param_n"].tolist()[:2] == [1, 2] and out["param_n"].dtype == "Int64"
