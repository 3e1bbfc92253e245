"""Assembling an experiment's chunks: the fast join equals joining chunk by chunk (#25)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from starid.experiment.runner import _join_each, _with_constants


def _chunk(n: int, algorithm: str, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    cols = {"trial": np.arange(n), "status": pd.array(rng.choice(["correct", "failed"], n), dtype="string"),
            "time_us": rng.random(n), "correct": rng.random(n) < 0.5, "label": [algorithm] * n}
    if algorithm == "a":        # parameters and columns only some algorithms have
        cols["param_k"] = np.full(n, 8)
        cols["counter_x"] = rng.integers(0, 9, n)
    else:
        cols["param_tol"] = np.full(n, 0.5)
        cols["flag"] = rng.random(n) < 0.3
    return pd.DataFrame(cols)


def _types(frame: pd.DataFrame) -> dict:
    """Each object column's value types row by row (1, 1.0 and True compare equal as values)."""
    return {c: frame[c].map(type).tolist() for c in frame.columns if frame[c].dtype == object}


CONSTANTS = [   # (lead, tail) per grid point: int here and float there, bool against int, None against text
    ({"study": "s1", "point": 0, "grid_x": 1}, {"seed": 0, "sim_on": True, "camera_name": None}),
    ({"study": "s1", "point": 1, "grid_x": 2.5}, {"seed": 0, "sim_on": 1, "camera_name": "cam"}),
    ({"study": "s2", "point": 0, "grid_y": "b"}, {"seed": 0, "sim_on": 1.0, "camera_name": None}),
    ({"study": "s2", "point": 1, "grid_y": "c"}, {"seed": 0, "sim_on": True, "camera_name": "cam"}),
]


@pytest.mark.parametrize("empty", [False, True])
def test_the_fast_join_is_the_chunk_by_chunk_join(empty):
    frames, lead, tail = [], [], []
    for block in range(3):                  # plan order: every point's chunks of one block, then the next block
        for p, (a, b) in enumerate(CONSTANTS):
            for algorithm in ("a", "b"):
                n = 0 if empty and block == 1 and p == 2 else 5 + block
                frames.append(_chunk(n, algorithm, 100 * block + 10 * p + (algorithm == "b")))
                lead.append(dict(a))
                tail.append(dict(b))
    want = _join_each(frames, lead, tail)
    got = _with_constants(frames, lead, tail)
    assert list(got.columns) == list(want.columns)
    assert got.dtypes.to_dict() == want.dtypes.to_dict()
    pd.testing.assert_frame_equal(got, want, check_exact=True)
    assert _types(got) == _types(want)
    # the cases the constants are there for
    assert want["grid_x"].dtype == np.float64 and want["sim_on"].dtype == object
    assert {type(v) for v in want["sim_on"]} == {bool, int, float}


def test_constants_equal_as_values_but_not_as_types_stay_apart():
    frames = [_chunk(3, "a", 1), _chunk(4, "a", 2), _chunk(2, "a", 3)]
    lead = [{"x": 1}, {"x": True}, {"x": 1.0}]
    tail = [{}, {}, {}]
    got = _with_constants(frames, lead, tail)
    assert [type(v) for v in got["x"]] == [int] * 3 + [bool] * 4 + [float] * 2
    assert _types(got) == _types(_join_each(frames, lead, tail))
