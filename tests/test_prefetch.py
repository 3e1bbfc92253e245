"""The prefetch hints (:mod:`starid.kernels.prefetch`) compile to the CPU's prefetch instruction and change
no value: a kernel reads the same with and without them."""

import numpy as np
from numba import njit

from starid.kernels.prefetch import prefetch, prefetch_at


@njit(cache=False)
def _sum_with_hints(v, m, rows):
    total = 0.0
    for k in range(rows.shape[0]):
        if k + 1 < rows.shape[0]:
            prefetch(v, rows[k + 1])          # a 1-D element
            prefetch(m, rows[k + 1])          # the start of a row
            prefetch_at(m, rows[k + 1], 2)    # one element of a row
        total += v[rows[k]] + m[rows[k], 2]
    return total


def test_prefetch_changes_no_value_and_emits_the_instruction():
    rng = np.random.default_rng(5)
    v, m = rng.normal(size=1000), rng.normal(size=(1000, 3))
    rows = rng.integers(0, 1000, 200)
    assert _sum_with_hints(v, m, rows) == sum(v[r] + m[r, 2] for r in rows)
    asm = "".join(_sum_with_hints.inspect_asm().values())
    if "x86" in asm or "%rsp" in asm:      # x86-64: the hint is prefetcht0
        assert asm.count("prefetcht0") >= 3
