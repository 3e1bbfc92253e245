"""``starid show``: one simulated image, every algorithm's identification (and reasoning) drawn on it.

:func:`show` regenerates trial ``K`` of a seed (the same image ``starid run`` scored as trial
``K`` with the same world settings), runs each algorithm on it as the harness does (database
built once, ``identify`` on the read-only observation without truth), calls the optional
``explain(database, observation)`` when the plugin has one, and draws
:func:`starid.plots.show_figure`: one panel per algorithm on the same image.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import pandas as pd
from matplotlib.figure import Figure

from .. import plots
from ..camera import Camera
from ..catalog import Catalog, load_hipparcos
from ..errors import ConfigError
from ..experiment import Variant
from ..experiment.executors import Limits, call_supervised, memory_error
from ..experiment.spec import sim_settings
from ..plugin import Explanation, check_identification
from ..scoring import CRASHED, score_trial
from ..simulate import SimConfig, Simulator


@dataclass(eq=False)
class Shown:
    """What :func:`show` computed: the figure, the image's stars and each label's ids and result."""

    figure: Figure
    stars: pd.DataFrame
    ids: pd.DataFrame
    results: pd.DataFrame
    explanations: dict


def explain(algorithm, database, observation) -> tuple[Explanation | None, str]:
    """The algorithm's explanation of this image, or ``None`` with the reason (no method, or it failed)."""
    method = getattr(algorithm, "explain", None)
    if method is None or not callable(method):
        return None, "no explain()"
    try:
        ex = method(database, observation)
    except Exception as exc:  # a teaching picture must not die of one plugin's bug
        return None, f"explain failed: {type(exc).__name__}: {exc}"
    if not isinstance(ex, Explanation):
        return None, f"explain returned {type(ex).__name__}, not starid.Explanation"
    return ex, ""


class _InProcess:
    """The control of :func:`_panel` without supervision (``limits=None``)."""

    def phase(self, name: str, build: bool = False) -> None:
        pass

    def emit(self, item) -> None:
        pass


def _panel(algorithm, database, catalog: Catalog, camera: Camera, view, control):
    """One algorithm on one image: build (unless ``database``), warm up, identify, explain; each call
    announced to ``control`` (:func:`~starid.experiment.executors.call_supervised`). Returns ``(hip, error,
    elapsed_ms, explanation, why)``; a plugin's exception is its ``error``."""
    hip, error, elapsed_ms = None, "", float("nan")
    try:
        if database is None:
            control.phase("build", build=True)
            database = algorithm.build(catalog, camera)
        control.phase("the warm-up identify", build=True)
        algorithm.identify(database, view)          # warm the JIT up, as the harness does
        control.phase("identify")
        t0 = time.perf_counter()
        result = algorithm.identify(database, view)
        elapsed_ms = (time.perf_counter() - t0) * 1e3
        check_identification(result, len(view), catalog.hip)
        hip = result.hip.astype("int64")
        control.emit((hip, elapsed_ms))     # drawn even when explain then overruns
        control.phase("explain")
        ex, why = explain(algorithm, database, view)
    except Exception as exc:  # shown in the panel's title, not raised: the other panels still draw
        error, ex, why = f"{type(exc).__name__}: {exc}", None, ""
    return hip, error, elapsed_ms, ex, why


def draw_trial(sim: Simulator, trial: int):
    """Trial ``trial`` exactly as the engine scores it: the simulator's projection, or for the
    ``image`` pipeline the render -> extract detections (:func:`starid.render.image_trials`)."""
    if sim.config.pipeline == "image":
        from ..render import image_trials

        return image_trials(sim, 1, int(trial))[0].observation(0)
    return sim.generate(1, int(trial)).observation(0)


