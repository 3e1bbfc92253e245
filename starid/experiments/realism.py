"""The sky and the spacecraft (issue #24): every registered algorithm against the world effects.

Every registered algorithm runs with its defaults on the same trials (common random numbers:
trial ``k`` has the same attitude and unit noise at every point, and every algorithm sees the
same images), at a base of 0.5 px / 0.2 Mv noise in the real sky, on two cameras
(:data:`CAMERAS`):

* ``table4``: Zhou & Ye's Table 4 camera (1024 x 1024 px, 10 x 10 deg), detection limit V 6;
* ``cubesat_wide``: the wide CubeSat preset (Erlank 2013: 1024 x 512 px, 50 x 26 deg) at its
  published limiting magnitude V 3.8 (a fixed ``mag_limit`` axis of its studies); the algorithms
  whose guide-star limit does not follow the world's get it set to the sensor's
  (:func:`camera_variants`), as a designer would configure them for this sensor.

Neither preset gives an exposure time, so the smear's exposure is
:data:`starid.sky.DEFAULT_EXPOSURE_S` = 0.1 s on both. Each effect is swept alone from zero to a
harsh value (:data:`SWEEPS`; study ``EFFECT_CAMERA``, e.g. ``rate_table4``):

* ``rate``: angular rate 0-2 deg/s about an axis drawn per trial (:mod:`starid.kernels.smear`);
  streaks of up to 20.5 px (Table 4) or 3.8 px (CubeSat) at 0.1 s;
* ``planets``: 0-3 planets in view (``planets_in_view``): that many of the five naked-eye planets,
  chosen at random per trial, at their apparent magnitudes at :data:`EPOCH`, placed uniformly in
  the field (:func:`starid.sky.forced_planets`), boresights within 5 deg of the ecliptic; the same
  attitudes and draws at every count, so the k-planet field is the (k-1)-planet field plus one;
* ``aberration``: observer speed 0-40 km/s (the catalog the algorithms use is not corrected);
* ``focal``: the algorithms' assumed focal length off by 0-1 % (the cameras issue's calibration
  error, docs/cameras.md);
* ``distortion``: the same optics with a barrel lens of k1 = -0.1 (``cubesat_wide_distorted``;
  on Table 4 the same k1 in :data:`DISTORTED`), the algorithms given the true lens
  (``assumed_distortion = "true"``, calibrated) and a pinhole (``"none"``, uncalibrated);

and one ``flight`` point per camera with every effect at a typical value (:data:`FLIGHT`), over
the whole sky. **Rule:** the flight point runs ``max(FLIGHT_TRIALS, trials)`` images (5,000 by
default) even when the sweeps run fewer, so that its sky maps (``starid report``, >= 2,000
trials, :data:`SKYMAP_STUDY`) have about 30 images per cell; ``experiment(...,
flight_trials=N)`` (``starid reproduce realism --flight-trials N``) sets it.

Every zero point of a sweep is the camera's base point (the same settings), so it is computed
once (the runner shares chunks with equal keys), and the simulated trials of a point are shared
by the algorithms a worker runs there.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..experiment import Experiment, Grid, Study
from ..report.tables import Table, markdown, pct
from ..stats import summarize
from . import registered_beyond, sweep_table

NAME = "realism"
TITLE = "The sky and the spacecraft: smear, planets, aberration, calibration"
DESCRIPTION = ("Every algorithm on two cameras against motion smear, planets in view, stellar aberration, "
               "focal error and uncalibrated distortion (issue #24)")
DEFAULT_TRIALS = 200
#: Images at each flight point: at least this many, whatever ``trials`` (see the module docstring).
FLIGHT_TRIALS = 5000
#: The base world: moderate noise in the real sky.
SIM = {"sigma_px": 0.5, "sigma_mag": 0.2, "mag_limit": 6.0, "min_stars": 6}
#: The cameras (preset specs) and the fixed settings of their studies (the CubeSat's published V 3.8 limit).
CAMERAS = {"table4": ({"preset": "table4"}, {}),
           "cubesat_wide": ({"preset": "cubesat_wide"}, {"mag_limit": 3.8})}
#: The same optics with a barrel lens (k1 = -0.1: ~16 px at the CubeSat's corner, ~1 px at Table 4's).
DISTORTED = {"table4": {"preset": "table4", "distortion": [-0.1, 0.0, 0.0, 0.0, 0.0]},
             "cubesat_wide": {"preset": "cubesat_wide_distorted"}}
#: The epoch of the planets (magnitudes) and of the flight point (positions, proper motion).
EPOCH = "2030-01-01T00:00:00"
#: One flight-like point: 0.5 deg/s (a slow slew; 5 px streaks on Table 4 at 0.1 s), the real planets
#: at the epoch, Earth's orbital speed plus a low orbit's (30 + 7.7 km/s), a 0.1 % focal-length error.
FLIGHT = {"rate_deg_s": 0.5, "planets": True, "epoch": EPOCH, "velocity_kms": 37.7, "focal_error_pct": 0.1}
#: The studies the report's sky maps are drawn for, one map each (starid.report.skymap, >= 2,000 trials):
#: the flight point on each camera.
SKYMAP_STUDY = ("flight_table4", "flight_cubesat_wide")

#: effect -> (axis, values, fixed settings, unit, title)
SWEEPS = {
    "rate": ("rate_deg_s", [0.0, 0.5, 1.0, 2.0], {}, "rate (deg/s)",
             "Motion smear: id rate vs angular rate (0.1 s exposure)"),
    "planets": ("planets_in_view", [0, 1, 2, 3], {"near_ecliptic": True, "epoch": EPOCH}, "planets in view",
                f"Planets: id rate vs naked-eye planets in the field (near the ecliptic, magnitudes at {EPOCH})"),
    "aberration": ("velocity_kms", [0.0, 20.0, 40.0], {}, "speed (km/s)",
                   "Stellar aberration: id rate vs observer speed (catalog not corrected)"),
    "focal": ("focal_error_pct", [0.0, 0.5, 1.0], {}, "focal error (%)",
              "Calibration: id rate vs focal-length error"),
    "distortion": ("assumed_distortion", ["true", "none"], {}, "assumed lens",
                   "Uncalibrated distortion: k1 = -0.1 lens, algorithms given the true lens or a pinhole"),
}


def variants() -> tuple[str, ...]:
    """Every working registered algorithm, with its defaults."""
    return registered_beyond(())


def camera_variants(fixed_cam: dict) -> tuple:
    """The algorithms on a camera whose detection limit is not the base's: an algorithm whose
    ``mag_limit`` does not follow the world's keeps its own margin above it (its default minus
    the base V 6; a derived default, None, gets the limit itself), so its guide catalog is the
    sensor's; labelled by the plain name."""
    import dataclasses

    from ..experiment import Variant
    from ..registry import get_algorithm

    names = variants()
    if "mag_limit" not in fixed_cam:
        return names
    out = []
    for name in names:
        cls = get_algorithm(name)
        fields = {f.name: f.default for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else {}
        if "mag_limit" not in fields or "mag_limit" in getattr(cls, "follows", {}):
            out.append(Variant(name))
            continue
        default = fields["mag_limit"]
        margin = default - SIM["mag_limit"] if isinstance(default, (int, float)) else 0.0
        out.append(Variant(name, (("mag_limit", round(fixed_cam["mag_limit"] + margin, 3)),), label=name))
    return tuple(out)


def study_name(effect: str, camera: str) -> str:
    return f"{effect}_{camera}"


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0, flight_trials: int | None = None) -> Experiment:
    """The experiment: ``trials`` images per sweep point, ``flight_trials`` (default
    ``max(FLIGHT_TRIALS, trials)``) at each flight point."""
    flight_n = max(FLIGHT_TRIALS, trials) if flight_trials is None else int(flight_trials)
    studies = []
    for cam, (spec, fixed_cam) in CAMERAS.items():
        algos = camera_variants(fixed_cam)
        for effect, (axis, values, fixed, _, _) in SWEEPS.items():
            grid = Grid({axis: values, **{k: [v] for k, v in {**fixed_cam, **fixed}.items()}})
            camera = DISTORTED[cam] if effect == "distortion" else spec
            studies.append(Study(study_name(effect, cam), algos, grid, trials, dict(camera)))
        studies.append(Study(study_name("flight", cam), algos,
                             Grid({k: [v] for k, v in {**fixed_cam, **FLIGHT}.items()}), flight_n, dict(spec)))
    return Experiment(NAME, tuple(studies), trials=trials, seed=seed, camera={}, sim=dict(SIM),
                      description=DESCRIPTION)


