"""ptp's median per image against tetra's as ``benchmarks/test_ratios.py`` measures it (every registered
plugin identifies each image in turn, Table 6's settings), with another copy of the ptp plugin (e.g. the
base commit's, from ``git archive``) timed in the same rounds: before and after in one run (issue #25).

    python benchmarks/tools/ptpspeed7_ab.py N_IMAGES ROUNDS [paper|real|both] [BASE_PTP_DIR]

``BASE_PTP_DIR`` is a directory holding another version of ``algorithms/ptp`` (its ``__init__.py``), loaded
as the package ``ptp_base``; it is called right after this checkout's ptp in each turn, and the two swap
places on every other image so neither always follows the other. Eighth round: also prints the median over
the images of the paired difference (this checkout's ptp minus the base's, same image and turn), which the
load moves less than either median.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.registry import available_algorithms, get_algorithm

TABLE6_SIM = {"sigma_px": 1.0, "sigma_mag": 0.5, "mag_limit": 6.0, "min_stars": 6}


def load_base(path: str):
    init = Path(path) / "__init__.py"
    spec = importlib.util.spec_from_file_location("ptp_base", init, submodule_search_locations=[str(Path(path))])
    mod = importlib.util.module_from_spec(spec)
    sys.modules["ptp_base"] = mod
    spec.loader.exec_module(mod)
    return mod.PTP


def main(n: int, rounds: int, skies, base: str | None) -> None:
    cat, cam = load_hipparcos(), Camera()
    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    plugins = [(nm, get_algorithm(nm)()) for nm in names]
    if base:
        plugins.append(("ptp_base", load_base(base)()))
    dbs = [a.build(cat, cam) for _, a in plugins]
    labels = [nm for nm, _ in plugins]
    i_ptp = labels.index("ptp")
    for sky in skies:
        sim = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0)
        trials = sim.generate(n)
        obs = [trials.observation(i, truth=False) for i in range(len(trials))]
        for (_, a), db in zip(plugins, dbs, strict=True):
            a.identify(db, obs[0])
        order = list(range(len(plugins)))
        if base:                                  # ptp_base right after ptp
            order.remove(len(plugins) - 1)
            order.insert(i_ptp + 1, len(plugins) - 1)
        out = np.zeros((len(plugins), rounds * len(obs)))
        for k, o in enumerate(obs * rounds):
            seq = list(order)
            if base and k % 2:                    # swap the two on every other image
                seq[i_ptp], seq[i_ptp + 1] = seq[i_ptp + 1], seq[i_ptp]
            for j in seq:
                a, db = plugins[j][1], dbs[j]
                t0 = time.perf_counter_ns()
                a.identify(db, o)
                out[j, k] = (time.perf_counter_ns() - t0) * 1e-9
        t = dict(zip(labels, out, strict=True))
        tetra = float(np.median(t["tetra"])) * 1e6
        line = f"{sky:5s} tetra {tetra:7.1f}"
        for nm in ("ptp", "ptp_base") if base else ("ptp",):
            med = float(np.median(t[nm])) * 1e6
            p95 = float(np.percentile(t[nm], 95)) * 1e6
            line += f"  {nm} {med:7.1f} ({med / tetra:4.2f}x, p95/median {p95 / med:5.2f})"
        if base:
            d = (t["ptp"] - t["ptp_base"]) * 1e6
            lo, hi = np.percentile(d, [25, 75])
            line += f"  paired ptp - base: median {np.median(d):6.1f} us (IQR {lo:6.1f} .. {hi:6.1f})"
        print(line, flush=True)


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4, 5):
        sys.exit(__doc__)
    sk = sys.argv[3] if len(sys.argv) >= 4 else "both"
    main(int(sys.argv[1]), int(sys.argv[2]), ("paper", "real") if sk == "both" else (sk,),
         sys.argv[4] if len(sys.argv) == 5 else None)
