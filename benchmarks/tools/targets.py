"""Issue #25's "Done when" in one command: every speed target measured on this checkout, one report.

    python benchmarks/tools/targets.py --out DIR [--ratio-runs 4] [--cold-runs 2] [--no-first-command]
                                       [--no-zhou2015] [--rows] [--rows-against REF_DIR]

Run it on an otherwise idle machine (the targets are the issue's, for its 2-core machine); it takes
some 10 minutes, 2 more with ``--rows``. One step after another, each in processes of its own:

1. **First command** (unless ``--no-first-command``): ``git clone`` of HEAD (commit first: the clone
   does not see uncommitted edits), a new venv, ``pip install -e .``, ``starid table6``, no numba cache
   anywhere (``benchmarks/test_compile.py``'s :func:`first_command`). Target 180 s. Its results folder
   is kept as ``DIR/rows/first_command`` (compared with ``--rows-against`` like the rest).
2. **Cold compile**, ``--cold-runs`` times (0: not measured): every registered plugin prepared by 2
   processes sharing an empty numba cache (``benchmarks/test_compile.py``'s :func:`cold_compile`); wall
   seconds, and each plugin's compile and CPU seconds. Target 40 s wall.
3. **zhou2015** (unless ``--no-zhou2015``): ``starid reproduce zhou2015 --trials 2000`` in this
   environment with a warm numba cache (an untimed ``--trials 2`` run first compiles whatever is not
   cached yet); wall, user and system seconds. Target 240 s.
4. **Per image**, ``--ratio-runs`` runs (0: not measured), each a new process timing every plugin image
   by image on Table 6's 200 images of each sky, three rounds (``benchmarks/test_ratios.py``'s
   :func:`time_per_image`). Per plugin and sky: the median over the runs of its median, its ratio to
   tetra's median of the same run, and its p95 / median. Targets: ``RATIO_TO_TETRA`` and
   ``P95_TO_MEDIAN`` of that file.
5. **Same results** (``--rows``): ``starid table6 --trials 300 --jobs 2``; every plugin and published
   variant (``NAME:paper``) at Table 6's settings, 150 trials, on the paper's sky, the real sky and the
   real sky with 3 false stars; ``starid reproduce zhou2015 --trials 200``; written under ``DIR/rows``.
   With ``--rows-against REF_DIR`` (an earlier report's ``rows`` folder) each is compared row by row
   (``compare_rows.py``): the non-time columns that differ, and the images that turned correct -> not
   correct ("lost"). Target: none lost (and, for a change meant to keep results, none differing).

Writes ``DIR/targets.json`` (every number) and ``DIR/targets.md`` (the table a closing note gives),
each atomically; prints the table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))              # benchmarks.test_compile, benchmarks.test_ratios
sys.path.insert(0, str(Path(__file__).resolve().parent))   # compare_rows

from compare_rows import compare  # noqa: E402

from benchmarks.test_compile import (  # noqa: E402
    COLD_COMPILE_WALL_S,
    FIRST_COMMAND_WALL_S,
    _names,
    cold_compile,
    first_command,
)
from benchmarks.test_ratios import P95_TO_MEDIAN, RATIO_TO_TETRA, REFERENCE  # noqa: E402
from benchmarks.test_reproduce import ZHOU2015_WALL_S  # noqa: E402
from starid.io import atomic_write_text  # noqa: E402

SKIES = ("paper", "real")
TABLE6_SIM = ["--pos-noise-px", "1", "--mag-noise", "0.5", "--mag-limit", "6", "--min-stars", "6"]
#: the same-results set's ``starid run`` folders: name -> the sky's arguments (Table 6's noise besides)
ROW_SKIES = {"paper": ["--sky", "paper"], "real": ["--sky", "real"],
             "false3": ["--sky", "real", "--false-stars", "3"]}

#: one ratio run: every plugin timed image by image on each sky; prints {sky: {name: [median_us, p95_us]}}
_RATIO_RUN = r"""
import json
import numpy as np
from starid import Camera, load_hipparcos
from benchmarks.test_ratios import time_per_image
catalog, camera = load_hipparcos(), Camera()
out = {}
for sky in ("paper", "real"):
    times = time_per_image(catalog, camera, sky)
    out[sky] = {n: [float(np.median(t)) * 1e6, float(np.percentile(t, 95)) * 1e6] for n, t in times.items()}