def paper_points() -> pd.DataFrame:
    return pd.DataFrame(columns=["study", "axis", "value", "algorithm", "paper_id_rate"])


def sweep(frame: pd.DataFrame, effect: str, camera: str) -> Table:
    axis, _, _, unit, title = SWEEPS[effect]
    name = study_name(effect, camera)
    if axis == "assumed_distortion":    # text values: sweep_table formats numbers
        part = frame[frame["study"] == name]
        s = summarize(part, by=("grid_assumed_distortion", "label"))
        s["cell"] = [f"{pct(r, 1)} [{pct(lo, 1)}, {pct(hi, 1)}]"
                     for r, lo, hi in zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], strict=True)]
        wide = s.pivot(index="label", columns="grid_assumed_distortion", values="cell").reindex(
            index=list(dict.fromkeys(s["label"])), columns=["true", "none"])
        wide.columns = ["true lens (calibrated)", "pinhole (uncalibrated)"]
        return Table(f"realism_{name}", f"{title} [{camera}]", s, markdown(wide.reset_index()))
    return sweep_table(frame, name, axis, {}, unit, f"{title} [{camera}]", f"realism_{name}")


def attitude_table(frame: pd.DataFrame, camera: str) -> Table:
    """Median attitude error (arcsec) of the correct identifications against observer speed:
    aberration moves the whole field almost rigidly, so the identification survives and the
    attitude (against the uncorrected catalog) carries the shift."""
    part = frame[(frame["study"] == study_name("aberration", camera)) & (frame["status"] == "correct")]
    g = part.groupby(["label", "grid_velocity_kms"], sort=False)["attitude_err_arcsec"].median().reset_index()
    wide = g.pivot(index="label", columns="grid_velocity_kms", values="attitude_err_arcsec")
    wide = wide.reindex(index=list(dict.fromkeys(g["label"])))
    wide.columns = [f"{c:g} km/s" for c in wide.columns]
    shown = wide.map(lambda v: f"{v:.1f}").reset_index()
    return Table(f"realism_aberration_attitude_{camera}", f"Aberration: median attitude error of correct "
                 f"identifications (arcsec) [{camera}]", g, markdown(shown),
                 ("Aberration by v/c displaces a star at angle theta from the apex by (v/c) sin(theta): 20.6 "
                  "arcsec at 30 km/s, nearly the same over the field, so the pattern the algorithms match is "
                  "intact but the attitude against the uncorrected catalog is off by up to v/c.",))


