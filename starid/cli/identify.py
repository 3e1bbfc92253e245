"""``identify`` (your own centroids) and ``simulate`` (the simulator's images in the same format)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..catalog import load_csv, load_hipparcos
from ..errors import ObservationError
from ..experiment.executors import Limits, Outcome, after_memory_error, call_per_item, memory_error
from ..harness import Prepared, prepare, rows_to_frame, timed_identify
from ..io import read_numeric_csv, write_frames
from ..observation import Observation
from ..scoring import CRASHED, ERROR, SuccessRule, score_trial
from ..simulate import SimConfig, Simulator
from ..stats import summarize
from .experiments import format_summary, variants
from .options import (
    add_camera,
    add_limits,
    add_world,
    camera_spec,
    check_out,
    make_camera,
    progress,
    seed_type,
    trials_type,
    world_settings,
)

OBS_REQUIRED = ("trial", "x_px", "y_px", "mag")
ID_COLUMNS = ["trial", "star", "hip", "x_px", "y_px", "mag", "truth_hip", "algorithm", "label"]
#: identify's trials.csv starts with these (then the trial-row schema of ``starid run``).
IDENTIFY_TRIAL_COLUMNS = ["trial", "status", "n_identified", "time_us", "error"]


def read_observations(path: Path, camera) -> tuple[list[int], list[Observation], bool]:
    """Read OBS.csv (``trial, x_px, y_px, mag[, truth_hip]``); every problem names its line."""
    cols, lines = read_numeric_csv(path, list(OBS_REQUIRED), ("truth_hip",), error=ObservationError,
                                   integer=("trial", "truth_hip"))
    if not lines.size:
        raise ObservationError(f"{path}: no observations")
    has_truth = "truth_hip" in cols
    off = np.flatnonzero(~camera.in_image(cols["x_px"], cols["y_px"]))
    if off.size:
        k = off[0]
        raise ObservationError(f"{path}, line {lines[k]}: ({cols['x_px'][k]}, {cols['y_px'][k]}) px lies outside "
                               f"the {camera.width_px}x{camera.height_px} image")
    trial = cols["trial"]
    trials = sorted(set(trial.tolist()))
    observations = []
    for t in trials:
        rows = np.flatnonzero(trial == t)   # input order within the trial
        observations.append(Observation(cols["x_px"][rows], cols["y_px"][rows], cols["mag"][rows], camera,
                                        cols["truth_hip"][rows] if has_truth else None))
    return trials, observations, has_truth


class _Size:
    """A database's size alone (what a trial row reports), sent back instead of the database."""

    def __init__(self, nbytes: int):
        self.nbytes = nbytes


def _identify_one(variant, catalog, camera, trials, observations, has_truth, fov_range, control, start):
    """In the supervised process: prepare ``variant`` and identify images ``start..``, each sent with
    ``control.emit((k, (row, hip)))``; the prepared algorithm's sizes as ``k = -1``."""
    from .images import band_preparer, solve_image

    def on_phase(phase: str) -> None:
        control.phase("the warm-up identify" if phase == "warmup" else "derived/build", build=True)

    prepared = prepare(variant.make(), catalog, camera, observations[0], variant.label, on_phase)
    db = None if prepared.database is None else _Size(prepared.database.nbytes)
    control.emit((-1, Prepared(prepared.algorithm, prepared.label, db, prepared.build_s, prepared.compile_s,
                               prepared.error)))
    bands = band_preparer(variant, catalog, camera, observations[0], on_phase) if fov_range is not None else None
    rule = SuccessRule()
    for k in range(start, len(trials)):
        t, obs = trials[k], observations[k]
        control.phase("identify")
        if fov_range is None:
            hip, elapsed_ns, error = timed_identify(prepared, obs, catalog.hip)
        else:          # the field-of-view search: the time is the whole search's; each call under the limit
            t0 = time.perf_counter_ns()
            hip, _, _, _, error = solve_image(prepared, obs, catalog, fov_range_deg=fov_range, prepared_for=bands,
                                              on_call=lambda: control.phase("identify"))
            elapsed_ns = time.perf_counter_ns() - t0
        row = {"trial": t, "n_stars": len(obs),
               "n_true_stars": int((obs.truth_hip >= 0).sum()) if has_truth else -1, "error": error,
               **score_trial(hip, obs.truth_hip, rule), "time_us": elapsed_ns / 1e3, "n_redraws": 0,
               "attitude_err_arcsec": float("nan")}
        if error:
            row["status"] = ERROR
        after_memory_error(error)       # what a kernel leaked on running out is not the next image's
        control.emit((k, (row, hip)))


