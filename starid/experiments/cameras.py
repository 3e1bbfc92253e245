"""Cameras (issue #23): every registered algorithm against the camera it does not know exactly.

Every registered algorithm runs with its defaults on the same trials (common random numbers:
trial ``k`` has the same attitude and unit noise at every point), at a base of 0.5 px / 0.2 Mv
noise in the real sky (V <= 6 detected), unless said otherwise:

* ``distortion_table4``, ``distortion_cubesat_wide``: uncalibrated radial distortion (the lens
  has ``k1``, the algorithm assumes a pinhole: ``assumed_distortion = "none"``), swept from 0 to
  the ``k1`` that moves the sensor corner outwards by 10 px (:func:`k1_for_corner_shift`), on the
  Table 4 camera (10 deg) and on the wide CubeSat preset (50 x 26 deg); the ``..._calibrated``
  studies are the same lenses with the calibration known (``assumed_distortion = "true"``);
* ``focal``: the assumed focal length off by 0-5 % (Table 4 camera);
* ``presets``: every shipped preset at 1 px / 0.5 Mv, calibrated;
* ``roundtrip``: a 10 deg camera (Table 4) with ``k1 = 0.5`` identified with its calibration and
  with the pinhole assumed, beside the undistorted Table 4 trials (the distortion sweep's 0 px
  point: the same attitudes and noise).

An experiment has one camera, so this one is several (:func:`parts`), each run into
``OUT/parts/<name>/`` (resumable) and joined into one results folder (``starid report OUT``):
the corner shift becomes the ``grid_corner_shift_px`` column of the distortion studies.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..experiment import Experiment, Grid, Study
from ..plots import AXIS_NAMES
from ..report.tables import Table, markdown, pct, rate_ci
from ..stats import summarize
from . import registered_beyond, sweep_table

NAME = "cameras"
TITLE = "Cameras: uncalibrated distortion, focal-length error, the presets"
DESCRIPTION = "Every algorithm against lens distortion, focal error and the camera presets (issue #23)"
DEFAULT_TRIALS = 100
#: The base world of the sweeps and the round trip: moderate noise in the real sky.
SIM = {"sigma_px": 0.5, "sigma_mag": 0.2, "mag_limit": 6.0, "min_stars": 6}
#: The presets' noise (calibrated): 1 px / 0.5 Mv.
PRESET_NOISE = {"sigma_px": 1.0, "sigma_mag": 0.5}
#: Corner shifts (px) of the distortion sweeps; the calibrated lens at the largest.
SHIFTS_PX = {"table4": (0.0, 5.0, 10.0), "cubesat_wide": (0.0, 5.0, 10.0)}
FOCAL_ERRORS_PCT = (0.0, 1.0, 2.0, 3.0, 5.0)
ROUNDTRIP_K1 = 0.5
#: The presets of the ``presets`` study (every shipped one).
PRESETS = ("table4", "luo2015", "tetra3_test", "altair_hb", "rigel_l", "hil_16mm", "cubesat_wide",
           "cubesat_wide_distorted")


# the printed names of this experiment's axes in the report's figures (starid.plots.axis_name)
AXIS_NAMES.setdefault("corner_shift_px", "lens corner shift (px)")
AXIS_NAMES.setdefault("focal_error_pct", "focal-length error (%)")


def variants() -> tuple[str, ...]:
    """Every working registered algorithm, with its defaults."""
    return registered_beyond(())


def k1_for_corner_shift(camera, shift_px: float) -> float:
    """The radial ``k1`` that moves the sensor's farthest corner by ``shift_px`` outwards: the
    corner at normalized radius ``r`` lands at ``r (1 + k1 r^2)``, so ``k1 = shift / (f r^3)``."""
    dx = max(camera.cx_px, camera.width_px - camera.cx_px)
    dy = max(camera.cy_px, camera.height_px - camera.cy_px)
    r = math.hypot(dx, dy) / camera.f_px
    return shift_px / (camera.f_px * r ** 3)


def _lens(preset: str, k1: float) -> dict:
    return {"preset": preset} if k1 == 0.0 else {"preset": preset, "distortion": [k1, 0.0, 0.0, 0.0, 0.0]}


def parts(trials: int = DEFAULT_TRIALS, seed: int = 0, algos: tuple | None = None) -> list[tuple[Experiment, dict]]:
    """The experiments, one per true camera, each with how its studies join the whole:
    ``{part study: (final study, extra columns)}``; ``algos`` (default: :func:`variants`)."""
    from ..cameras import load_camera

    algos = variants() if algos is None else tuple(algos)
    out = []

    def add(name, camera, studies, join, sim=None):
        exp = Experiment(f"{NAME}-{name}", tuple(studies), trials=trials, seed=seed, camera=camera,
                         sim=dict(sim or SIM), description=DESCRIPTION)
        out.append((exp, join))

    def roundtrip():
        studies = [Study("roundtrip", algos, Grid({"assumed_distortion": ["true", "none"]}))]
        add("roundtrip", _lens("table4", ROUNDTRIP_K1), studies, {"roundtrip": ("roundtrip", {})})

    for preset, shifts in SHIFTS_PX.items():
        cam = load_camera(preset)
        for shift in shifts:
            k1 = k1_for_corner_shift(cam, shift)
            # at 0 px the lens is a pinhole: the base world (its rows are also the calibrated study's
            # 0 px point and, on Table 4, the focal sweep's 0 % point: the same chunks, computed once)
            grid = Grid() if shift == 0.0 else Grid({"assumed_distortion": ["none"]})
            studies = [Study("uncalibrated", algos, grid)]
            join = {"uncalibrated": (f"distortion_{preset}", {"grid_corner_shift_px": shift})}
            if shift == max(shifts):
                studies.append(Study("calibrated", algos, Grid({"assumed_distortion": ["true"]})))
                join["calibrated"] = (f"distortion_{preset}_calibrated", {"grid_corner_shift_px": shift})
            if shift == 0.0 and preset == "table4":
                studies.append(Study("focal", algos, Grid({"focal_error_pct": list(FOCAL_ERRORS_PCT)})))
                join["focal"] = ("focal", {})
            if shift == 0.0:
                studies.append(Study("preset", algos, Grid({k: [v] for k, v in PRESET_NOISE.items()})))
                join["preset"] = ("presets", {})
            add(f"{preset}-{shift:g}px", _lens(preset, k1), studies, join)
        if preset == "table4":
            roundtrip()                 # right after its baseline (the cheap parts first)
    for preset in PRESETS:
        if preset in SHIFTS_PX:
            continue
        studies = [Study("preset", algos, Grid({k: [v] for k, v in PRESET_NOISE.items()}))]
        add(f"preset-{preset}", {"preset": preset}, studies, {"preset": ("presets", {})})
    return out


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0) -> Experiment:
    """The whole as one definition (the manifest's; :func:`run` runs its :func:`parts`)."""
    studies = []
    for exp, join in parts(trials, seed):
        for s in exp.studies:
            final = join[s.name][0]
            if final not in {x.name for x in studies}:
                studies.append(Study(final, s.variants, s.grid))
    return Experiment(NAME, tuple(studies), trials=trials, seed=seed, camera={}, sim=dict(SIM),
                      description=DESCRIPTION)


def join_frames(pieces: list[tuple[Experiment, dict, pd.DataFrame]]) -> pd.DataFrame:
    """The parts' rows as one frame: final study names, the extra columns, one ``point`` per
    distinct (part, part point) within each final study."""
    frames = []
    for exp, join, frame in pieces:
        for part_study, g in frame.groupby("study", sort=False):
            final, extra = join[part_study]
            g = g.copy()
            g["study"] = final
            g["part"] = exp.name
            for k, v in extra.items():
                g[k] = v
            frames.append(g)
    out = pd.concat(frames, ignore_index=True)
    for preset in SHIFTS_PX:            # the pinhole point of each calibrated curve
        zero = out[(out["study"] == f"distortion_{preset}") & (out["grid_corner_shift_px"] == 0.0)]
        out = pd.concat([out, zero.assign(study=f"distortion_{preset}_calibrated")], ignore_index=True)
    key = out["part"] + "/" + out["point"].astype(str)
    out["point"] = key.groupby(out["study"], sort=False).transform(lambda s: pd.factorize(s)[0]).astype(int)
    rt = out["study"] == "roundtrip"
    out.loc[rt, "lens"] = np.where(out.loc[rt, "grid_assumed_distortion"] == "true",
                                   f"k1 = {ROUNDTRIP_K1:g}, calibrated", f"k1 = {ROUNDTRIP_K1:g}, pinhole assumed")
    # the assumed distortion is in each study's name: no string-valued swept axis for the figures
    out["grid_assumed_distortion"] = None
    return out


def run(args, engine) -> tuple[pd.DataFrame, float]:
    """``starid reproduce cameras``: every part through ``engine(args, experiment, out)`` (the
    CLI's runner), then the joined frame written as one results folder when ``args.out`` is given."""
    t0 = time.perf_counter()
    trials = args.trials if args.trials is not None else DEFAULT_TRIALS
    pieces = []
    out: Path | None = args.out
    for exp, join in parts(trials, args.seed):
        sub = out / "parts" / exp.name.removeprefix(f"{NAME}-") if out is not None else None
        frame, _ = engine(args, exp, sub)
        pieces.append((exp, join, frame))
    frame = join_frames(pieces)
    if out is not None:
        from ..experiment import read_manifest
        from ..io import atomic_write_bytes, atomic_write_text

        manifest = read_manifest(out / "parts" / pieces[0][0].name.removeprefix(f"{NAME}-"))
        manifest["experiment"] = experiment(trials, args.seed).to_dict()
        manifest["parts"] = [e.name for e, _, _ in pieces]
        manifest["camera"] = {"name": "several (see the camera_* columns)"}
        import io

        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        atomic_write_bytes(out / "results.parquet", buf.getvalue())
        atomic_write_text(out / "manifest.json", json.dumps(manifest, indent=2, default=str) + "\n")
    return frame, time.perf_counter() - t0


def paper_points() -> pd.DataFrame:
    return pd.DataFrame(columns=["study", "axis", "value", "algorithm", "paper_id_rate"])


def _rates(part: pd.DataFrame, by: str) -> pd.DataFrame:
    rows = []
    for (label, key), g in part.groupby(["label", by], sort=False):
        s = summarize(g).iloc[0]
        rows.append({"label": label, by: key, "trials": int(s["trials"]), "id_rate": s["id_rate"],
                     "id_rate_lo": s["id_rate_lo"], "id_rate_hi": s["id_rate_hi"], "misid_rate": s["misid_rate"]})
    return pd.DataFrame(rows)


def roundtrip_table(frame: pd.DataFrame) -> Table:
    """The k1 = 0.5 lens calibrated and uncalibrated beside the undistorted trials, per algorithm."""
    base = frame[(frame["study"] == "distortion_table4") & (frame["grid_corner_shift_px"] == 0.0)].copy()
    base["lens"] = "undistorted"
    part = pd.concat([base, frame[frame["study"] == "roundtrip"]], ignore_index=True)
    s = _rates(part, "lens")
    wide = s.pivot(index="label", columns="lens", values="id_rate").reindex(index=list(dict.fromkeys(s["label"])))
    cal, pin = f"k1 = {ROUNDTRIP_K1:g}, calibrated", f"k1 = {ROUNDTRIP_K1:g}, pinhole assumed"
    shown = pd.DataFrame({"algorithm": wide.index,
                          "undistorted": wide["undistorted"].map(pct),
                          "calibrated": wide[cal].map(pct),
                          "calibrated - undistorted": ((wide[cal] - wide["undistorted"]) * 100).map(
                              lambda v: f"{v:+.1f} pt"),
                          "within 1 pt": (abs(wide[cal] - wide["undistorted"]) <= 0.01).map(
                              {True: "yes", False: "NO"}),
                          "pinhole assumed": wide[pin].map(pct),
                          "loss uncalibrated": ((wide["undistorted"] - wide[pin]) * 100).map(
                              lambda v: f"{v:.1f} pt")})
    from ..cameras import load_camera

    shift = k1_for_corner_shift(load_camera("table4"), 1.0)
    note = (f"The same attitudes and noise in every column; k1 = {ROUNDTRIP_K1:g} moves the 10 deg camera's corner "
            f"by {ROUNDTRIP_K1 / shift:.1f} px. 'calibrated': the harness undistorts the centroids with the true "
            f"calibration before the plugin sees them; 'pinhole assumed': they are handed over as measured.")
    return Table("cameras_roundtrip", f"Distortion round trip: k1 = {ROUNDTRIP_K1:g} on the 10 deg camera",
                 s, markdown(shown), (note,))


def preset_table(frame: pd.DataFrame) -> Table:
    part = frame[frame["study"] == "presets"]
    s = _rates(part, "camera_name")
    s["cell"] = [rate_ci(r, lo, hi) for r, lo, hi in zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"],
                                                          strict=True)]
    order = [p for p in PRESETS if p in set(s["camera_name"])]
    wide = s.pivot(index="label", columns="camera_name", values="cell").reindex(
        index=list(dict.fromkeys(s["label"])), columns=order)
    fovs = part.drop_duplicates("camera_name").set_index("camera_name")
    notes = ("Fields across the width: " + ", ".join(
        f"{n} {math.degrees(2 * math.atan(fovs.loc[n, 'camera_width_px'] / 2 / (fovs.loc[n, 'camera_focal_mm'] * 1000 / fovs.loc[n, 'camera_pixel_um']))):.1f} deg"  # noqa: E501
        for n in order) + "; the noise is in pixels, so a wide field's 1 px is a larger angle.",)
    return Table("cameras_presets", "Every preset at 1 px / 0.5 Mv, calibrated", s, markdown(wide.reset_index()),
                 notes)


