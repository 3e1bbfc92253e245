"""The sky and the spacecraft (issue #24): every registered algorithm against the world effects.

Every registered algorithm runs with its defaults on the same trials (common random numbers:
trial ``k`` has the same attitude and unit noise at every point), on the Table 4 camera
(1024 x 1024 px, 10 deg, no exposure time given, so the smear's exposure is
:data:`starid.sky.DEFAULT_EXPOSURE_S` = 0.1 s), at a base of 0.5 px / 0.2 Mv noise in the real
sky. Each effect is swept alone from zero to a harsh value:

* ``rate``: angular rate 0-2 deg/s (a streak of 0-20.5 px at 0.1 s) about an axis drawn per
  trial (:mod:`starid.kernels.smear`);
* ``planets``: boresights within 5 deg of the ecliptic at :data:`EPOCH`, without and with the
  planets Mercury..Neptune in the sky (the same attitudes at both points); the table splits the
  trials by the number of planets in view (0, 1, 2+);
* ``aberration``: observer speed 0-40 km/s (the catalog the algorithms use is not corrected);
* ``focal``: the algorithms' assumed focal length off by 0-2 % (the cameras issue's calibration
  error, docs/cameras.md);

and one ``flight`` point with every effect at a typical value (:data:`FLIGHT`), over the whole
sky: the sky maps (``starid report``) are drawn for it when it has at least 2,000 trials
(:data:`SKYMAP_STUDY`).

Not here (yet): the wide CubeSat preset (an experiment has one camera: run
``starid sweep --camera cubesat_wide`` with the same axes) and uncalibrated lens distortion
(``starid reproduce cameras``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..experiment import Experiment, Grid, Study
from ..report.tables import Table, markdown, pct, rate_ci
from ..stats import summarize
from . import registered_beyond, sweep_table

NAME = "realism"
TITLE = "The sky and the spacecraft: smear, planets, aberration, calibration"
DESCRIPTION = "Every algorithm against motion smear, planets, stellar aberration and focal error (issue #24)"
DEFAULT_TRIALS = 200
#: The base world: moderate noise in the real sky.
SIM = {"sigma_px": 0.5, "sigma_mag": 0.2, "mag_limit": 6.0, "min_stars": 6}
#: The planets' epoch: the planets spread along the ecliptic (every one within 2 deg of it).
EPOCH = "2030-01-01T00:00:00"
#: One flight-like point: 0.5 deg/s (a slow slew or tumble; 5 px streaks at 0.1 s), the planets,
#: Earth's orbital speed plus a low orbit's (30 + 7.7 km/s), a 0.1 % focal-length error.
FLIGHT = {"rate_deg_s": 0.5, "planets": True, "epoch": EPOCH, "velocity_kms": 37.7, "focal_error_pct": 0.1}
#: The study the report's sky maps are drawn for (starid.report.skymap, >= 2,000 trials).
SKYMAP_STUDY = "flight"

SWEEPS = {
    "rate": ("rate_deg_s", [0.0, 0.5, 1.0, 2.0], {}, "angular rate (deg/s)"),
    "aberration": ("velocity_kms", [0.0, 10.0, 20.0, 40.0], {}, "observer speed (km/s)"),
    "focal": ("focal_error_pct", [0.0, 0.5, 1.0, 2.0], {}, "focal-length error (%)"),
}


def variants() -> tuple[str, ...]:
    """Every working registered algorithm, with its defaults."""
    return registered_beyond(())


def experiment(trials: int = DEFAULT_TRIALS, seed: int = 0) -> Experiment:
    algos = variants()
    studies = [Study(name, algos, Grid({axis: values, **{k: [v] for k, v in fixed.items()}}))
               for name, (axis, values, fixed, _) in SWEEPS.items()]
    studies.append(Study("planets", algos, Grid({"planets": [False, True], "near_ecliptic": [True],
                                                 "epoch": [EPOCH]})))
    studies.append(Study("flight", algos, Grid({k: [v] for k, v in FLIGHT.items()})))
    return Experiment(NAME, tuple(studies), trials=trials, seed=seed, camera={}, sim=dict(SIM),
                      description=DESCRIPTION)


def paper_points() -> pd.DataFrame:
    return pd.DataFrame(columns=["study", "axis", "value", "algorithm", "paper_id_rate"])


TITLES = {"rate": "Motion smear: id rate vs angular rate (0.1 s exposure)",
          "aberration": "Stellar aberration: id rate vs observer speed (catalog not corrected)",
          "focal": "Calibration: id rate vs focal-length error"}


def sweep(frame: pd.DataFrame, name: str) -> Table:
    axis, _, _, unit = SWEEPS[name]
    return sweep_table(frame, name, axis, {}, unit, TITLES[name], f"realism_{name}")


def attitude_table(frame: pd.DataFrame) -> Table:
    """Median attitude error (arcsec) of the correct identifications against observer speed:
    aberration moves the whole field almost rigidly, so the identification survives and the
    attitude (against the uncorrected catalog) carries the shift."""
    part = frame[(frame["study"] == "aberration") & (frame["status"] == "correct")]
    g = part.groupby(["label", "grid_velocity_kms"], sort=False)["attitude_err_arcsec"].median().reset_index()
    wide = g.pivot(index="label", columns="grid_velocity_kms", values="attitude_err_arcsec")
    wide = wide.reindex(index=list(dict.fromkeys(g["label"])))
    wide.columns = [f"{c:g} km/s" for c in wide.columns]
    shown = wide.map(lambda v: f"{v:.1f}").reset_index()
    return Table("realism_aberration_attitude", "Aberration: median attitude error of correct identifications "
                 "(arcsec)", g, markdown(shown),
                 ("Aberration by v/c displaces a star at angle theta from the apex by (v/c) sin(theta): 20.6 "
                  "arcsec at 30 km/s, nearly the same over a 10 deg field, so the pattern the algorithms match is "
                  "intact but the attitude against the uncorrected catalog is off by up to v/c.",))


def planets_in_view(frame: pd.DataFrame) -> pd.Series:
    """Planets imaged in each trial row: detections without a HIP (the planet studies add no false stars)."""
    return frame["n_stars"] - frame["n_true_stars"]


def planet_table(frame: pd.DataFrame) -> Table:
    """Id and misid rate by planets in view (with the planets) beside the same trials without them."""
    part = frame[frame["study"] == "planets"].copy()
    with_p = part[part["grid_planets"].astype(bool)]
    n_view = planets_in_view(with_p).clip(upper=2)
    view_of_trial = dict(zip(with_p["trial"], n_view, strict=False))
    part["in_view"] = part["trial"].map(view_of_trial).fillna(0).astype(int)
    part["world"] = np.where(part["grid_planets"].astype(bool), "planets", "no planets")
    rows = []
    for (label, world, k), g in part.groupby(["label", "world", "in_view"], sort=False):
        s = summarize(g).iloc[0]
        rows.append({"label": label, "world": world, "planets_in_view": k, "trials": int(s["trials"]),
                     "id_rate": s["id_rate"], "id_rate_lo": s["id_rate_lo"], "id_rate_hi": s["id_rate_hi"],
                     "misid_rate": s["misid_rate"]})
    s = pd.DataFrame(rows)
    s["cell"] = [f"{rate_ci(r, lo, hi)}, misid {pct(m)}" for r, lo, hi, m in
                 zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], s["misid_rate"], strict=True)]
    s["column"] = [f"{w}, {k if k < 2 else '2+'} in view (n={n})" for w, k, n in
                   zip(s["world"], s["planets_in_view"], s["trials"], strict=True)]
    order = sorted(s["column"].unique(), key=lambda c: (c.split(",")[1], c.startswith("planets")))
    wide = s.pivot(index="label", columns="column", values="cell").reindex(
        index=list(dict.fromkeys(s["label"])), columns=order)
    return Table("realism_planets", f"Planets: id rate by planets in view (boresights within 5 deg of the "
                 f"ecliptic, {EPOCH})", s, markdown(wide.reset_index()),
                 ("'no planets' is the same trials without the planets in the sky, split by how many the "
                  "planet run had in view, so each pair of columns differs by the planets alone.",))


def flight_table(frame: pd.DataFrame) -> Table:
    part = frame[frame["study"] == "flight"]
    s = summarize(part)
    shown = pd.DataFrame({"algorithm": s["label"],
                          "id rate": [rate_ci(r, lo, hi) for r, lo, hi in
                                      zip(s["id_rate"], s["id_rate_lo"], s["id_rate_hi"], strict=True)],
                          "misid": s["misid_rate"].map(pct), "no result": s["no_result_rate"].map(pct),
                          "median time": s["time_median_us"].map(lambda v: f"{v / 1e3:.2f} ms")})
    setting = ", ".join(f"{k} = {v}" for k, v in FLIGHT.items())
    return Table("realism_flight", "Flight point: every effect at a typical value", s, markdown(shown),
                 (f"{setting}; boresights over the whole sky.",))


def tables(frame: pd.DataFrame, experiment: Experiment) -> list[Table]:
    return [*(sweep(frame, name) for name in SWEEPS), attitude_table(frame), planet_table(frame),
            flight_table(frame)]