def planets_in_view(frame: pd.DataFrame) -> pd.Series:
    """Planets detected in each trial row: detections without a HIP (the planet studies add no false stars)."""
    return frame["n_stars"] - frame["n_true_stars"]


def planet_misid_table(frame: pd.DataFrame) -> Table:
    """Misidentification rate and the share of fields whose planets were all detected, per camera
    and planets in view."""
    rows = []
    for cam in CAMERAS:
        part = frame[frame["study"] == study_name("planets", cam)]
        for (label, k), g in part.groupby(["label", "grid_planets_in_view"], sort=False):
            rows.append({"camera": cam, "label": label, "planets_in_view": int(k),
                         "misid_rate": float((g["status"] == "wrong").mean()),
                         "detected_mean": float(planets_in_view(g).mean())})
    s = pd.DataFrame(rows)
    s["cell"] = [f"{pct(m, 1)} ({d:.2f} seen)" for m, d in zip(s["misid_rate"], s["detected_mean"], strict=True)]
    s["column"] = [f"{c}, {k} in view" for c, k in zip(s["camera"], s["planets_in_view"], strict=True)]
    wide = s.pivot(index="label", columns="column", values="cell").reindex(
        index=list(dict.fromkeys(s["label"])), columns=list(dict.fromkeys(s["column"])))
    return Table("realism_planets_misid", "Planets: misidentification rate (mean planets detected)", s,
                 markdown(wide.reset_index()),
                 ("A planet carries no HIP: a result naming one, or misplaced by one, is scored wrong.",))