print(json.dumps(out))
"""


def _now() -> str:
    return time.strftime("%H:%M:%S", time.gmtime())


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def _say(text: str) -> None:
    print(f"[{_now()} load {_load():.1f}] {text}", flush=True)


def machine() -> dict:
    """What the numbers were measured on: commit, processor, cores, versions, load at the start."""
    import llvmlite.binding
    import numba

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                            text=True).stdout.strip()
    dirty = bool(subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                                capture_output=True, text=True).stdout.strip())
    cpu = platform.processor()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                   if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"commit": commit, "uncommitted_changes": dirty, "cpu": cpu, "cores": os.cpu_count(),
            "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
            "llvm": ".".join(map(str, llvmlite.binding.llvm_version_info)),
            "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "load": _load()}


def measure_first_command(keep: Path) -> dict:
    """The first command's times; its results folder (Table 6 at 10,000 trials) is kept as ``keep``."""
    with tempfile.TemporaryDirectory(prefix="starid-first-") as tmp:
        load = _load()
        wall_s, install_s = first_command(Path(tmp))
        written = (Path(tmp) / "out" / "table6.md").exists()
        if written:
            shutil.rmtree(keep, ignore_errors=True)
            shutil.copytree(Path(tmp) / "out", keep)
    return {"wall_s": round(wall_s, 1), "install_s": round(install_s, 1), "load": load, "written": written}


def measure_cold(runs: int) -> list[dict]:
    """Each run's wall seconds and plugin records, and how many plugins it should have prepared."""
    out = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix="starid-numba-") as tmp:
            load = _load()
            wall_s, records = cold_compile(Path(tmp), 2)
        out.append({"wall_s": round(wall_s, 1), "load": load, "expected": len(_names()), "plugins": records})
    return out


def measure_ratios(runs: int) -> list[dict]:
    """Each run's medians and p95s; a run that fails ends the step with its error (the step's result
    is then the error alone: a part of the runs would be another measurement)."""
    out = []
    for _ in range(runs):
        load = _load()
        r = subprocess.run([sys.executable, "-c", _RATIO_RUN], cwd=REPO, capture_output=True, text=True)
        if r.returncode != 0:
            return [{"error": (r.stderr.strip().splitlines() or ["no output"])[-1]}]
        out.append({"load": load, **json.loads(r.stdout.strip().splitlines()[-1])})
    return out


def _timed(command: list[str]) -> dict:
    """Wall, user and system seconds of one command run to its end (its children included)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load, t0 = _load(), time.perf_counter()
    r = subprocess.run(command, cwd=REPO, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"command": " ".join(command[2:]), "wall_s": round(wall, 1), "load": load,
            "user_s": round(after.ru_utime - before.ru_utime, 1),
            "system_s": round(after.ru_stime - before.ru_stime, 1),
            "returncode": r.returncode, "stderr_tail": r.stderr.strip().splitlines()[-3:]}


def measure_zhou2015(out: Path) -> dict:
    """zhou2015 at 2,000 trials, timed, after an untimed run of 2 trials (the numba cache warm)."""
    command = [sys.executable, "-m", "starid", "reproduce", "zhou2015", "--quiet", "--overwrite", "--out", str(out)]
    subprocess.run(command + ["--trials", "2"], cwd=REPO, capture_output=True)   # a failure shows in the next
    return _timed(command + ["--trials", "2000"])


def readings() -> list[str]:
    """Every registered plugin, and the published variant of each that has one."""
    from starid.registry import available_algorithms, get_algorithm

    names = sorted(i.name for i in available_algorithms() if i.status == "ok")
    return names + [f"{n}:paper" for n in names if get_algorithm(n).published]


def run_rows(folder: Path) -> dict:
    """The same-results set under ``folder``; each entry's command, times and exit status."""
    starid = [sys.executable, "-m", "starid"]
    runs = {"table6": starid + ["table6", "--trials", "300", "--jobs", "2"],
            "zhou200": starid + ["reproduce", "zhou2015", "--trials", "200"]}
    names = readings()
    for name, sky in ROW_SKIES.items():
        runs[name] = starid + ["run", *names, "--trials", "150", "--jobs", "2", *TABLE6_SIM, *sky]
    done = {}
    for name, command in runs.items():
        _say(f"rows: {name}")
        done[name] = _timed(command + ["--quiet", "--overwrite", "--out", str(folder / name)])
    return done


