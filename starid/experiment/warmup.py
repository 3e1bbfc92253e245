"""Compile scheduling: workers compile disjoint plugins first and share numba's on-disk cache.

A worker process compiles a plugin's kernels (``@njit(cache=True)``) the first time it prepares
a chunk of that plugin, and writes the machine code to numba's on-disk cache; any later process
that needs the same kernels loads them from disk in a fraction of a second instead of compiling
them again. In plan order (study, grid point, variant, block) the first chunks of every worker
belong to the same plugin, so on a cold cache every worker compiles the same kernels at the same
time, and then the next plugin's, and so on: with ``n`` workers each kernel is compiled ``n``
times.

:func:`schedule` reorders the tasks so that the first chunk of each plugin comes first (in the
order the plugins first appear), then every other chunk in plan order. Free workers take tasks in
this order, so the first chunks -- those that compile -- go to different workers, each plugin is
compiled once, and the other workers load it from the cache when they reach its later chunks.
Only the order of computation changes: every chunk is computed from its own settings and seed
and the frame is assembled in plan order, so every result but the times is identical.
"""

from __future__ import annotations


def plugin_of(task) -> str:
    """The registered plugin name whose kernels ``task`` compiles (variants share their plugin's)."""
    return task.chunk.variant.name


def schedule(tasks: list) -> list:
    """``tasks`` with the first task of each plugin moved to the front (stable otherwise)."""
    seen: set[str] = set()
    first, rest = [], []
    for task in tasks:
        name = plugin_of(task)
        (rest if name in seen else first).append(task)
        seen.add(name)
    return first + rest