def show(algorithms, trial: int, seed: int = 0, world: dict | None = None, camera: Camera | None = None,
         catalog: Catalog | None = None, label_stars: bool = True, databases: dict | None = None,
         recorded: dict | None = None, heading: str = "", limits: Limits | None = None) -> Shown:
    """Trial ``trial`` of ``seed`` in the world ``world`` (SimConfig fields, or ``sky``), one panel per
    algorithm (names or variants such as ``"ptp[n_slaves=3]"``).

    ``databases`` (label -> database built for the same catalog and camera) skips the builds, e.g.
    when a notebook draws several images. ``recorded`` (label -> the row a results folder holds for
    this trial) puts the folder's status beside the redrawn one in each caption (:func:`show_folder`).

    ``limits`` (:class:`~starid.experiment.executors.Limits`; the command always gives them) runs each
    algorithm's calls in a supervised process: a build or warm-up past ``build_time_limit_s``, an identify or
    explain past ``time_limit_s`` or memory past ``memory_limit_gb`` is that panel's ``timeout`` /
    ``crashed``, the other panels drawn as usual. Without, they run in this process.
    """
    if not algorithms:
        raise ConfigError("show needs at least one algorithm")
    if int(trial) != trial or trial < 0:
        raise ConfigError(f"--trial must be a whole number >= 0, got {trial!r}")
    variants = [a if isinstance(a, Variant) else Variant.parse(a) for a in algorithms]
    labels = [v.label for v in variants]
    if len(set(labels)) != len(labels):
        raise ConfigError(f"an algorithm is given twice ({', '.join(labels)})")
    catalog = catalog or load_hipparcos()
    camera = camera or Camera()
    config = SimConfig(**sim_settings(dict(world or {}), {}))
    sim = Simulator(catalog, camera, config, seed)
    obs = draw_trial(sim, int(trial))
    view = obs.for_plugin()
    stars = obs.to_frame()
    id_rows, results, explanations, titles = [], [], {}, {}
    for variant in variants:
        algorithm = variant.make().resolved(config)
        database = (databases or {}).get(variant.label)

        def panel(control, algorithm=algorithm, database=database):
            return _panel(algorithm, database, catalog, camera, view, control)

        status = ""
        if limits is None:
            hip, error, elapsed_ms, ex, why = panel(_InProcess())
        else:                   # every plugin call in a supervised process, under the limits
            outcome = call_supervised(panel, limits)
            if outcome.status:
                hip, elapsed_ms = outcome.emitted[-1] if outcome.emitted else (None, float("nan"))
                ex, why, status, error = None, outcome.error, outcome.status, outcome.error
            else:
                hip, error, elapsed_ms, ex, why = outcome.value
                memory = memory_error(error, limits.memory_limit_gb)
                if memory:
                    status, error = CRASHED, memory
                why = memory_error(why, limits.memory_limit_gb) or why
        if hip is None:
            hip = pd.Series(-1, index=range(len(obs))).to_numpy()
        scored = score_trial(hip, obs.truth_hip)
        status = status or ("error" if error else scored["status"])
        results.append({"label": variant.label, "status": status, "time_ms": elapsed_ms, "error": error,
                        "explain": "yes" if ex is not None else why, **{k: v for k, v in scored.items()
                                                                         if k != "status"}})
        id_rows.append(pd.DataFrame({"label": variant.label, "star": range(len(obs)), "hip": hip}))
        explanations[variant.label] = ex
        titles[variant.label] = (f"{status}, {elapsed_ms:.2f} ms" if not error else f"{status}: {error[:70]}")
        if recorded and variant.label in recorded:
            row = recorded[variant.label]
            titles[variant.label] = (f"folder: {row['status']} ({int(row['n_correct'])} correct, "
                                     f"{int(row['n_wrong'])} wrong); redrawn: {titles[variant.label]}")
            results[-1]["folder_status"] = row["status"]
    ids = pd.concat(id_rows, ignore_index=True)
    world_text = ", ".join(f"{k} = {v:g}" for k, v in config.as_dict().items()
                           if k in ("sigma_px", "sigma_mag", "false_stars", "lost_stars"))
    world_text += ("; real sky (every star to V 8)" if config.sky_mag_limit is None
                   else f"; sky V <= {config.sky_mag_limit:g}")
    heading = (heading + f"trial {trial}, seed {seed}: {len(obs)} detections ({int((obs.truth_hip >= 0).sum())} true); "
               f"{world_text}")
    fig = plots.show_figure(stars, ids, explanations, camera.width_px, camera.height_px, titles, label_stars,
                            suptitle=heading)
    return Shown(fig, stars, ids, pd.DataFrame(results), explanations)


def show_folder(folder, trial: int, labels=None, study: str | None = None, point: int | None = None,
                catalog: Catalog | None = None, label_stars: bool = True,
                limits: Limits | None = None) -> tuple[Shown, pd.DataFrame]:
    """Redraw trial ``trial`` of a results folder: the very image it scored (the manifest's camera,
    seed and the point's world settings; the same draw), one panel per label (default: every label
    at that point) with the folder's status beside the redrawn one. Returns the figure and the
    folder's rows for that trial.

    With several studies or points, ``study`` / ``point`` choose one (default: the first); ``limits`` as
    :func:`show`'s.
    :class:`ConfigError` for a trial, label, study or point the folder does not hold.
    """
    from pathlib import Path

    from ..experiment import Experiment
    from ..experiment.spec import sim_settings as expand
    from .build import load

    folder = Path(folder)
    manifest, frame = load(folder)
    exp = Experiment.from_dict(manifest["experiment"])
    if int(trial) != trial or not 0 <= trial < exp.trials:
        raise ConfigError(f"--trial {trial}: {folder} holds trials 0..{exp.trials - 1}")
    names = [s.name for s in exp.studies]
    if study is not None and study not in names:
        raise ConfigError(f"--study {study!r}: {folder} holds {', '.join(map(repr, names))}")
    chosen = next(s for s in exp.studies if s.name == (study or names[0]))
    points = chosen.grid.points()
    p = 0 if point is None else int(point)
    if not 0 <= p < len(points):
        raise ConfigError(f"--point {point}: study {chosen.name!r} has points 0..{len(points) - 1}")
    variants = {v.label: v for v in chosen.variants}
    labels = list(labels or variants)
    unknown = [x for x in labels if x not in variants]
    if unknown:
        raise ConfigError(f"--label {unknown[0]!r}: study {chosen.name!r} of {folder} has labels "
                          f"{', '.join(variants)}")
    rows = frame[(frame["study"] == chosen.name) & (frame["point"] == p) & (frame["trial"] == trial)
                 & frame["label"].isin(labels)]
    recorded = {r["label"]: r for r in rows.to_dict("records")}
    world = expand(exp.sim, points[p])
    where = ", ".join(f"{k} = {v}" for k, v in points[p].items())
    heading = (f"{folder.name}: study {chosen.name}" + (f", point {p} ({where})" if where else "") + "; ")
    shown = show([variants[x] for x in labels], int(trial), exp.seed, world, exp.make_camera(), catalog,
                 label_stars=label_stars, recorded=recorded, heading=heading, limits=limits)
    return shown, rows.reset_index(drop=True)


__all__ = ["Shown", "draw_trial", "explain", "show", "show_folder"]
