"""The ``starid`` command line: ``list``, ``run``, ``identify``, ``table6`` (see ``starid --help``)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__, table6
from .camera import Camera
from .catalog import Catalog, load_csv, load_hipparcos
from .errors import ConfigError, ObservationError, StarIDError
from .harness import SUMMARY_COLUMNS, SuccessRule, prepare, run, score_trial, summarize, timed_identify
from .io import atomic_write_text, read_numeric_csv, write_frame
from .observation import Observation
from .plugin import Algorithm
from .registry import available_algorithms, get_algorithm
from .simulate import SimConfig, Simulator

# the summary columns named by the CLI contract (summary.csv adds error_rate and the attitude error)
SHOWN_COLUMNS = SUMMARY_COLUMNS[:SUMMARY_COLUMNS.index("compile_s") + 1]


def _parse_value(text: str):
    low = text.strip().lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("none", "null"):
        return None
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def parse_overrides(items: list[str], names: list[str]) -> dict[str, dict]:
    """``ALGO.KEY=VALUE`` strings -> ``{algo: {key: value}}`` (values parsed as bool/None/int/float/str)."""
    out: dict[str, dict] = {name: {} for name in names}
    for item in items:
        head, sep, value = item.partition("=")
        algo, dot, key = head.partition(".")
        if not (sep and dot and key):
            raise ConfigError(f"--set expects ALGO.KEY=VALUE, got {item!r}")
        if algo not in out:
            raise ConfigError(f"--set names {algo!r}, which is not among the algorithms run ({', '.join(names)})")
        out[algo][key] = _parse_value(value)
    return out


def make_algorithm(name: str, params: dict) -> Algorithm:
    cls = get_algorithm(name)
    try:
        return cls(**params)
    except TypeError as exc:
        raise ConfigError(f"{name}: {exc}") from None


def _catalog(path: str | None) -> Catalog:
    return load_csv(path) if path else load_hipparcos()


def _camera(args) -> Camera:
    res = args.resolution
    if args.fov_deg is not None:
        if args.focal_mm is not None:
            raise ConfigError("give either --fov-deg or --focal-mm, not both")
        return Camera.from_fov(args.fov_deg, res or 1024, args.pixel_um or 12.0)
    if res is None and args.focal_mm is None and args.pixel_um is None:
        return Camera()
    base = Camera()
    return Camera(width_px=res or base.width_px, height_px=res or base.height_px,
                  pixel_um=args.pixel_um or base.pixel_um, focal_mm=args.focal_mm or base.focal_mm)


def _progress(args) -> bool:
    return not args.quiet and sys.stderr.isatty()


def format_summary(summary: pd.DataFrame) -> str:
    """A fixed-width text table of the summary columns."""
    return summary[SHOWN_COLUMNS].to_string(index=False, float_format=lambda v: f"{v:.4g}")


def cmd_list(args) -> int:
    infos = available_algorithms()
    if not infos:
        print("no algorithms registered")
        return 0
    width = max(len(i.name) for i in infos)
    for info in infos:
        text = info.summary if info.status == "ok" else info.error
        print(f"{info.name:<{width}}  {info.status:<6}  {text}")
    return 0


def add_sim_arguments(p: argparse.ArgumentParser, trials_default: int, seed_default: int,
                      pos_default: float = 0.0, mag_default: float = 0.0) -> None:
    p.add_argument("--trials", type=int, default=trials_default, help=f"number of images (default {trials_default})")
    p.add_argument("--seed", type=int, default=seed_default, help=f"simulator seed (default {seed_default})")
    p.add_argument("--pos-noise-px", type=float, default=pos_default, help="centroid noise sigma in px")
    p.add_argument("--mag-noise", type=float, default=mag_default, help="magnitude noise sigma in mag")
    p.add_argument("--false-stars", type=int, default=0, help="false stars added per image")
    p.add_argument("--lost-stars", type=int, default=0, help="detections removed per image")
    p.add_argument("--min-stars", type=int, default=6, help="redraw images with fewer true stars (default 6)")
    p.add_argument("--mag-limit", type=float, default=6.0, help="sensor detection limit in mag (default 6.0)")
    p.add_argument("--merge-radius-px", type=float, default=2.0, help="stars closer merge (default 2 px)")
    p.add_argument("--sky-mag-limit", type=float, default=None,
                   help="simulate only catalog stars with V <= this (default: the whole catalog, V <= 8; "
                        "6.0 reproduces the papers' convention of imaging the guide list only)")
    p.add_argument("--catalog", help="CSV catalog (hip,ra_deg,dec_deg,vmag) instead of the embedded Hipparcos")
    p.add_argument("--out", type=Path, help="write trials.csv and summary.csv (and .parquet) here")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def simulator_from_args(args, catalog: Catalog, camera: Camera | None = None) -> Simulator:
    config = SimConfig(sigma_px=args.pos_noise_px, sigma_mag=args.mag_noise, mag_limit=args.mag_limit,
                       false_stars=args.false_stars, lost_stars=args.lost_stars, min_stars=args.min_stars,
                       merge_radius_px=args.merge_radius_px)
    sky = catalog if args.sky_mag_limit is None else catalog.brighter_than(args.sky_mag_limit)
    return Simulator(sky, camera or Camera(), config, seed=args.seed)


def cmd_run(args) -> int:
    catalog = _catalog(args.catalog)
    overrides = parse_overrides(args.set or [], args.algorithms)
    algorithms = [make_algorithm(name, overrides[name]) for name in args.algorithms]
    if args.trials < 1:
        raise ConfigError(f"--trials must be >= 1, got {args.trials}")
    sim = simulator_from_args(args, catalog)
    t0 = time.perf_counter()
    trials = sim.generate(args.trials)
    sim_s = time.perf_counter() - t0
    df = run(algorithms, trials, catalog, sim, SuccessRule(), progress=_progress(args), jobs=args.jobs)
    summary = summarize(df)
    print(f"{len(trials)} trials, seed {args.seed}, {args.pos_noise_px:g} px / {args.mag_noise:g} mag noise, "
          f"{args.false_stars} false / {args.lost_stars} lost stars; simulated in {sim_s:.2f} s "
          f"({int(trials.n_redraws.sum())} attitudes redrawn for < {args.min_stars} stars)")
    print(format_summary(summary))
    if args.out:
        write_frame(df, args.out / "trials.csv")
        write_frame(summary, args.out / "summary.csv")
        print(f"wrote {args.out / 'trials.csv'} and {args.out / 'summary.csv'}")
    return 0


OBS_REQUIRED = ("trial", "x_px", "y_px", "mag")


def read_observations(path: Path, camera: Camera) -> tuple[list[int], list[Observation], bool]:
    """Read OBS.csv (``trial, x_px, y_px, mag[, truth_hip]``); every problem names its line."""
    cols, lines = read_numeric_csv(path, list(OBS_REQUIRED), ("truth_hip",), error=ObservationError)
    if not lines.size:
        raise ObservationError(f"{path}: no observations")
    has_truth = "truth_hip" in cols
    truth = cols.get("truth_hip", np.full(lines.size, -1.0))
    for name, values in (("trial", cols["trial"]), ("truth_hip", truth)):
        bad = np.flatnonzero(values != np.round(values))
        if bad.size:
            raise ObservationError(f"{path}, line {lines[bad[0]]}: {name} must be a whole number")
    off = np.flatnonzero(~camera.in_image(cols["x_px"], cols["y_px"]))
    if off.size:
        k = off[0]
        raise ObservationError(f"{path}, line {lines[k]}: ({cols['x_px'][k]}, {cols['y_px'][k]}) px lies outside "
                               f"the {camera.width_px}x{camera.height_px} image")
    trial = cols["trial"].astype(np.int64)
    trials = sorted(set(trial.tolist()))
    observations = []
    for t in trials:
        rows = np.flatnonzero(trial == t)   # input order within the trial
        observations.append(Observation(cols["x_px"][rows], cols["y_px"][rows], cols["mag"][rows], camera,
                                        truth[rows].astype(np.int64) if has_truth else None))
    return trials, observations, has_truth


def cmd_identify(args) -> int:
    camera = _camera(args)
    trials, observations, has_truth = read_observations(args.obs, camera)
    catalog = _catalog(args.catalog)
    algorithm = make_algorithm(args.algorithm, parse_overrides(args.set or [], [args.algorithm])[args.algorithm])
    prepared = prepare(algorithm, catalog, camera, observations[0])
    id_rows, trial_rows, scored = [], [], []
    rule = SuccessRule()
    for t, obs in zip(trials, observations):
        hip, elapsed_ns, error = timed_identify(algorithm, prepared.database, obs, catalog.hip)
        n_id = int((hip != -1).sum())
        if has_truth:
            s = score_trial(hip, obs.truth_hip, rule)
            s["status"] = "error" if error else s["status"]
            scored.append({"algorithm": algorithm.name, "trial": t, "n_true_stars": int((obs.truth_hip >= 0).sum()),
                           "time_us": elapsed_ns / 1e3, "db_mb": prepared.database.nbytes / 1e6,
                           "build_s": prepared.build_s, "compile_s": prepared.compile_s,
                           "attitude_err_arcsec": float("nan"), **s})
            status = s["status"]
        else:
            status = "error" if error else ("identified" if n_id >= rule.min_correct else "no_result")
        id_rows += [{"trial": t, "star": j, "hip": int(h)} for j, h in enumerate(hip)]
        trial_rows.append({"trial": t, "status": status, "n_identified": n_id, "time_us": elapsed_ns / 1e3,
                           "error": error})
    args.out.mkdir(parents=True, exist_ok=True)
    write_frame(pd.DataFrame(id_rows, columns=["trial", "star", "hip"]), args.out / "identifications.csv")
    write_frame(pd.DataFrame(trial_rows, columns=["trial", "status", "n_identified", "time_us", "error"]),
                args.out / "trials.csv")
    n_ok = sum(r["status"] in ("identified", "correct") for r in trial_rows)
    print(f"{algorithm.name}: {len(trials)} images, {n_ok} identified; wrote {args.out}")
    if has_truth:
        summary = summarize(pd.DataFrame(scored))
        write_frame(summary, args.out / "summary.csv")
        print(format_summary(summary))
    return 0


def cmd_table6(args) -> int:
    if args.trials < 1:
        raise ConfigError(f"--trials must be >= 1, got {args.trials}")
    catalog = _catalog(args.catalog)
    algorithms = [make_algorithm(name, {}) for name in table6.ALGORITHMS]
    config = SimConfig(**table6.SIM)
    sky = catalog if args.sky_mag_limit is None else catalog.brighter_than(args.sky_mag_limit)
    sim = Simulator(sky, Camera(), config, seed=args.seed)
    t0 = time.perf_counter()
    trials = sim.generate(args.trials)
    df = run(algorithms, trials, catalog, sim, SuccessRule(), progress=_progress(args), jobs=args.jobs)
    wall_s = time.perf_counter() - t0
    summary, tests = table6.table(df)
    sky_text = "V <= 8.0 sky" if args.sky_mag_limit is None else f"V <= {args.sky_mag_limit:g} sky"
    header = (f"Table 6 (Zhou & Ye 2015) regenerated by starid {__version__}: {args.trials} images, seed {args.seed}, "
              f"1 px / 0.5 Mv noise, > 5 stars, {sky_text}, 10x10 deg FOV; {wall_s:.1f} s wall with {args.jobs} "
              f"job(s), databases included ({int(trials.n_redraws.sum())} attitudes redrawn)")
    text = table6.markdown(summary, tests, header)
    print(text, end="")
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out / "table6.md", text)
        write_frame(summary, args.out / "table6.csv")
        write_frame(df, args.out / "trials.csv")
        print(f"wrote {args.out / 'table6.md'}, {args.out / 'table6.csv'} and {args.out / 'trials.csv'}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="starid", description="Compare lost-in-space star-identification "
                                     "algorithms on one catalog, one simulator and one scoring harness.")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list registered algorithms").set_defaults(func=cmd_list)

    p = sub.add_parser("run", help="score algorithms on simulated images")
    p.add_argument("algorithms", nargs="+", metavar="ALGO")
    add_sim_arguments(p, trials_default=1000, seed_default=0)
    p.add_argument("--set", action="append", metavar="ALGO.KEY=VALUE", help="override an algorithm parameter")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1; results identical)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("table6", help="regenerate Table 6 of Zhou & Ye (2015): PTP vs P-vector vs planar triangle")
    p.add_argument("--trials", type=int, default=10_000, help="number of images (default 10,000)")
    p.add_argument("--seed", type=int, default=0, help="simulator seed (default 0)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)")
    p.add_argument("--sky-mag-limit", type=float, default=None,
                   help="simulate only stars with V <= this (6.0: the paper's convention; default: V <= 8)")
    p.add_argument("--catalog", help="CSV catalog instead of the embedded Hipparcos")
    p.add_argument("--out", type=Path, help="write table6.md, table6.csv and trials.csv here")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_table6)

    p = sub.add_parser("identify", help="identify your own centroids (OBS.csv: trial,x_px,y_px,mag[,truth_hip])")
    p.add_argument("algorithm", metavar="ALGO")
    p.add_argument("obs", type=Path, metavar="OBS.csv")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--fov-deg", type=float, help="square field of view across the image width")
    p.add_argument("--resolution", type=int, help="image width = height in px (default 1024)")
    p.add_argument("--focal-mm", type=float, help="focal length in mm (default 70.2262)")
    p.add_argument("--pixel-um", type=float, help="pixel pitch in um (default 12)")
    p.add_argument("--catalog", help="CSV catalog instead of the embedded Hipparcos")
    p.add_argument("--set", action="append", metavar="ALGO.KEY=VALUE", help="override an algorithm parameter")
    p.set_defaults(func=cmd_identify)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except StarIDError as exc:
        print(f"starid: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