def compare_rows(folder: Path, reference: Path) -> dict:
    out = {}
    for sub in sorted(p.name for p in reference.iterdir() if (p / "results.parquet").exists()):
        if not (folder / sub / "results.parquet").exists():
            out[sub] = {"missing": True}
            continue
        r = compare(reference / sub, folder / sub)
        out[sub] = {"rows": r["rows"], "compared": r["compared"], "differing": r["differing"],
                    "only_before": r["only_before"], "only_after": r["only_after"],
                    "lost": sum(g[3] for g in r["groups"]), "gained": sum(g[4] for g in r["groups"]),
                    "correct": [(str(g[0]), g[1], g[2]) for g in r["groups"]]}
    return out


def summarise_ratios(runs: list[dict]) -> dict:
    """Per sky and plugin: the medians over the runs of its median (µs), its ratio to the reference's
    median of the same run, and its p95 / median; and each run's ratio."""
    out = {}
    for sky in SKIES:
        names = list(runs[0][sky])
        out[sky] = {}
        for n in names:
            med = [r[sky][n][0] for r in runs]
            ratio = [r[sky][n][0] / r[sky][REFERENCE][0] for r in runs]
            tail = [r[sky][n][1] / r[sky][n][0] for r in runs]
            out[sky][n] = {"median_us": float(np.median(med)), "ratio": float(np.median(ratio)),
                           "ratio_runs": [round(x, 2) for x in ratio], "p95_to_median": float(np.median(tail))}
    return out


def _spread(values: list[float]) -> str:
    """A list of runs' values as their range ("2.15-2.30"), or the one value."""
    lo, hi = min(values), max(values)
    return f"{lo:.2f}" if lo == hi else f"{lo:.2f}-{hi:.2f}"


