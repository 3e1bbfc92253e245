"""A strict, input-order-free order of detections: by a key (e.g. magnitude), exact ties by x, then y.

Every plugin that takes "the brightest stars first" or "the stars nearest the centre first" uses
these, so two detections with the same key are ordered the same way whatever order they came in.
"""

from __future__ import annotations

import numpy as np

from .jit import inner, kernel


@kernel
def before(key, x_px, y_px, i, j):
    """True when detection ``i`` comes before ``j``: smaller ``key``, exact ties by x, then y."""
    if key[i] != key[j]:
        return key[i] < key[j]
    if x_px[i] != x_px[j]:
        return x_px[i] < x_px[j]
    return y_px[i] < y_px[j]


#: Above this many rows :func:`sort_rows` merge-sorts by key first, so that its insertion pass
#: only settles exact ties (insertion sort alone is quadratic).
PRESORT_ROWS = 64


@inner
def _key_less(x, y):
    """numpy's sort order: ``x < y``, NaN after every number."""
    return x < y or (y != y and x == x)


@inner
def stable_sort_by_key(rows, n, key):
    """Stable sort of ``rows[:n]`` in place by ``key[rows]``, NaN last: the order ``np.argsort(key[rows[:n]],
    kind="mergesort")`` gives (a stable order is unique), by a bottom-up merge sort written out, not
    numba's argmergesort (~1.3 CPU s to compile, again in every kernel that inlines it). Kernels only
    (no Python wrapper); ptp's ``argsort_int`` is this on ``np.arange(n)``."""
    src = rows[:n].copy()
    dst = np.empty_like(src)
    width = 1
    while width < n:
        i = 0
        while i < n:
            mid = min(i + width, n)
            hi = min(i + 2 * width, n)
            a = i
            b = mid
            k = i
            while a < mid and b < hi:
                if _key_less(key[src[b]], key[src[a]]):
                    dst[k] = src[b]
                    b += 1
                else:
                    dst[k] = src[a]
                    a += 1
                k += 1
            while a < mid:
                dst[k] = src[a]
                a += 1
                k += 1
            while b < hi:
                dst[k] = src[b]
                b += 1
                k += 1
            i = hi
        src, dst = dst, src
        width *= 2
    for a in range(n):
        rows[a] = src[a]


@kernel
def sort_rows(rows, n, key, x_px, y_px):
    """Sort ``rows[:n]`` in place by :func:`before` (stable): an insertion sort, after a stable
    merge sort by ``key`` alone when there are more than :data:`PRESORT_ROWS` of them."""
    if n > PRESORT_ROWS:
        stable_sort_by_key(rows, n, key)
    for a in range(1, n):
        r = rows[a]
        b = a - 1
        while b >= 0 and before(key, x_px, y_px, r, rows[b]):
            rows[b + 1] = rows[b]
            b -= 1
        rows[b + 1] = r


@kernel
def order_by(key, x_px, y_px):
    """Indices of all detections in :func:`before` order."""
    order = np.arange(key.shape[0])
    sort_rows(order, order.shape[0], key, x_px, y_px)
    return order


@inner
def search_left(a, v):
    """``np.searchsorted(a, v)`` (side left) of an ascending array, as a bisection written out: numba's
    searchsorted overload costs ~0.3 CPU s of a cold compile, again in every kernel that links it.
    Kernels only (no Python wrapper)."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def sort_int_prefix(a, n):
    """Sort ``a[:n]`` (integers) ascending in place: the array ``np.sort`` gives (equal integers are
    indistinguishable), without compiling numpy's quicksort (~0.7 CPU s cold, and again in every
    kernel that inlines it). Insertion sort for short runs, heapsort (n log n, no buffer) above."""
    if n <= 16:
        for i in range(1, n):
            v = a[i]
            j = i - 1
            while j >= 0 and a[j] > v:
                a[j + 1] = a[j]
                j -= 1
            a[j + 1] = v
        return
    for start in range(n // 2 - 1, -1, -1):
        _sift_down(a, start, n)
    for end in range(n - 1, 0, -1):
        t = a[0]
        a[0] = a[end]
        a[end] = t
        _sift_down(a, np.int64(0), end)   # np.int64: not a literal (one signature)


@inner
def _sift_down(a, root, end):
    """Heapsort's sift-down of ``a[root]`` within the max-heap ``a[:end]``."""
    v = a[root]
    while True:
        child = 2 * root + 1
        if child >= end:
            break
        if child + 1 < end and a[child + 1] > a[child]:
            child += 1
        if a[child] <= v:
            break
        a[root] = a[child]
        root = child
    a[root] = v
