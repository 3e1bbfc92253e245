"""Where the cold cost of ptp's Python wrapper goes (issue #25, eighth speed round): ``PTP.identify`` against
its pieces, each timed once right after the other registered plugins identified the same image (as
``benchmarks/test_ratios.py`` times it: "cold") and as the minimum of 3 repeats right after ("warm").

    python benchmarks/tools/ptpspeed7_wrapper.py N SKY [SEED]

Table 6's images (1 px / 0.5 Mv, seed SEED, default 0), N of them in SKY (paper or real). Median µs over the
images of: tetra's ``identify`` (after every plugin but tetra); ptp's ``identify``, and the same with an inline
identity test of the kept arguments instead of ``kept`` (with the paired difference); the kernel called with
the kept arguments (no wrapper); the kernel and the ``Identification`` (no ``kept``; the kernel as of this
round, which returns ``(hip, counters, tail)``); a numba kernel that returns at once with ptp's six
arguments, alone and with the wrapper's tail before this round and with variants of it; ``kept`` alone and
the same identity test inline; the tail before this round (slices of one array, ``tolist``, ``dict``,
``Identification``) and its pieces, on the array the kernel returned before this round (computed before the
evicting plugins ran); and an empty lambda (the timing's own floor).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from numba import njit
from starid_algorithms.ptp import kernels as K

from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
from starid.plugin import Identification
from starid.registry import available_algorithms, get_algorithm

NW = len(K.WORK_NAMES)


@njit(cache=True)
def _noop6(x_px, y_px, mag, params, narrow, wide):
    return np.zeros(x_px.shape[0] + 5, dtype=np.int64)


@njit(cache=True)
def _noop_tuple(x_px, y_px, mag, params, narrow, wide):
    return np.zeros(x_px.shape[0], dtype=np.int64), (np.int64(1), np.int64(2), np.int64(3), np.int64(4))


@njit(cache=True)
def _noop_flat(x_px, y_px, mag, params, narrow, wide):
    return np.zeros(x_px.shape[0], dtype=np.int64), np.int64(1), np.int64(2), np.int64(3), np.int64(4)


@njit(cache=True)
def _noop_two(x_px, y_px, mag, params, narrow, wide):
    out = np.zeros(2 * x_px.shape[0] + 1, dtype=np.int64)
    return out[:x_px.shape[0]], (np.int64(1), np.int64(2), np.int64(3), np.int64(4)), out[x_px.shape[0]:]


def setup(n: int, sky: str, seed: int = 0):
    """What the ptpspeed7 tools share: ``(camera, ptp, its database, [(plugin, database)] of every other
    registered plugin (by name), n of Table 6's images of ``sky``, ptp's kept kernel arguments (tolerances,
    parameters, packed tables, view))``, ptp warmed up on the first image."""
    cat, cam = load_hipparcos(), Camera()
    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    ptp = get_algorithm("ptp")()
    db = ptp.build(cat, cam)
    rest = [(a, a.build(cat, cam)) for a in (get_algorithm(nm)() for nm in names if nm != "ptp")]
    sim = Simulator(cat, cam, SimConfig(sigma_px=1.0, sigma_mag=0.5, mag_limit=6.0, min_stars=6, **SKIES[sky]),
                    seed=seed)
    trials = sim.generate(n)
    obs = [trials.observation(i, truth=False) for i in range(n)]
    ptp.identify(db, obs[0])
    return cam, ptp, db, rest, obs, ptp.kept("kernel_call", (db, cam), lambda: None)


def main(n: int, sky: str, seed: int) -> None:
    cam, ptp, db, rest, obs, (tol, params, (narrow, wide), view) = setup(n, sky, seed)
    tetra, tdb = next(pair for pair in rest if pair[0].name == "tetra")
    rest = [pair for pair in rest if pair[0] is not tetra] + [(tetra, tdb)]   # tetra last: timed after the others
    kernel = K.identify_kernel
    names_w = K.WORK_NAMES
    state = {}

    def kernel_only(o):
        return kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)

    def legacy(o):                # the kernel's one array before this round: hip, counters, k, sel, rows
        hip, counts, tail = kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return np.concatenate([hip, np.array(counts), [tail.shape[0] // 2], tail])

    def kernel_ident(o):
        hip, counts, _ = kernel(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(hip, counters=dict(zip(names_w, counts, strict=True)))

    def kept_only(o):
        return ptp.kept("kernel_call", (db, o.camera), lambda: None)

    def tail_only(o):
        out, m = state["out"], state["n"]
        return Identification(out[:m], counters=dict(zip(names_w, out[m:m + NW].tolist(), strict=True)))

    def tail_split(o):            # one tolist of the whole array, counters from the list
        out, m = state["out"], state["n"]
        v = out[m:m + NW].tolist()
        return Identification(out[:m], counters={"searches": v[0], "window_triangles": v[1], "candidates": v[2],
                                                  "hypotheses": v[3]})

    def slice_only(o):
        out, m = state["out"], state["n"]
        return out[:m], out[m:m + NW]

    def ident_only(o):
        return Identification(state["out"], counters=state["c"])

    def noop(o):
        return _noop6(o.x_px, o.y_px, o.mag, params, narrow, wide)

    def noop_now(o):              # today's wrapper tail on a kernel that returns at once
        x_px = o.x_px
        m = x_px.shape[0]
        out = _noop6(x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(out[:m], counters=dict(zip(names_w, out[m:m + NW].tolist(), strict=True)))

    def noop_tuple(o):
        hip, c = _noop_tuple(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(hip, counters={"searches": c[0], "window_triangles": c[1], "candidates": c[2],
                                             "hypotheses": c[3]})

    def noop_tuple_zip(o):
        hip, c = _noop_tuple(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(hip, counters=dict(zip(names_w, c, strict=True)))

    def noop_flat(o):
        hip, a, b, c, d = _noop_flat(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(hip, counters={"searches": a, "window_triangles": b, "candidates": c, "hypotheses": d})

    def noop_two(o):
        hip, c, _ = _noop_two(o.x_px, o.y_px, o.mag, params, narrow, wide)
        return Identification(hip, counters={"searches": c[0], "window_triangles": c[1], "candidates": c[2],
                                             "hypotheses": c[3]})

    def memo_inline(o):
        memo = ptp.__dict__.get("_kept")
        held = memo.get("kernel_call") if memo is not None else None
        if held is not None and held[0][0] is db and held[0][1] is o.camera:
            return held[1]
        return None

    memo = {}

    def identify_memo(o):         # PTP.identify with the kept arguments found by an inline identity test
        camera = o.camera
        held = memo.get("call")
        if held is None or held[0] is not db or held[1] is not camera:
            held = memo["call"] = (db, camera, *ptp._kernel_call(db, camera))
        x_px = o.x_px
        hip, counts, tail = kernel(x_px, o.y_px, o.mag, held[3], held[4][0], held[4][1])
        if held[2].assign_all:
            pass
        return Identification(hip, counters=dict(zip(names_w, counts, strict=True)))

    def identify_kept(o):         # PTP.identify's body as a function of the tool (kept and its lambda)
        camera = o.camera
        tol_, params_, (narrow_, wide_), view_ = ptp.kept("kernel_call", (db, camera),
                                                          lambda: ptp._kernel_call(db, camera))
        x_px = o.x_px
        hip, counts, tail = kernel(x_px, o.y_px, o.mag, params_, narrow_, wide_)
        if tol_.assign_all:
            pass
        return Identification(hip, counters=dict(zip(names_w, counts, strict=True)))

    calls = {
        "tetra identify": lambda o: tetra.identify(tdb, o),
        "ptp identify, body with kept": identify_kept,
        "ptp identify": lambda o: ptp.identify(db, o),
        "ptp identify, memo inline": identify_memo,
        "kernel only": kernel_only,
        "kernel + Identification": kernel_ident,
        "noop kernel, 6 args": noop,
        "noop + today's tail": noop_now,
        "noop (hip, 4-tuple) + dict literal": noop_tuple,
        "noop (hip, 4-tuple) + dict(zip)": noop_tuple_zip,
        "noop (hip, 4 ints) + dict literal": noop_flat,
        "noop (hip, 4-tuple, tail)": noop_two,
        "memo inline (no kept call)": memo_inline,
        "kept only": kept_only,
        "tail: slices+tolist+dict+Ident": tail_only,
        "tail: counters by name": tail_split,
        "tail: two slices only": slice_only,
        "Identification() only": ident_only,
        "empty lambda": lambda o: None,
    }
    for f in calls.values():
        state["out"] = legacy(obs[0])
        state["n"] = len(obs[0].x_px)
        state["c"] = {"a": 1}
        f(obs[0])
    for a, d in rest:
        a.identify(d, obs[0])
    cold = {k: [] for k in calls}
    warm = {k: [] for k in calls}
    for o in obs:
        for k, f in calls.items():
            state["out"] = legacy(o)
            state["n"] = len(o.x_px)
            state["c"] = {"a": 1}
            for a, d in rest:
                if k == "tetra identify" and a is tetra:
                    ptp.identify(db, o)        # in tetra's place: every plugin but the one timed
                else:
                    a.identify(d, o)
            t0 = time.perf_counter_ns()
            f(o)
            cold[k].append(time.perf_counter_ns() - t0)
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter_ns()
                f(o)
                best = min(best, time.perf_counter_ns() - t0)
            warm[k].append(best)
    print(f"{sky} sky, {n} images, seed {seed}; median µs: cold (after the other plugins) / warm (min of 3)")
    for k in calls:
        print(f"  {k:32s} {np.median(cold[k]) / 1e3:7.1f} {np.median(warm[k]) / 1e3:7.1f}", flush=True)
    d = np.array(cold["ptp identify, memo inline"]) - np.array(cold["ptp identify"])
    print(f"  paired cold, memo inline - ptp identify: median {np.median(d) / 1e3:.1f} µs")


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    main(int(sys.argv[1]), sys.argv[2], int(sys.argv[3]) if len(sys.argv) == 4 else 0)