def verdicts(report: dict) -> list[dict]:
    """One line per target of the issue: what was measured and whether it is met."""
    lines = []
    fc = report.get("first_command")
    if fc:
        lines.append({"target": f"first command (fresh clone, new venv, empty caches) <= {FIRST_COMMAND_WALL_S:g} s",
                      "measured": f"{fc['wall_s']:.0f} s (clone + venv + install {fc['install_s']:.0f} s)",
                      "met": fc["written"] and fc["wall_s"] <= FIRST_COMMAND_WALL_S})
    cold = report.get("cold_compile")
    if cold:
        walls = [c["wall_s"] for c in cold]
        lines.append({"target": f"cold compile of every plugin, 2 processes <= {COLD_COMPILE_WALL_S:g} s wall",
                      "measured": " / ".join(f"{w:.1f} s" for w in walls),
                      "met": all(len(c["plugins"]) == c["expected"] and not any(p["error"] for p in c["plugins"])
                                 for c in cold) and float(np.median(walls)) <= COLD_COMPILE_WALL_S})
    z = report.get("zhou2015")
    if z:
        lines.append({"target": f"starid reproduce zhou2015 --trials 2000 <= {ZHOU2015_WALL_S:g} s",
                      "measured": f"{z['wall_s']:.1f} s ({z['user_s']:.0f} s user)",
                      "met": z["returncode"] == 0 and z["wall_s"] <= ZHOU2015_WALL_S})
    failed = [r["error"] for r in report.get("ratio_runs", []) if "error" in r]
    if failed:
        lines.append({"target": "per image (ratios to tetra, p95)", "measured": f"not measured: {failed[0]}",
                      "met": False})
    ratios = report.get("ratios")
    if ratios:
        for limit in sorted(set(RATIO_TO_TETRA.values())):
            names = sorted(n for n, v in RATIO_TO_TETRA.items() if v == limit)
            over = [f"{n} {sky} {ratios[sky][n]['ratio']:.2f}x ({_spread(ratios[sky][n]['ratio_runs'])})"
                    for n in names for sky in SKIES if n in ratios[sky] and ratios[sky][n]["ratio"] > limit]
            absent = [n for n in names if any(n not in ratios[sky] for sky in SKIES)]
            said = (["over: " + ", ".join(over)] if over else []) + (["not measured: " + ", ".join(absent)]
                                                                     if absent else [])
            lines.append({"target": f"{', '.join(names)} <= {limit:g}x {REFERENCE}'s median",
                          "measured": "; ".join(said) or "all within", "met": not over and not absent})
        over = [f"{n} {sky} {ratios[sky][n]['p95_to_median']:.2f}" for sky in SKIES for n in ratios[sky]
                if ratios[sky][n]["p95_to_median"] > P95_TO_MEDIAN]
        total = sum(len(ratios[sky]) for sky in SKIES)
        lines.append({"target": f"every p95 <= {P95_TO_MEDIAN:g}x its median",
                      "measured": f"{total - len(over)} of {total}" + (f" (over: {', '.join(over)})" if over else ""),
                      "met": not over})
    rows = report.get("rows_compared")
    if rows:
        lost = sum(r.get("lost", 0) for r in rows.values())
        differing = sum(len(r.get("differing", [])) for r in rows.values())
        missing = [k for k, r in rows.items() if r.get("missing")]
        unjoined = [k for k, r in rows.items() if not r.get("missing") and len(set(r["rows"])) > 1]
        lines.append({"target": "no correct identification lost",
                      "measured": f"{lost} lost, {sum(r.get('gained', 0) for r in rows.values())} gained; "
                                  f"{differing} non-time columns differing over {len(rows)} folders"
                                  + (f"; missing: {', '.join(missing)}" if missing else "")
                                  + (f"; rows not all joined: {', '.join(unjoined)}" if unjoined else ""),
                      "met": lost == 0 and not missing and not unjoined})
    return lines


