"""``report`` (a results folder as Markdown + one self-contained HTML, or two folders as a regression
report) and ``show`` (one simulated image, one panel per algorithm)."""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigError
from ..experiment.executors import Limits
from .options import add_camera, add_limits, add_world, camera_spec, make_camera, seed_type, world_settings

EXAMPLES = {
    "report": """examples:
  starid reproduce zhou2015 --trials 2000 --out results/zhou2015 && starid report results/zhou2015
  starid sweep ptp pvector --param sigma_px=0:2:0.5 --out results/noise && starid report results/noise
  starid report results/noise --format html
  starid report results/ptp-v1 results/ptp-v2          # regression: new vs old, same images
  starid report results/ptp-v1 results/ptp-v2 --out results/regression
  starid report results/ptp-v1 results/ptp-v2 --fail-on worse,misid,slower:1.2   # CI gate: exit 1""",
    "show": """examples:
  starid show ptp pvector planar_triangle triangle_voting --trial 3 --out trial3.png
  starid show ptp 'ptp[n_slaves=3]' --trial 12 --seed 7 --pos-noise-px 1 --mag-noise 0.5 --out t12.png
  starid show ptp triangle_voting --trial 0 --false-stars 3 --sky paper --out false3.svg
  starid show results/noise --trial 12 --label ptp --point 2 --out t12.png   # the image that folder scored""",
}


