"""Mortari's k-vector: O(1) range search over sorted keys (Mortari & Neta 2000)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .jit import inner, kernel


def kvector_build(sorted_values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Build Mortari's k-vector over ascending ``sorted_values`` (Mortari & Neta 2000).

    The line ``z(i) = m i + q`` (i = 1..n) is slightly steeper than the data and passes just
    outside both extremes (Zhou & Ye 2015, eqs. 15-16); ``k[i-1] = #{s_j <= z(i)}``.
    Returns ``(k, m, q)``; query with :func:`kvector_range`.
    """
    s = np.ascontiguousarray(sorted_values, dtype=np.float64)
    n = s.shape[0]
    if n >= 2 and np.any(np.diff(s) < 0):
        raise ValueError("kvector_build needs ascending values")
    if n < 2 or s[-1] == s[0]:
        lo = s[0] if n else 0.0
        m, q = 1.0, lo - 1.0
    else:
        xi = np.finfo(np.float64).eps * max(abs(s[0]), abs(s[-1]))
        m = (s[-1] - s[0] + 2.0 * xi) / (n - 1)
        q = s[0] - m - xi
    z = m * np.arange(1, n + 1, dtype=np.float64) + q
    k = np.searchsorted(s, z, side="right").astype(np.int64)
    return k, float(m), float(q)


@inner   # kernels call it only
def kvector_ends(m, q, lo, hi):
    """The two k-vector positions ``(jb, jt)`` :func:`kvector_slice` reads for ``[lo, hi]``: a caller
    that prefetches ``k[jb - 1]`` and ``k[jt - 1]`` before :func:`kvector_rows` reads them (ptp's passes)
    gets the same slice."""
    return int(math.floor((lo - q) / m)) - 1, int(math.ceil((hi - q) / m)) + 1


@inner   # kernels call it only
def kvector_rows(k, n, jb, jt):
    """:func:`kvector_slice`'s ``[start, stop)`` from the positions of :func:`kvector_ends` (``n > 0``),
    as int64 whatever ``k``'s integer type."""
    if jb < 1:
        start = 0
    elif jb > n:
        start = n
    else:
        start = np.int64(k[jb - 1])
    if jt < 1:
        stop = 0
    elif jt > n:
        stop = n
    else:
        stop = np.int64(k[jt - 1])
    if stop < start:
        stop = start
    return start, stop


@kernel
def kvector_slice(k, m, q, n, lo, hi):
    """Index range ``[start, stop)`` of the ``n`` sorted keys that holds every key in ``[lo, hi]``,
    from the k-vector alone: the O(1) slice :func:`kvector_range` then trims
    (Zhou & Ye 2015, eqs. 17-19), so the keys themselves need not be stored.

    The line puts a margin of one full bin ``m`` on each side (``z(jb) <= lo - m``, ``z(jt) >= hi + m``),
    so the slice holds at most a few keys outside ``[lo, hi]`` on each end; a caller that checks each
    candidate anyway (P-vector's three sides) gets the same matches as with the trimmed range.
    """
    if n == 0 or hi < lo:
        return 0, 0
    jb, jt = kvector_ends(m, q, lo, hi)
    return kvector_rows(k, n, jb, jt)


@inner   # kernels call it only
def kvector_trim(sorted_values, n, start, stop, lo, hi):
    """The slice ``[start, stop)`` of the ``n`` sorted values (a k-vector's slightly wide one) trimmed, or
    widened where float rounding put a line on the wrong side, to exactly the values in ``[lo, hi]``."""
    while start > 0 and sorted_values[start - 1] >= lo:
        start -= 1
    while start < n and sorted_values[start] < lo:
        start += 1
    while stop < n and sorted_values[stop] <= hi:
        stop += 1
    while stop > start and sorted_values[stop - 1] > hi:
        stop -= 1
    if stop < start:
        stop = start
    return start, stop


@kernel
def kvector_range(sorted_values, k, m, q, lo, hi):
    """Index range ``[start, stop)`` of ``sorted_values`` lying in ``[lo, hi]``.

    The k-vector gives a slightly wide slice in O(1) (Zhou & Ye 2015, eqs. 17-19); its ends
    are then trimmed exactly, so the result equals
    ``searchsorted(s, lo, 'left'), searchsorted(s, hi, 'right')``.
    """
    n = sorted_values.shape[0]
    if n == 0 or hi < lo:
        return 0, 0
    start, stop = kvector_slice(k, m, q, n, lo, hi)
    return kvector_trim(sorted_values, n, start, stop, lo, hi)


class KVector(NamedTuple):
    """A k-vector as one bundle, the single name every plugin uses for it.

    values : float (n,) the sorted keys; k : int (n,) the k-vector; m, q : its line ``z = m i + q``.
    numba passes a ``KVector`` into kernels as a tuple, so kernels take one argument, not four.
    """

    values: np.ndarray
    k: np.ndarray
    m: float
    q: float

    @property
    def nbytes(self) -> int:
        return int(self.values.nbytes + self.k.nbytes)


def kvector_make(sorted_values: np.ndarray, values_dtype=np.float64, index_dtype=np.int64) -> KVector:
    """Build a :class:`KVector` over ascending ``sorted_values`` (stored as ``values_dtype``)."""
    values = np.ascontiguousarray(sorted_values, dtype=values_dtype)
    k, m, q = kvector_build(values.astype(np.float64))
    return KVector(values, k.astype(index_dtype), m, q)


@kernel
def kvector_query(kv, lo, hi):
    """Index range ``[start, stop)`` of ``kv.values`` lying in ``[lo, hi]`` (see :func:`kvector_range`)."""
    return kvector_range(kv[0], kv[1], kv[2], kv[3], lo, hi)
