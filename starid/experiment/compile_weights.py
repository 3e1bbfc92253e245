"""Measured cold-preparation CPU seconds per plugin: the order workers compile in (heaviest first).

Written by ``python benchmarks/tools/compile_weights.py`` (each plugin alone in a process, empty numba
cache, database build + warm-up identify) at commit 41fd66c, 2026-12-05, on issue #25's
2-core machine. :func:`starid.experiment.warmup.schedule` deals the first chunk of each plugin (the one
that compiles) heaviest first, so that two workers finish compiling at about the same time; a plugin
not listed (a third party's) weighs the median. Only the order of computation depends on these numbers.
"""

CPU_S: dict[str, float] = {
    "planar_triangle": 21.5,
    "triangle_voting": 21.3,
    "lpt": 20.5,
    "ptp": 19.0,
    "lpt_improved": 15.5,
    "composite_pyramid": 15.1,
    "geometric_voting": 14.3,
    "angle": 12.8,
    "spherical_triangle": 12.8,
    "grid": 12.7,
    "pvector": 12.1,
    "pyramid": 11.4,
    "interior_angle": 10.2,
    "tetra": 10.2,
}
