"""Measured cold-preparation CPU seconds per plugin: the order workers compile in (heaviest first).

Written by ``python benchmarks/tools/compile_weights.py`` (each plugin alone in a process, empty numba
cache, database build + warm-up identify) at commit 43be098, 2026-12-05, on issue #25's
2-core machine. :func:`starid.experiment.warmup.schedule` deals the first chunk of each plugin (the one
that compiles) heaviest first, so that two workers finish compiling at about the same time; a plugin
not listed (a third party's) weighs the median. Only the order of computation depends on these numbers.
"""

CPU_S: dict[str, float] = {
    "triangle_voting": 17.9,
    "planar_triangle": 17.1,
    "lpt": 16.0,
    "ptp": 14.1,
    "lpt_improved": 12.1,
    "spherical_triangle": 11.2,
    "composite_pyramid": 11.2,
    "geometric_voting": 10.5,
    "pvector": 10.2,
    "angle": 10.0,
    "grid": 9.2,
    "pyramid": 9.2,
    "interior_angle": 8.2,
    "tetra": 7.7,
}