def _formats(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def cmd_report(args) -> int:
    from ..report.build import build_regression, build_report

    formats = _formats(args.format)
    if args.new is None:
        if args.out is not None:
            raise ConfigError("--out is for the regression report (starid report OLD NEW); a folder's report is "
                              "written into the folder")
        written = build_report(args.dir, formats, svg=not args.no_svg)
        print(f"wrote {', '.join(str(written[f]) for f in formats)} and {len(written['figures'])} figures in "
              f"{args.dir / 'figures'}")
        return 0
    from ..report.regression import gate, parse_fail_on

    fail_on = parse_fail_on(args.fail_on)
    if args.fail_on_regression and ("worse", None) not in fail_on:
        fail_on.append(("worse", None))
    written, diff = build_regression(args.dir, args.new, args.out, formats, svg=not args.no_svg,
                                     allow_different_worlds=args.allow_different_worlds)
    shown = diff.assign(old=100 * diff["old_rate"], new=100 * diff["new_rate"], diff_pp=100 * diff["diff"],
                        misid_pp=100 * diff["misid_diff"], failed_pp=100 * diff["failed_diff"])
    print(shown[["study", "where", "label", "trials", "old", "new", "diff_pp", "only_old_correct",
                 "only_new_correct", "p_value", "misid_pp", "failed_pp", "time_ratio"]]
          .to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    for k, a, b in written["differences"]:
        print(f"world differs: {k}: {a} (old) vs {b} (new)")
    for r in written["one_sided"].itertuples():
        print(f"only in {r.side}: {r.study}/{r.label} @ {r.where} ({r.trials} trials), not compared")
    print(f"wrote {', '.join(str(written[f]) for f in formats)}")
    reasons = gate(diff, fail_on)
    for line in reasons:
        print(f"FAIL {line}")
    return 1 if reasons else 0


def cmd_show(args) -> int:
    from .. import available
    from ..catalog import load_csv, load_hipparcos
    from ..report.show import show

    out = args.out
    limits = Limits.from_args(args)     # checked before any work
    if out.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise ConfigError(f"--out {out}: give a .png, .svg or .pdf file name")
    if out.exists() and out.is_dir():
        raise ConfigError(f"--out {out} is a folder; give a file name such as {out / 'trial.png'}")
    catalog = load_csv(args.catalog) if args.catalog else load_hipparcos()
    folder = Path(args.algorithms[0])
    if (folder / "manifest.json").is_file() or (folder.is_dir() and folder.name not in available()):
        # starid show DIR --trial K [--label L ...]
        return _show_folder(args, folder, catalog, limits)
    if args.label or args.study or args.point is not None:
        raise ConfigError("--label, --study and --point go with a results folder: starid show DIR --trial K")
    if (args.trial is None) == (args.boresight is None):
        raise ConfigError("give either --trial K or --boresight RA,DEC")
    if args.boresight is not None:   # the trial whose boresight is nearest (sky issue)
        from .. import sky
        from ..experiment.spec import sim_settings
        from ..simulate import SimConfig, Simulator

        ra, dec = sky.parse_radec(args.boresight)
        sim = Simulator(catalog, make_camera(camera_spec(args)), SimConfig(**sim_settings(world_settings(args), {})),
                        args.seed)
        args.trial, sep = sky.nearest_trial(sim, ra, dec, args.search_trials)
        print(f"trial {args.trial}: boresight {sep:.2f} deg from RA {ra:g}, DEC {dec:g} "
              f"(nearest of {args.search_trials} trials)")
    shown = show(args.algorithms, args.trial, args.seed, world_settings(args), make_camera(camera_spec(args)),
                 catalog, label_stars=not args.no_labels, limits=limits)
    out.parent.mkdir(parents=True, exist_ok=True)
    shown.figure.savefig(out, dpi=args.dpi, facecolor="white")
    print(shown.results[["label", "status", "n_identified", "n_correct", "n_wrong", "time_ms", "explain"]]
          .to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    for r in shown.results[shown.results["error"] != ""].itertuples():
        print(f"{r.label}: {r.status}: {r.error}")
    print(f"wrote {out}")
    return 0


def _show_folder(args, folder: Path, catalog, limits) -> int:
    """``starid show DIR --trial K [--label L ...]``: the image the folder scored, redrawn."""
    from ..report.show import show_folder

    if len(args.algorithms) > 1:
        raise ConfigError(f"starid show DIR takes one results folder; choose labels with --label "
                          f"(got {' '.join(args.algorithms)})")
    if args.trial is None or args.boresight is not None:
        raise ConfigError("starid show DIR needs --trial K (the folder's trial index)")
    shown, rows = show_folder(folder, args.trial, args.label, args.study, args.point, catalog, limits=limits,
                              label_stars=not args.no_labels)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    shown.figure.savefig(args.out, dpi=args.dpi, facecolor="white")
    print(f"{folder}: trial {args.trial} redrawn from its manifest (world, camera, seed): "
          f"{len(shown.stars)} detections")
    print(shown.results[["label", "folder_status", "status", "n_identified", "n_correct", "n_wrong", "time_ms"]]
          .rename(columns={"status": "redrawn_status"}).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    print(f"wrote {args.out}")
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("report", help="a results folder as report.md + report.html + figures; or OLD NEW: regression",
                       formatter_class=formatter, epilog=EXAMPLES["report"],
                       description="Turn a results folder (starid run/sweep --out, experiment run, reproduce, table6 "
                                   "--out) into DIR/report.md, one self-contained DIR/report.html (figures embedded, "
                                   "no external URL, no JavaScript) and DIR/figures/*.png + .svg: conditions, "
                                   "provenance, tables, rate curves with 95 % Wilson bands and the paper's points, "
                                   "time and memory trade-offs, star counts, McNemar tests. With two folders of the "
                                   "same experiment (OLD NEW): per label and point, the paired changes in id rate, "
                                   "misidentification and failures (Newcombe interval, McNemar's exact test), median "
                                   "and p95 time ratios (bootstrap interval), database size and build time "
                                   "(regression.md / .html); folders of different worlds are refused, naming the "
                                   "settings that differ.")
    p.add_argument("dir", type=Path, metavar="DIR", help="results folder (OLD when NEW is given)")
    p.add_argument("new", type=Path, nargs="?", metavar="NEW", help="a second results folder: regression report")
    p.add_argument("--format", default="md,html", metavar="md,html", help="which documents to write")
    p.add_argument("--out", type=Path, metavar="DIR", help="where the regression report goes (default: NEW)")
    p.add_argument("--no-svg", action="store_true", help="write PNG figures only")
    p.add_argument("--fail-on", action="append", metavar="worse,misid,slower:R",
                   help="regression report: exit 1 when a label/point got significantly worse in id rate ('worse'), "
                        "significantly more misidentifications ('misid'), or a median time ratio whose 95 %% "
                        "interval lies above R ('slower:1.2'); comma-separated or repeated (for CI)")
    p.add_argument("--fail-on-regression", action="store_true", help="the same as --fail-on worse")
    p.add_argument("--allow-different-worlds", action="store_true",
                   help="regression report: compare two folders whose simulated worlds differ (refused otherwise; "
                        "the differing settings are listed in the report)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("show", help="one simulated image, one panel per algorithm, its reasoning drawn over it",
                       formatter_class=formatter, epilog=EXAMPLES["show"],
                       description="Draw trial K of a seed (the image 'starid run' scores as trial K in the same "
                                   "world): stars sized by magnitude, each with its true and identified HIP; "
                                   "correct, wrong, missed and false stars marked by shape; and, for plugins with "
                                   "explain(), the algorithm's own reasoning (the triangles it formed, the one that "
                                   "matched) with its caption.")
    p.add_argument("algorithms", nargs="+", metavar="ALGO|DIR",
                   help="registered names or variants NAME[KEY=VALUE,...]; or one results folder (its world, "
                        "camera and seed from the manifest: the very image it scored)")
    p.add_argument("--trial", type=seed_type, default=None, metavar="K", help="trial index")
    p.add_argument("--label", action="append", metavar="L",
                   help="with DIR: draw only these labels (repeatable; default every label of the study)")
    p.add_argument("--study", metavar="S", help="with DIR: the study (default: the first)")
    p.add_argument("--point", type=seed_type, default=None, metavar="N",
                   help="with DIR: the grid point index of the study (default 0)")
    p.add_argument("--boresight", metavar="RA,DEC", default=None,
                   help="instead of --trial: the trial whose boresight is nearest RA,DEC (deg)")
    p.add_argument("--search-trials", type=seed_type, default=2000, metavar="N",
                   help="--boresight searches trials 0..N-1")
    p.add_argument("--seed", type=seed_type, default=0, help="simulator seed")
    p.add_argument("--out", type=Path, required=True, metavar="FILE.png", help="picture to write (.png, .svg, .pdf)")
    p.add_argument("--dpi", type=int, default=150, help="resolution of a PNG")
    p.add_argument("--no-labels", action="store_true", help="leave out the HIP numbers beside the stars")
    add_world(p)
    add_camera(p)
    add_limits(p.add_argument_group("limits (each algorithm runs in a supervised process)"), engine=False)
    p.set_defaults(func=cmd_show)


__all__ = ["add_parsers"]
