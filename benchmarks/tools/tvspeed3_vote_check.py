"""``vote``'s outputs on many images, saved or compared (issue #25, tvspeed3: the same votes after a change).

    python benchmarks/tools/tvspeed3_vote_check.py save FILE.npz [N]     # on the base commit
    python benchmarks/tools/tvspeed3_vote_check.py check FILE.npz [N]    # on the branch

Table 6's camera, 1 px / 0.5 Mv, seed 0, N images (300) of each of: the paper's sky, the real sky, the real
sky with 3 false stars; each with the default parameters, with ``side_check=false vote_neighbours=false``
and with ``vote_neighbours=false``. Per image ``vote``'s ``cand``, ``cand_votes``, ``hyp``, ``score``,
``work`` (brightest-first stars as ``identify`` orders them) and ``identify``'s HIP; ``check`` prints the
number of images compared and of those differing in any of them (exit 1 if any).
"""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
from starid_algorithms.triangle_voting import algorithm as tva
from starid_algorithms.triangle_voting import kernels as tvk

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.kernels import backproject_px
from starid.registry import get_algorithm

VARIANTS = {"default": {}, "double": {"side_check": False, "vote_neighbours": False},
            "no_nbr_votes": {"vote_neighbours": False}}


def _outputs(n: int) -> dict:
    cat, cam = load_hipparcos(), Camera()
    out = {}
    base = get_algorithm("triangle_voting")()
    db = base.build(cat, cam)
    for sky, false_stars in (("paper", 0), ("real", 0), ("real", 3)):
        sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6,
                                            false_stars=false_stars, **SKIES[sky]), seed=0)
        trials = sim.generate(n)
        for vname, over in VARIANTS.items():
            alg = dataclasses.replace(base, **over)
            _, ktol, _ = alg._tolerances(cam)
            for k in range(n):
                o = trials.observation(k, truth=False)
                x, y, mag = o.x_px, o.y_px, o.mag
                order = np.lexsort((y, x, mag))
                order = order[mag[order] <= alg.mag_limit + alg.mag_margin][:alg.max_stars]
                key = f"{sky}{false_stars}_{vname}_{k}"
                out[key + "_hip"] = alg.identify(db, o).hip
                if order.size < 3:
                    continue
                v_cam = backproject_px(x[order], y[order], cam.f_px, cam.cx_px, cam.cy_px)
                no = np.zeros((0, 0), dtype=np.int32)
                for name, value in zip(("cand", "cand_votes", "hyp", "score", "work"),
                                       tvk.vote(v_cam, tva._kernel_tables(db), ktol, no, no), strict=True):
                    out[f"{key}_{name}"] = value
    return out


def main(mode: str, path: str, n: int) -> None:
    out = _outputs(n)
    if mode == "save":
        np.savez_compressed(path, **out)
        print(f"saved {len(out)} arrays to {path}")
        return
    ref = np.load(path)
    images = {k.rsplit("_", 1)[0] for k in ref.files if k.endswith("_hip")}
    bad = sorted({k.rsplit("_", 1)[0] for k in set(ref.files) | set(out)
                  if k not in out or k not in ref.files or not np.array_equal(ref[k], out[k])})
    print(f"images x variants compared: {len(images)}; differing: {len(bad)} {bad[:10]}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 300)
