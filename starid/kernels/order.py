"""A strict, input-order-free order of detections: by a key (e.g. magnitude), exact ties by x, then y.

Every plugin that takes "the brightest stars first" or "the stars nearest the centre first" uses
these, so two detections with the same key are ordered the same way whatever order they came in.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def before(key, x_px, y_px, i, j):
    """True when detection ``i`` comes before ``j``: smaller ``key``, exact ties by x, then y."""
    if key[i] != key[j]:
        return key[i] < key[j]
    if x_px[i] != x_px[j]:
        return x_px[i] < x_px[j]
    return y_px[i] < y_px[j]


@njit(cache=True)
def sort_rows(rows, n, key, x_px, y_px):
    """Insertion sort of ``rows[:n]`` in place by :func:`before` (stable; meant for short or nearly
    sorted lists)."""
    for a in range(1, n):
        r = rows[a]
        b = a - 1
        while b >= 0 and before(key, x_px, y_px, r, rows[b]):
            rows[b + 1] = rows[b]
            b -= 1
        rows[b + 1] = r


@njit(cache=True)
def order_by(key, x_px, y_px):
    """Indices of all detections in :func:`before` order (a stable sort by ``key``, then an insertion
    pass that settles the exact ties)."""
    order = np.argsort(key, kind="mergesort")
    sort_rows(order, order.shape[0], key, x_px, y_px)
    return order
