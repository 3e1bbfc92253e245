"""Compile scheduling: workers compile disjoint plugins first and share numba's on-disk cache.

A worker process compiles a plugin's kernels (``@njit(cache=True)``) the first time it prepares
a chunk of that plugin, and writes the machine code to numba's on-disk cache; any later process
that needs the same kernels loads them from disk in a fraction of a second instead of compiling
them again. In plan order (study, grid point, variant, block) the first chunks of every worker
belong to the same plugin, so on a cold cache every worker compiles the same kernels at the same
time, and then the next plugin's, and so on: with ``n`` workers each kernel is compiled ``n``
times.

:func:`schedule` reorders the tasks so that the first chunk of each plugin comes first (those
that take longest to compile first: :func:`compile_order`), then every other chunk. Free workers
take tasks in this order, so the first chunks -- those that compile -- go to different workers, each plugin is
compiled once, and the other workers load it from the cache when they reach its later chunks.
The other chunks follow grouped by the images they score (grid point settings, block of trials,
catalog, camera, seed), in the order each group first appears: every plugin's chunk of one block
runs before the next block's. A worker keeps the last few simulated blocks
(``executors._trials``), so it simulates each block once for all the plugins it runs on it
instead of once per chunk: in plan order (plugin-major) the cache never hits, and Table 6 at
10,000 trials simulated its 40 blocks 400 times (0.2 CPU s per block of 500 images).

Only the order of computation changes: every chunk is computed from its own settings and seed
and the frame is assembled in plan order, so every result but the times is identical.
"""

from __future__ import annotations

from collections import OrderedDict, deque


def plugin_of(task) -> str:
    """The registered plugin name whose kernels ``task`` compiles (variants share their plugin's)."""
    return task.chunk.variant.name


def images_of(task) -> tuple:
    """What decides the images ``task`` scores (the key of a worker's simulated-trials cache)."""
    chunk = task.chunk
    return (getattr(task, "catalog_path", ""), getattr(task, "camera", None), getattr(task, "seed", None),
            getattr(chunk, "settings_key", None), getattr(chunk, "start", None), getattr(chunk, "stop", None))


