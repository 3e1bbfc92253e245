"""Scalar parameters as one float64 array, a kernel's argument.

numba converts a tuple argument element by element on every call, an array at once: a kernel that
takes its camera and tolerance scalars (floats, integers, flags) as one float64 array and rebuilds
its named bundles inside spends less on each call, most when the call's Python objects are out of
the cache (issue #25; ptp and triangle voting measured 3-10 us per call). The rebuilding stays in
each kernel, which knows the types; this module only packs, and refuses any value that float64
does not hold exactly, so the kernel sees the same numbers, integers and flags.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ..errors import ConfigError
from .assign import Frame
from .jit import kernel

#: how many values a camera :class:`~starid.kernels.Frame` takes in a parameter array (its fields, in order)
FRAME_SIZE = 5


def exact_float64(values: Iterable, what: str) -> np.ndarray:
    """``values`` (floats, integers, bools: no arrays) as one float64 array, each exact (a float
    is; an integer must be within 2**53).

    Raises :class:`~starid.errors.ConfigError` naming ``what`` and the value when one is an array or
    is an integer float64 does not hold exactly."""
    values = list(values)
    out = np.empty(len(values), dtype=np.float64)
    for k, v in enumerate(values):
        if isinstance(v, np.ndarray):
            raise ConfigError(f"{what}: parameter {k} is an array, not a number")
        out[k] = float(v)
        if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) and int(out[k]) != int(v):
            raise ConfigError(f"{what}: parameter {k} ({v!r}) is not exact in float64")
    return out


def pack_with_frame(frame: Frame, values: Iterable, what: str) -> np.ndarray:
    """``frame``'s :data:`FRAME_SIZE` fields, then ``values``, as one float64 array (:func:`exact_float64`): the
    layout whose frame :func:`frame_at` reads back at offset 0, the rest each kernel's own."""
    return exact_float64([*frame, *values], what)


@kernel
def frame_at(p, i):
    """The :class:`~starid.kernels.Frame` packed at ``p[i:i + FRAME_SIZE]`` (its fields in order), rebuilt
    inside a kernel that takes its parameters as one array (call it with an ``np.int64`` offset: one
    signature)."""
    return Frame(p[i], p[i + 1], p[i + 2], p[i + 3], p[i + 4])