SWEEPS = {
    "distortion_table4": ("corner_shift_px", "corner shift (px)",
                          "Uncalibrated distortion, Table 4 camera (10 deg): id rate vs the corner's shift"),
    "distortion_table4_calibrated": ("corner_shift_px", "corner shift (px)",
                                     "Calibrated distortion, Table 4 camera (10 deg)"),
    "distortion_cubesat_wide": ("corner_shift_px", "corner shift (px)",
                                "Uncalibrated distortion, cubesat_wide (50 x 26 deg): id rate vs the corner's shift"),
    "distortion_cubesat_wide_calibrated": ("corner_shift_px", "corner shift (px)",
                                           "Calibrated distortion, cubesat_wide (50 x 26 deg)"),
    "focal": ("focal_error_pct", "focal error (%)", "Focal-length error: id rate vs the assumed focal length's error"),
}


def tables(frame: pd.DataFrame, experiment: Experiment) -> list[Table]:
    out = []
    for name, (axis, unit, title) in SWEEPS.items():
        if name in set(frame["study"]):
            out.append(sweep_table(frame, name, axis, {}, unit, title, f"cameras_{name}"))
    if "roundtrip" in set(frame["study"]):
        out.append(roundtrip_table(frame))
    if "presets" in set(frame["study"]):
        out.append(preset_table(frame))
    return out