def compile_weight(name: str) -> float:
    """CPU seconds plugin ``name`` took to build and compile on an empty cache, alone in a process
    (:data:`starid.experiment.compile_weights.CPU_S`, measured by ``benchmarks/tools/compile_weights.py``);
    a plugin not measured (a third party's) weighs the median of those measured."""
    from .compile_weights import CPU_S

    if name in CPU_S:
        return CPU_S[name]
    values = sorted(CPU_S.values())
    return values[len(values) // 2] if values else 0.0


def compile_order(names: list[str]) -> list[str]:
    """``names`` heaviest to compile first (:func:`compile_weight`; equal weights keep their order).

    Free workers take the first chunks in this order, so on a cold cache the longest compiles start
    first and the short ones fill in at the end, as in longest-processing-time-first scheduling: with
    Table 6's order (triangle voting, among the longest, last) one of two workers compiled for about
    10 s after the other had finished."""
    return sorted(names, key=lambda name: -compile_weight(name))


def schedule(tasks: list) -> list:
    """``tasks`` with the first task of each plugin moved to the front (heaviest compile first,
    :func:`compile_order`), then the others grouped by the images they score (groups in
    first-appearance order, plan order within a group)."""
    seen: set[str] = set()
    first, groups = {}, {}
    for task in tasks:
        name = plugin_of(task)
        if name in seen:
            groups.setdefault(images_of(task), []).append(task)
        else:
            first[name] = task
        seen.add(name)
    return [first[name] for name in compile_order(list(first))] + [task for group in groups.values()
                                                                   for task in group]


#: simulated blocks a worker keeps (``executors._trials``); :class:`Dispatcher` mirrors what each worker holds.
#: A block of 500 images is well under 1 MB; Table 6 at 10,000 trials has 40.
TRIALS_KEPT = 48

#: how far down the pending tasks :meth:`Dispatcher.take` looks for one that suits the free worker
LOOK_AHEAD = 400


def _prepared_key(task) -> tuple:
    """What a worker keys the database it built by: :func:`starid.harness.database_key` of the plugin
    with the grid point's settings filled into its ``follows`` parameters. Chunks with one key share one
    database on a worker."""
    from ..harness import database_key
    from ..simulate import SimConfig, assumed_camera

    chunk = task.chunk
    try:
        config = SimConfig(**chunk.settings)
        algorithm = chunk.variant.make().resolved(config)
        return database_key(algorithm, getattr(task, "catalog_path", ""), assumed_camera(task.camera, config))
    except Exception:  # noqa: BLE001 -- an algorithm that cannot be made: its chunk's own key
        return ("unmade", chunk.variant, getattr(chunk, "settings_key", None), getattr(task, "catalog_path", ""))


class Dispatcher:
    """The pending tasks of a :class:`~starid.experiment.executors.LocalExecutor` run, and which one a free
    worker takes next.

    First the first chunk of each plugin (:func:`schedule`: those compile), each to the next free worker.
    Then a free worker takes, in :func:`schedule` order, the first pending chunk whose algorithm it has
    already prepared and whose images it has already simulated; else the first whose algorithm it has
    prepared at the grid point the run is at (the first pending task's settings); else the first pending
    chunk. So each worker keeps to the algorithms it built: with the plain order both workers took every
    algorithm's chunks in turn and built every database twice (Table 6: 14 databases, 0.2-10 s each;
    zhou2015: one per algorithm and grid point its ``follows`` parameters change, ~100, fewer where those are
    ``query_only``), while the blocks
    they simulate stay those of the point at hand. Only the order changes; every row but the times is the
    same.

    A worker is any object: its prepared keys and simulated blocks are kept on it (``_prepared``,
    ``_images``), as it will hold them once it has run the tasks it was given.
    """

    def __init__(self, tasks: list):
        ordered = schedule(tasks)
        n_first = len({plugin_of(t) for t in tasks})
        self._keys: dict = {}
        self._first = deque(ordered[:n_first])
        self._rest = list(ordered[n_first:])

    def __bool__(self) -> bool:
        return bool(self._first or self._rest)

    def __len__(self) -> int:
        return len(self._first) + len(self._rest)

    def put_back(self, task) -> None:
        """``task`` first again (a chunk to redo after its worker died or overran)."""
        self._first.appendleft(task)

    def _key(self, task) -> tuple:
        k = id(task)
        if k not in self._keys:
            self._keys[k] = (task, _prepared_key(task), images_of(task), getattr(task.chunk, "settings_key", None))
        return self._keys[k][1:]

    def take(self, worker):
        """The task ``worker`` (free) runs next, taken off the pending ones."""
        if self._first:
            task = self._first.popleft()
        else:
            prepared = getattr(worker, "_prepared", set())
            images = getattr(worker, "_images", {})
            pick, here = 0, self._key(self._rest[0])[2]
            second = None
            for i, task in enumerate(self._rest[:LOOK_AHEAD]):
                pk, ik, settings = self._key(task)
                if pk in prepared:
                    if ik in images:
                        pick = i
                        break
                    if second is None and settings == here:
                        second = i
            else:
                pick = second if second is not None else 0
            task = self._rest.pop(pick)
        self._keep(worker, task)
        return task

    def _keep(self, worker, task) -> None:
        pk, ik, _ = self._key(task)
        self._keys.pop(id(task), None)
        if not hasattr(worker, "_prepared"):
            worker._prepared, worker._images = set(), OrderedDict()
        worker._prepared.add(pk)
        worker._images[ik] = True
        worker._images.move_to_end(ik)
        while len(worker._images) > TRIALS_KEPT:
            worker._images.popitem(last=False)
