"""Where triangle_voting's ``identify`` spends its time, interleaved as the benchmark times it and warm (issue #25).

    python benchmarks/tools/tvspeed5_profile.py [N] [R]

``tvspeed4_profile.py`` with one more stage, ``dispatch``: ``identify_image`` on the image's first two stars
(the kernel's entry, its arguments converted, an early return), called as ``identify`` called it before
``identify_flat``; ``dispatch_flat`` the same for ``identify_flat``, and ``identify_flat`` (the kernel
``identify`` calls now). Table 6's two skies (``benchmarks/test_ratios.py``'s settings: 1 px / 0.5 Mv, V <= 6, more
than five stars, seed 0), N images (200), R rounds (2). Every registered plugin is built and warmed up as in the
benchmark. Then, per image and per stage, the other plugins identify the image first (untimed: they evict
triangle_voting's data and code from the caches as in the benchmark's interleaved timing) and the stage is timed
once ("cold"); and per image each stage is timed 3 times back to back, minimum kept ("warm"). Stages:
``dispatch``, ``vote``, ``identify_rows`` (+ selection, verification, confirmation / fallback),
``identify_image`` (the one kernel: order, back-projection, ``identify_rows``, the final step) and ``identify``
(+ the Python wrapper and the ``Identification``); tetra's ``identify`` is timed the same way for scale. Prints
the median over images and rounds per stage, in us.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid.kernels import backproject_px

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tvspeed4_profile  # noqa: E402

STAGES = ("dispatch", "dispatch_flat", "vote", "identify_rows", "identify_image", "identify_flat", "identify", "tetra")
NO = np.zeros((0, 0), dtype=np.int32)


def _calls(alg, db, tetra, tetra_db, o):
    """The stages of one image as argument-free callables."""
    x, y, mag = o.x_px, o.y_px, o.mag
    _, ktol, fin_cam = alg._tolerances(o.camera)
    kt, fin_db = tva._kernel_tables(db), tva._finish_tables(db)
    flat = alg._flat_args(db, o.camera)
    out = {"identify": lambda: alg.identify(db, o),
           "identify_image": lambda: tvk.identify_image(x, y, mag, kt, ktol, fin_db, fin_cam),
           "tetra": lambda: tetra.identify(tetra_db, o),
           # the kernel's entry and exit alone: the same arguments, two stars (returns before any work)
           "dispatch": lambda: tvk.identify_image(x[:2], y[:2], mag[:2], kt, ktol, fin_db, fin_cam),
           "identify_flat": lambda: tvk.identify_flat(x, y, mag, *flat),
           "dispatch_flat": lambda: tvk.identify_flat(x[:2], y[:2], mag[:2], *flat)}
    order = np.lexsort((y, x, mag))
    order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
    if order.size >= 3:
        cam = o.camera
        v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
        out["vote"] = lambda: tvk.vote(v_cam, kt, ktol, NO, NO)
        out["identify_rows"] = lambda: tvk.identify_rows(v_cam, kt, ktol, NO, NO)
    return out


if __name__ == "__main__":
    tvspeed4_profile.main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, int(sys.argv[2]) if len(sys.argv) > 2 else 2,
                          _calls, STAGES)