def cmd_identify(args) -> int:
    from .images import parse_fov_range

    check_out(args.out)
    limits = Limits.from_args(args)
    fov_range = parse_fov_range(args.fov_range) if getattr(args, "fov_range", None) is not None else None
    camera = make_camera(camera_spec(args))
    trials, observations, has_truth = read_observations(args.obs, camera)
    algorithm_variants = variants(args.algorithms, args.set)
    catalog = load_csv(args.catalog) if args.catalog else load_hipparcos()
    id_frames, trial_frames = [], []
    for variant in algorithm_variants:
        bar = None
        if progress(args):
            from tqdm.auto import tqdm

            bar = tqdm(total=len(trials), desc=variant.label, unit="img", leave=False)

        def compute(control, start, variant=variant):
            return _identify_one(variant, catalog, camera, trials, observations, has_truth, fov_range, control,
                                 start)

        # every plugin call in a supervised process (the engine's limits): one that overruns or dies is
        # that image's (or, preparing, every image's) timeout / crashed row, the other algorithms' intact
        items = call_per_item(compute, len(trials), limits,
                              on_item=lambda k, _item, bar=bar: bar.update(1) if bar is not None and k >= 0 else None)
        if bar is not None:
            bar.close()
        prepared = items.get(-1) or Prepared(variant.make(), variant.label, None, float("nan"), float("nan"))
        rows, ids = [], []
        for k, (t, obs) in enumerate(zip(trials, observations, strict=True)):
            item = items[k]
            if isinstance(item, Outcome):
                row = {"trial": t, "n_stars": len(obs),
                       "n_true_stars": int((obs.truth_hip >= 0).sum()) if has_truth else -1, "error": item.error,
                       "status": item.status, "n_identified": 0, "n_correct": 0, "n_wrong": 0,
                       "time_us": float("nan"), "n_redraws": 0, "attitude_err_arcsec": float("nan")}
                hip = np.full(len(obs), -1, dtype=np.int64)
            else:
                row, hip = item
                memory = memory_error(row["error"], limits.memory_limit_gb)
                if memory:
                    row = {**row, "status": CRASHED, "error": memory}
            rows.append(row)
            ids.append(pd.DataFrame({"trial": t, "star": np.arange(len(obs)), "x_px": obs.x_px, "y_px": obs.y_px,
                                     "mag": obs.mag, "hip": hip,
                                     "truth_hip": obs.truth_hip if has_truth else -1}))
        trial_frames.append(rows_to_frame(prepared, rows))
        id_frame = pd.concat(ids, ignore_index=True)
        id_frame.insert(0, "algorithm", prepared.algorithm.name)
        id_frame.insert(1, "label", variant.label)
        id_frames.append(id_frame)
    trials_df = pd.concat(trial_frames, ignore_index=True)
    trials_df = trials_df[IDENTIFY_TRIAL_COLUMNS + [c for c in trials_df.columns if c not in IDENTIFY_TRIAL_COLUMNS]]
    for column, value in camera.columns().items():      # the camera the centroids were identified with
        trials_df[column] = value
    frames = {"identifications.csv": pd.concat(id_frames, ignore_index=True)[ID_COLUMNS], "trials.csv": trials_df}
    if has_truth:
        frames["summary.csv"] = summarize(trials_df)
    stale = [] if has_truth else ["summary.csv", "summary.parquet"]
    write_frames(args.out, frames, remove=stale)
    for label, g in trials_df.groupby("label", sort=False):
        n_ok = int(g["status"].isin(["identified", "correct"]).sum())
        print(f"{label}: {len(g)} images, {n_ok} identified")
    if has_truth:
        print(format_summary(frames["summary.csv"]))
    print(f"wrote {', '.join(frames)} to {args.out}")
    return 0


def cmd_simulate(args) -> int:
    settings = world_settings(args)
    from ..experiment.spec import sim_settings

    config = SimConfig(**sim_settings(settings, {}))
    catalog = load_csv(args.catalog) if args.catalog else load_hipparcos()
    sim = Simulator(catalog, make_camera(camera_spec(args)), config, seed=args.seed)
    trials = sim.generate(args.trials)
    frame = trials.to_frame().drop(columns=["star"])
    out: Path = args.out
    check_out(out.parent if str(out.parent) else Path("."))
    write_frames(out.parent, {out.name: frame})
    print(f"wrote {len(trials)} images ({len(frame)} detections, with truth) to {out}")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("identify", help="identify your own centroids (OBS.csv: trial,x_px,y_px,mag[,truth_hip])",
                       formatter_class=formatter,
                       epilog="examples:\n  starid simulate --trials 100 --pos-noise-px 1 --out obs.csv\n"
                              "  starid identify ptp pvector obs.csv --out ids/",
                       description="Identify centroids you measured. OBS.csv has columns trial, x_px, y_px, mag "
                                   "and optionally truth_hip (then the images are scored like 'starid run').")
    p.add_argument("items", nargs="+", metavar="ALGO... OBS.csv", help="one or more algorithms, then the file")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="writes identifications.csv (algorithm, label, trial, star, x_px, y_px, mag, hip, truth_hip), "
                        "trials.csv and, with truth, summary.csv")
    p.add_argument("--catalog", help="CSV catalog instead of the embedded Hipparcos")
    p.add_argument("--set", action="append", metavar="LABEL.KEY=VALUE", help="override an algorithm parameter")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_camera(p)
    add_limits(p.add_argument_group("limits (each algorithm runs in a supervised process)"), engine=False)
    p.set_defaults(func=_identify_entry)

    p = sub.add_parser("simulate", help="write simulated images as an OBS.csv (with truth) for 'starid identify'",
                       formatter_class=formatter,
                       epilog="example:\n  starid simulate --trials 100 --pos-noise-px 1 --mag-noise 0.5 --out obs.csv")
    p.add_argument("--trials", type=trials_type, default=100, help="number of images")
    p.add_argument("--seed", type=seed_type, default=0, help="simulator seed")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.csv", help="the OBS.csv to write")
    add_world(p)
    add_camera(p)
    p.set_defaults(func=cmd_simulate)


def _identify_entry(args) -> int:
    from .images import identify_images, is_image_file

    if len(args.items) >= 2 and is_image_file(args.items[-1]):
        return identify_images(args)
    if args.out is None:
        raise ObservationError("identify OBS.csv needs --out DIR")
    if len(args.items) < 2:
        raise ObservationError("identify needs at least one algorithm and then OBS.csv")
    args.algorithms, args.obs = args.items[:-1], Path(args.items[-1])
    return cmd_identify(args)


__all__ = ["ID_COLUMNS", "add_parsers"]
