"""``run``, ``sweep``, ``experiment``, ``reproduce`` and ``table6``: everything on the experiment engine."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pandas as pd

from .. import experiments as builtin
from ..errors import ConfigError
from ..experiment import Experiment, Grid, Study, Variant, run_experiment
from ..experiment.spec import coerce
from ..experiment.store import claim_folder, record_derived
from ..io import atomic_write_text, write_frame
from ..provenance import versions
from ..registry import get_algorithm
from ..scoring import FAILED
from ..stats import IMAGE_COLUMNS, SUMMARY_COLUMNS, summarize
from .options import (
    add_camera,
    add_engine,
    add_out,
    add_world,
    camera_spec,
    check_out,
    progress,
    trials_type,
    world_settings,
)

#: The summary columns ``run`` prints (then the failure columns when anything failed).
SHOWN = ["label"] + SUMMARY_COLUMNS[1:SUMMARY_COLUMNS.index("compile_s") + 1]


def format_summary(summary: pd.DataFrame) -> str:
    """A fixed-width text table of the summary (errors, timeouts and crashes shown when any)."""
    cols = list(SHOWN)
    for extra in ("error_rate", "timeout_rate", "crash_rate"):
        if summary[extra].fillna(0).gt(0).any():
            cols.append(extra)
    cols += [c for c in IMAGE_COLUMNS if c in summary.columns]
    return summary[cols].to_string(index=False, float_format=lambda v: f"{v:.4g}")


def variants(names: list[str], overrides: list[str] | None) -> tuple[Variant, ...]:
    """Algorithm arguments (``ptp``, ``ptp[verify=false]``) with ``--set LABEL.KEY=VALUE`` applied."""
    out = [Variant.parse(n) for n in names]
    labels = [v.label for v in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise ConfigError(f"algorithm {dup[0]!r} given twice; to run one algorithm twice give the copies different "
                          f"parameters, e.g. ptp and 'ptp[verify=false]'")
    for item in overrides or []:
        head, sep, value = item.partition("=")
        label, dot, key = head.rpartition(".")
        if not (sep and dot and key):
            raise ConfigError(f"--set expects LABEL.KEY=VALUE, got {item!r}")
        matches = [i for i, v in enumerate(out) if v.label == label]
        if not matches:
            raise ConfigError(f"--set names {label!r}, which is not among the algorithms run ({', '.join(labels)})")
        i = matches[0]
        v = out[i]
        out[i] = Variant(v.name, tuple({**dict(v.params), key: coerce(get_algorithm(v.name), key, value)}.items()),
                         v.label)
    return tuple(out)


def check_all_failed(frame: pd.DataFrame) -> list[str]:
    """Labels every one of whose trials failed (error, timeout, crash)."""
    failed = frame["status"].isin(FAILED).groupby(frame["label"], sort=False).all()
    return [label for label, all_failed in failed.items() if all_failed]


def _finish(frame: pd.DataFrame) -> int:
    bad = check_all_failed(frame)
    for label in bad:
        first = frame.loc[(frame["label"] == label) & (frame["error"] != ""), "error"]
        why = first.iloc[0] if len(first) else "see the error column"
        print(f"starid: every trial of {label} failed: {why}")
    return 1 if bad else 0


def _engine(args, experiment: Experiment, out: Path | None):
    if out is not None:     # one folder, one definition: another one is refused unless --overwrite / --extend
        claim_folder(out, experiment, overwrite=getattr(args, "overwrite", False),
                     extend=getattr(args, "extend", False))
    t0 = time.perf_counter()
    frame = run_experiment(experiment, out, jobs=args.jobs, executor=args.executor, scheduler=args.scheduler,
                           catalog_path=getattr(args, "catalog", None) or "", time_limit_s=args.time_limit,
                           progress=progress(args), build_time_limit_s=args.build_time_limit,
                           memory_limit_gb=args.memory_limit_gb)
    return frame, time.perf_counter() - t0


def cmd_run(args) -> int:
    check_out(args.out)
    study = Study("run", variants(args.algorithms, args.set))
    exp = Experiment("run", (study,), trials=args.trials, seed=args.seed, camera=camera_spec(args),
                     sim=world_settings(args))
    frame, wall_s = _engine(args, exp, args.out)
    summary = summarize(frame)
    s = world_settings(args)
    noise = "rendered images (render -> extract)" if s["pipeline"] == "image" else \
        f"{s['sigma_px']:g} px / {s['sigma_mag']:g} mag noise"
    print(f"{args.trials} trials, seed {args.seed}, {noise}, "
          f"{s['false_stars']} false / {s['lost_stars']} lost stars, {_sky_text(frame)}; {wall_s:.1f} s wall with "
          f"{args.jobs} job(s) ({int(frame.drop_duplicates('trial')['n_redraws'].sum())} attitudes redrawn for "
          f"< {s['min_stars']} stars)")
    print(format_summary(summary))
    if args.out:
        record_derived(args.out, write_frame(frame, args.out / "trials.csv")
                       + write_frame(summary, args.out / "summary.csv"))
        print(f"wrote {args.out / 'trials.csv'} and {args.out / 'summary.csv'}")
    return _finish(frame)


def _sky_text(frame: pd.DataFrame) -> str:
    limit = frame["sim_sky_mag_limit"].iloc[0]
    return "real sky (every catalog star imaged)" if limit is None or pd.isna(limit) else f"sky V <= {limit:g}"


def parse_range(text: str) -> tuple[str, list]:
    """``KEY=START:STOP:STEP`` (STOP included) or ``KEY=v1,v2,...`` -> ``(key, values)``."""
    key, sep, spec = text.partition("=")
    if not sep or not key:
        raise ConfigError(f"--param expects KEY=START:STOP:STEP or KEY=V1,V2,..., got {text!r}")
    try:
        if ":" in spec:
            parts = [float(x) for x in spec.split(":")]
            if len(parts) != 3 or parts[2] <= 0 or parts[1] < parts[0]:
                raise ValueError
            start, stop, step = parts
            n = int(math.floor((stop - start) / step + 1e-9)) + 1
            if n > 1000:
                raise ConfigError(f"--param {text!r} gives {n} values; at most 1000")
            values = [round(start + i * step, 12) for i in range(n)]
        else:
            values = [float(x) for x in spec.split(",")]
    except ValueError:
        raise ConfigError(f"--param {text!r}: START:STOP:STEP needs numbers with STEP > 0 and STOP >= START") from None
    if key in ("false_stars", "lost_stars", "min_stars"):
        if any(v != int(v) for v in values):
            raise ConfigError(f"--param {key} takes whole numbers, got {values}")
        values = [int(v) for v in values]
    return key, values


def cmd_sweep(args) -> int:
    check_out(args.out)
    axes = dict(parse_range(p) for p in args.param)
    study = Study("sweep", variants(args.algorithms, args.set), Grid(axes, "zip" if args.zip else "product"))
    exp = Experiment("sweep", (study,), trials=args.trials, seed=args.seed, camera=camera_spec(args),
                     sim=world_settings(args))
    frame, wall_s = _engine(args, exp, args.out)
    by = tuple(f"grid_{k}" for k in axes) + ("label",)
    summary = summarize(frame, by=by)
    print(f"sweep over {', '.join(axes)}: {len(frame)} rows in {wall_s:.1f} s")
    print(summary[list(by[:-1]) + SHOWN].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    record_derived(args.out, write_frame(summary, args.out / "summary.csv"))
    print(f"wrote {args.out}")
    return _finish(frame)


def cmd_experiment_list(args) -> int:
    for mod in builtin.all_experiments():
        print(f"{mod.NAME:<11}  {mod.DESCRIPTION} (default {mod.DEFAULT_TRIALS:,} trials)")
    return 0


def cmd_experiment_run(args) -> int:
    exp = Experiment.from_toml(args.file)
    check_out(args.out)
    frame, wall_s = _engine(args, exp, args.out)
    by = ("study",) + tuple(c for c in frame.columns if c.startswith("grid_")) + ("label",)
    summary = summarize(frame, by=by)
    record_derived(args.out, write_frame(summary, args.out / "summary.csv"))
    print(summary[list(by[:-1]) + SHOWN].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    print(f"{exp.name}: {len(frame)} rows in {wall_s:.1f} s; wrote {args.out}")
    return _finish(frame)


def reproduce(args, name: str) -> tuple[str, pd.DataFrame, object]:
    """Run a built-in experiment, write its tables beside the results; the Markdown text."""
    mod = builtin.get(name)
    trials = args.trials if args.trials is not None else mod.DEFAULT_TRIALS
    extra = {"flight_trials": args.flight_trials} if getattr(args, "flight_trials", None) else {}
    exp = mod.experiment(trials, args.seed, **extra)
    check_out(args.out)
    if hasattr(mod, "run"):     # an experiment over several cameras runs its parts (experiments/cameras.py)
        frame, wall_s = mod.run(args, _engine)
    else:
        frame, wall_s = _engine(args, exp, args.out)
    tables = mod.tables(frame, exp)
    header = (f"{mod.TITLE} regenerated by starid "
              f"{versions()['starid_version']}: {trials} images per point, seed {args.seed}; {wall_s:.1f} s wall "
              f"with {args.jobs} job(s), databases included")
    if args.out:
        from ..report.tables import write_tables

        text = write_tables(tables, args.out, header)
        atomic_write_text(args.out / f"{name}.md", text)
        record_derived(args.out, [args.out / f"{name}.md"] + sorted((args.out / "tables").glob("*")))
    else:
        text = header + "\n\n" + "\n".join(t.text() for t in tables)
    return text, frame, tables


def cmd_reproduce(args) -> int:
    text, frame, _ = reproduce(args, args.name)
    print(text, end="")
    if args.out:
        print(f"wrote {args.out}: {args.name}.md, tables/*.csv and *.md, results.parquet, manifest.json")
    return _finish(frame)


def cmd_table6(args) -> int:
    text, frame, tables = reproduce(args, "table6")
    print(text, end="")
    if args.out:
        summary = pd.concat([t.frame for t in tables], ignore_index=True)
        written = write_frame(summary, args.out / "table6.csv")
        atomic_write_text(args.out / "table6.md", text)
        written += write_frame(frame, args.out / "trials.csv")
        record_derived(args.out, written + [args.out / "table6.md"])
        print(f"wrote {args.out / 'table6.md'}, {args.out / 'table6.csv'} and {args.out / 'trials.csv'}")
    return _finish(frame)


EXAMPLES = {
    "run": """examples:
  starid run ptp pvector --trials 2000 --pos-noise-px 1 --mag-noise 0.5
  starid run ptp 'ptp[verify=false]' --sky paper --out results/ptp-verify
  starid run ptp --set ptp.n_slaves=3 --false-stars 2""",
    "sweep": """examples:
  starid sweep ptp pvector --param sigma_px=0:2:0.5 --trials 1000 --out results/noise
  starid sweep ptp --param false_stars=0:5:1 --param sigma_mag=0,0.5 --out results/fs""",
    "reproduce": """examples:
  starid reproduce zhou2015 --trials 2000 --out results/zhou2015
  starid reproduce table6 --trials 1000 --quiet""",
    "table6": """examples:
  starid table6
  starid table6 --trials 2000 --jobs 1 --out results/table6""",
    "experiment run": """example FILE.toml:
  name = "noise"
  trials = 1000
  [sim]
  sigma_mag = 0.5
  sky = "paper"
  [[study]]
  name = "position noise"
  algorithms = ["ptp", "pvector", "ptp[n_slaves=3]"]
  grid = { sigma_px = [0.0, 1.0, 2.0] }""",
}


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("run", help="score algorithms on simulated images", formatter_class=formatter,
                       epilog=EXAMPLES["run"],
                       description="Score algorithms on the same simulated images. ALGO is a registered name "
                                   "(see 'starid list') or a variant NAME[KEY=VALUE,...] (see 'starid info NAME').")
    p.add_argument("algorithms", nargs="+", metavar="ALGO")
    p.add_argument("--set", action="append", metavar="LABEL.KEY=VALUE",
                   help="override a parameter of one algorithm label (repeatable)")
    add_engine(p, trials=1000)
    add_out(p, "trials.csv, summary.csv (+ .parquet), results.parquet, manifest.json")
    add_world(p)
    add_camera(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("sweep", help="an ad-hoc grid of simulator settings", formatter_class=formatter,
                       epilog=EXAMPLES["sweep"],
                       description="Run algorithms at every point of a grid of simulator settings (SimConfig "
                                   "fields: sigma_px, sigma_mag, false_stars, lost_stars, mag_limit, sky_mag_limit, "
                                   "min_stars, merge_radius_px); the other world options set the rest.")
    p.add_argument("algorithms", nargs="+", metavar="ALGO")
    p.add_argument("--param", action="append", required=True, metavar="KEY=START:STOP:STEP",
                   help="a grid axis (STOP included) or KEY=V1,V2,... (repeatable)")
    p.add_argument("--zip", action="store_true", help="pair the axes' values instead of taking their product")
    p.add_argument("--set", action="append", metavar="LABEL.KEY=VALUE", help="override an algorithm parameter")
    add_engine(p, trials=1000)
    add_out(p, "manifest, Parquet results and summary.csv", required=True)
    add_world(p)
    add_camera(p)
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("experiment", help="built-in experiments, or your own from a TOML file",
                       formatter_class=formatter)
    esub = p.add_subparsers(dest="experiment_command", required=True)
    q = esub.add_parser("list", help="name the built-in experiments", formatter_class=formatter)
    q.set_defaults(func=cmd_experiment_list)
    q = esub.add_parser("run", help="run an experiment written as TOML", formatter_class=formatter,
                        epilog=EXAMPLES["experiment run"])
    q.add_argument("file", type=Path, metavar="FILE.toml")
    add_engine(q, trials=None)
    add_out(q, "manifest, Parquet results and summary.csv", required=True)
    q.set_defaults(func=cmd_experiment_run)

    p = sub.add_parser("reproduce", help="regenerate a published comparison, the paper's values beside ours",
                       formatter_class=formatter, epilog=EXAMPLES["reproduce"])
    p.add_argument("name", metavar="NAME", help="a built-in experiment (see 'starid experiment list')")
    p.add_argument("--trials", type=trials_type, default=None, help="images per grid point (default: the experiment's)")
    p.add_argument("--flight-trials", type=trials_type, default=None,
                   help="realism only: images at each flight point (default: max(5000, --trials))")
    add_engine(p, trials=None)
    add_out(p, "NAME.md, tables/*.csv and *.md, results.parquet, manifest.json")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("table6", help="regenerate Table 6 of Zhou & Ye (2015) in the paper's and the real sky",
                       formatter_class=formatter, epilog=EXAMPLES["table6"])
    add_engine(p, trials=10_000)
    add_out(p, "table6.md, table6.csv, trials.csv")
    p.set_defaults(func=cmd_table6)


__all__ = ["add_parsers", "format_summary"]