def flight_table(frame: pd.DataFrame) -> Table:
    rows = []
    for cam in CAMERAS:
        s = summarize(frame[frame["study"] == study_name("flight", cam)])
        s.insert(0, "camera", cam)
        rows.append(s)
    s = pd.concat(rows, ignore_index=True)
    shown = pd.DataFrame({"camera": s["camera"], "algorithm": s["label"], "images": s["trials"].astype(int),
                          "id rate": [f"{pct(r, 1)} [{pct(lo, 1)}, {pct(hi, 1)}]" for r, lo, hi in
                                      zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], strict=True)],
                          "misid": s["misid_rate"].map(lambda v: pct(v, 1)),
                          "no result": s["no_result_rate"].map(lambda v: pct(v, 1)),
                          "median time": s["time_median_us"].map(lambda v: f"{v / 1e3:.2f} ms")})
    setting = ", ".join(f"{k} = {v}" for k, v in FLIGHT.items())
    return Table("realism_flight", "Flight point: every effect at a typical value", s, markdown(shown),
                 (f"{setting}; boresights over the whole sky; the CubeSat at V <= 3.8.",))


def robustness_table(frame: pd.DataFrame) -> Table:
    """Id-rate change (percentage points) from each camera's base point to each effect's harshest
    value (and the flight point): the summary the docs' conclusions are drawn from."""
    rows = []
    for cam in CAMERAS:
        base = frame[(frame["study"] == study_name("rate", cam)) & (frame["grid_rate_deg_s"] == 0.0)]
        base_rate = base.groupby("label", sort=False)["status"].apply(lambda s: (s == "correct").mean())
        for effect, (axis, values, _, _, _) in SWEEPS.items():
            part = frame[(frame["study"] == study_name(effect, cam))]
            ref = part[part[f"grid_{axis}"] == values[0]].groupby("label", sort=False)["status"].apply(
                lambda s: (s == "correct").mean())
            harsh = part[part[f"grid_{axis}"] == values[-1]].groupby("label", sort=False)["status"].apply(
                lambda s: (s == "correct").mean())
            for label in harsh.index:
                rows.append({"camera": cam, "label": label, "effect": f"{effect} {values[-1]}",
                             "base_id_rate": base_rate.get(label, np.nan), "ref_id_rate": ref.get(label, np.nan),
                             "id_rate": harsh[label], "change_pts": 100 * (harsh[label] - ref.get(label, np.nan))})
        fl = frame[frame["study"] == study_name("flight", cam)].groupby("label", sort=False)["status"].apply(
            lambda s: (s == "correct").mean())
        for label in fl.index:
            rows.append({"camera": cam, "label": label, "effect": "flight", "base_id_rate": base_rate.get(label),
                         "ref_id_rate": base_rate.get(label), "id_rate": fl[label],
                         "change_pts": 100 * (fl[label] - base_rate.get(label, np.nan))})
    s = pd.DataFrame(rows)
    s["column"] = s["camera"] + ": " + s["effect"]
    shown = s.assign(cell=[f"{100 * r:.1f} ({c:+.1f})" for r, c in zip(s["id_rate"], s["change_pts"], strict=True)])
    base_cells = s.drop_duplicates(["camera", "label"]).assign(
        column=lambda d: d["camera"] + ": base", cell=lambda d: [f"{100 * r:.1f}" for r in d["base_id_rate"]])
    both = pd.concat([base_cells, shown], ignore_index=True)
    wide = both.pivot(index="label", columns="column", values="cell").reindex(
        index=list(dict.fromkeys(s["label"])), columns=list(dict.fromkeys(
            c for cam in CAMERAS for c in [f"{cam}: base", *[x for x in s["column"] if x.startswith(cam + ":")]])))
    return Table("realism_robustness", "Id rate (%) at each effect's harshest value, change from its zero point "
                 "(points)", s, markdown(wide.reset_index()),
                 ("Base: the camera's point with every effect off. Each effect's change is against its own "
                  "zero point (for planets: the near-ecliptic fields without planets; for distortion: the "
                  "calibrated lens); the flight point's against the base.",))


def tables(frame: pd.DataFrame, experiment: Experiment) -> list[Table]:
    out = [robustness_table(frame)]
    for cam in CAMERAS:
        out += [sweep(frame, effect, cam) for effect in SWEEPS]
        out.append(attitude_table(frame, cam))
    return [*out, planet_misid_table(frame), flight_table(frame)]