def markdown(report: dict) -> str:
    m = report["machine"]
    text = [f"# Issue #25's targets on {m['commit']}{' (uncommitted changes)' if m['uncommitted_changes'] else ''}",
            "", f"{m['date_utc']} UTC; {m['cpu']}, {m['cores']} cores; Python {m['python']}, numpy {m['numpy']}, "
            f"numba {m['numba']} (LLVM {m['llvm']}); load {m['load']} at the start.", "",
            "| target | measured | met |", "|---|---|---|"]
    text += [f"| {v['target']} | {v['measured']} | {'yes' if v['met'] else 'no'} |" for v in report["verdicts"]]
    cold = report.get("cold_compile")
    if cold:
        text += ["", "Cold compile per plugin, compile s / CPU s, one column per run:", "",
                 "| plugin | " + " | ".join(f"run {k + 1}" for k in range(len(cold))) + " |",
                 "|---|" + "---:|" * len(cold)]
        per = {}
        for c in cold:
            for p in c["plugins"]:
                per.setdefault(p["plugin"], []).append(f"{p['compile_s']:.1f} / {p['cpu_s']:.1f}")
        text += [f"| {n} | " + " | ".join(v) + " |" for n, v in per.items()]
        text += ["| CPU s per process | " + " | ".join(
            " + ".join(f"{sum(p['cpu_s'] for p in c['plugins'] if p['process'] == k):.1f}"
                       for k in sorted({p["process"] for p in c["plugins"]})) for c in cold) + " |"]
        text += ["| **wall, 2 processes** | " + " | ".join(f"**{c['wall_s']:.1f} s**" for c in cold) + " |"]
    ratios = report.get("ratios")
    if ratios:
        runs = len(report["ratio_runs"])
        text += ["", f"Per image, median µs and ratio to {REFERENCE}'s median "
                 + (f"(each the median of {runs} runs):" if runs > 1 else "(one run):"), "",
                 "| plugin | paper's sky µs | ratio | p95 / median | real sky µs | ratio | p95 / median |",
                 "|---|---:|---:|---:|---:|---:|---:|"]
        for n in sorted(ratios["real"], key=lambda n: ratios["real"][n]["ratio"]):
            cells = []
            for sky in SKIES:
                r = ratios[sky][n]
                cells += [f"{r['median_us']:.1f}", f"{r['ratio']:.2f}x", f"{r['p95_to_median']:.2f}"]
            text.append(f"| {n} | " + " | ".join(cells) + " |")
    rows = report.get("rows_compared")
    if rows:
        text += ["", "Same results against the reference rows:", "", "| folder | rows (before, after, joined) | "
                 "non-time columns | differing | lost | gained |", "|---|---|---:|---|---:|---:|"]
        for k, r in rows.items():
            if r.get("missing"):
                text.append(f"| {k} | missing | | | | |")
                continue
            text.append(f"| {k} | {r['rows']} | {r['compared']} | {r['differing'] or 'none'} | {r['lost']} | "
                        f"{r['gained']} |")
    return "\n".join(text) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, type=Path, help="folder for targets.json, targets.md (and rows/)")
    ap.add_argument("--ratio-runs", type=int, default=4, help="per-image runs (0: none)")
    ap.add_argument("--cold-runs", type=int, default=2, help="cold compiles (0: none)")
    ap.add_argument("--no-first-command", action="store_true")
    ap.add_argument("--no-zhou2015", action="store_true")
    ap.add_argument("--rows", action="store_true", help="run the same-results set into OUT/rows")
    ap.add_argument("--rows-against", type=Path, help="an earlier report's rows folder to compare with")
    a = ap.parse_args(argv)
    if a.rows_against is not None and not a.rows_against.is_dir():
        ap.error(f"--rows-against {a.rows_against}: not a folder")
    a.out.mkdir(parents=True, exist_ok=True)
    report: dict = {"machine": machine()}
    if report["machine"]["uncommitted_changes"] and not a.no_first_command:
        _say("note: uncommitted changes; the first command clones HEAD without them")
    if not a.no_first_command:
        _say("first command")
        report["first_command"] = measure_first_command(a.out / "rows" / "first_command")
    if a.cold_runs > 0:
        _say(f"cold compile x {a.cold_runs}")
        report["cold_compile"] = measure_cold(a.cold_runs)
    if not a.no_zhou2015:
        _say("zhou2015 --trials 2000")
        report["zhou2015"] = measure_zhou2015(a.out / "zhou2015")
    if a.ratio_runs > 0:
        _say(f"per image x {a.ratio_runs}")
        report["ratio_runs"] = measure_ratios(a.ratio_runs)
        if not any("error" in r for r in report["ratio_runs"]):
            report["ratios"] = summarise_ratios(report["ratio_runs"])
    if a.rows:
        report["rows"] = run_rows(a.out / "rows")
    if a.rows_against is not None:
        report["rows_compared"] = compare_rows(a.out / "rows", a.rows_against)
    report["verdicts"] = verdicts(report)
    report["load_at_end"] = _load()
    atomic_write_text(a.out / "targets.json", json.dumps(report, indent=1, default=str) + "\n")
    text = markdown(report)
    atomic_write_text(a.out / "targets.md", text)
    print(text)
    return 0 if all(v["met"] for v in report["verdicts"]) else 1


if __name__ == "__main__":
    sys.exit(main())
