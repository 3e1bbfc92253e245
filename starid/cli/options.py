"""Argument groups shared by the commands, and their conversion to starid objects."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..camera import Camera
from ..errors import ConfigError
from ..experiment.executors import BUILD_TIME_LIMIT_S, DEFAULT_TIME_LIMIT_S
from ..simulate import PIPELINES, SKIES

MAX_TRIALS = 10_000_000


class Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults in every help line that does not already say its default, examples kept as
    written; an unset default (None, a flag's False) is not printed."""

    def _get_help_string(self, action):
        text = action.help or ""
        unset = action.default is None or action.default is False or action.default is argparse.SUPPRESS
        if unset or "default" in text:
            return text
        return super()._get_help_string(action)


def trials_type(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if not 1 <= n <= MAX_TRIALS:
        raise argparse.ArgumentTypeError(f"must be from 1 to {MAX_TRIALS:,}, got {n}")
    return n


def seed_type(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {n}")
    return n


def jobs_type(text: str) -> int:
    cores = os.cpu_count() or 1
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if not 1 <= n <= cores:
        raise argparse.ArgumentTypeError(f"must be from 1 to {cores} (this machine's cores; more would "
                                         f"oversubscribe the timings), got {n}")
    return n


def add_engine(p: argparse.ArgumentParser, trials: int | None, seed: int = 0) -> None:
    """--trials --seed --jobs --executor --scheduler --time-limit --quiet --out."""
    if trials is not None:
        p.add_argument("--trials", type=trials_type, default=trials, help="images per grid point")
    p.add_argument("--seed", type=seed_type, default=seed, help="simulator seed (trial k is reproducible "
                   "from (seed, k) alone)")
    p.add_argument("--jobs", type=jobs_type, default=os.cpu_count() or 1,
                   help="worker processes (default: all cores); every result but the times is identical for any "
                        "number")
    p.add_argument("--executor", choices=("local", "dask"), default="local",
                   help="where chunks run: supervised local processes, or a Dask cluster (starid-bench[dask]) whose "
                        "workers supervise them the same way, under the same limits")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: a LocalCluster); its "
                   "workers must not be daemonic: DASK_DISTRIBUTED__WORKER__DAEMON=False dask worker ADDRESS")
    add_limits(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def add_limits(p: argparse.ArgumentParser, engine: bool = True) -> None:
    """--time-limit --build-time-limit --memory-limit-gb: the engine's (``engine``), or those of a command
    that calls plugin code itself (show, identify, check: one supervised process per algorithm)."""
    where = "per worker" if engine else "per algorithm"
    p.add_argument("--time-limit", type=float, default=DEFAULT_TIME_LIMIT_S, metavar="S",
                   help="per-image identify time limit in seconds; slower images are recorded as 'timeout'"
                        + ("" if engine else " (explain() too)"))
    p.add_argument("--build-time-limit", type=float, default=BUILD_TIME_LIMIT_S, metavar="S",
                   help=f"seconds an algorithm may take to prepare (derived + build, then the warm-up identify that "
                        f"compiles its kernels) {where}; beyond, its images are recorded as 'timeout'")
    p.add_argument("--memory-limit-gb", type=float, default=None, metavar="GB",
                   help="GB a worker's address space may grow by in a chunk's preparation and again in its "
                        "images (default: the machine's memory / --jobs); an image that exceeds it is recorded as "
                        "'crashed'" if engine else
                        "GB the address space of the process each algorithm runs in may grow by while it "
                        "prepares and again over its images (default: the machine's memory); exceeding it is "
                        "that algorithm's 'crashed'")


def add_out(p: argparse.ArgumentParser, what: str, required: bool = False) -> None:
    p.add_argument("--out", type=Path, required=required, metavar="DIR",
                   help=f"results folder: {what}; running the same command on it again resumes an interrupted run")
    p.add_argument("--overwrite", action="store_true",
                   help="--out holds another definition's results: delete everything in it (reports included) "
                        "and start afresh (refused otherwise, naming what the folder holds)")
    p.add_argument("--extend", action="store_true",
                   help="--out holds a changed definition of the same experiment: reuse its chunks (only new "
                        "points and variants are computed); its reports and tables made before are removed")


def add_world(p: argparse.ArgumentParser, pos_default: float = 0.0, mag_default: float = 0.0,
              exposure: bool = True) -> None:
    """The simulated world: noise, false and lost stars, sky, catalog, and the sky effects
    (:mod:`starid.sky`; ``exposure=False`` where the command has its own ``--exposure-s``)."""
    g = p.add_argument_group("simulated world")
    g.add_argument("--pos-noise-px", type=float, default=pos_default, help="centroid noise sigma in px")
    g.add_argument("--mag-noise", type=float, default=mag_default, help="magnitude noise sigma in mag")
    g.add_argument("--false-stars", type=int, default=0, help="false stars added per image")
    g.add_argument("--lost-stars", type=int, default=0, help="detections removed per image")
    g.add_argument("--min-stars", type=int, default=6, help="redraw images with fewer true stars")
    g.add_argument("--mag-limit", type=float, default=6.0, help="sensor detection limit in mag")
    g.add_argument("--merge-radius-px", type=float, default=2.0, help="stars closer than this merge")
    g.add_argument("--sky", choices=tuple(SKIES), default=None,
                   help="which stars are imaged: 'real' = every catalog star (V <= 8), 'paper' = the papers' "
                        "guide stars only (V <= 6), 'fig10' = V <= 6.15 (calibrated on Zhou & Ye's Fig. 10 star "
                        "counts); default real")
    g.add_argument("--sky-mag-limit", type=float, default=None,
                   help="image only catalog stars with V <= this (6.0 is the paper's sky)")
    g.add_argument("--catalog", help="CSV catalog (hip,ra_deg,dec_deg,vmag) instead of the embedded Hipparcos")
    g.add_argument("--pipeline", choices=PIPELINES, default="centroids",
                   help="'centroids': Gaussian noise on ideal centroids; 'image': render each image to pixels and "
                        "extract its stars (the render's noise replaces --pos-noise-px and --mag-noise; summaries "
                        "add detection rate, false detections and rms centroid error)")
    add_sky(p, exposure)


def add_sky(p: argparse.ArgumentParser, exposure: bool = True) -> None:
    """The sky and spacecraft effects (all off by default; starid.sky)."""
    g = p.add_argument_group("sky and spacecraft (all off by default)")
    g.add_argument("--rate-deg-s", type=float, default=0.0, help="angular rate in deg/s during the exposure "
                   "(motion smear), about an axis drawn per trial unless --rate-axis")
    g.add_argument("--rate-axis", metavar="X,Y,Z", default=None, help="rotation axis in the camera frame")
    if exposure:
        g.add_argument("--exposure-s", type=float, default=None, help="exposure in s (default: the camera's, "
                       "else 0.1)")
    g.add_argument("--epoch", default=None, help="observation time, ISO UTC (e.g. 2030-01-01T00:00:00) or a year")
    g.add_argument("--planets", action="store_true", help="put Mercury..Neptune in the sky at --epoch")
    g.add_argument("--moon", action="store_true", help="put the Moon in the sky at --epoch")
    g.add_argument("--planets-in-view", type=int, default=0, metavar="K",
                   help="put K (0-5) of the naked-eye planets, drawn per trial, at their magnitudes at --epoch "
                        "into every field")
    g.add_argument("--near-ecliptic", action="store_true", help="draw boresights within 5 deg of the ecliptic")
    g.add_argument("--velocity-kms", type=float, default=0.0, help="observer speed in km/s (stellar aberration; "
                   "the catalog is not corrected)")


def sky_settings(args) -> dict:
    """The sky effects the options give (only those that are not off, so existing settings stay equal)."""
    out = {}
    for key, off in (("rate_deg_s", 0.0), ("rate_axis", None), ("exposure_s", None), ("epoch", None),
                     ("planets", False), ("moon", False), ("planets_in_view", 0), ("near_ecliptic", False),
                     ("velocity_kms", 0.0)):
        value = getattr(args, key, off)
        if value != off:
            out[key] = value
    return out


def world_settings(args) -> dict:
    """The simulator settings the world options give (a dict for :class:`~starid.simulate.SimConfig`)."""
    if args.sky is not None and args.sky_mag_limit is not None:
        raise ConfigError("give either --sky or --sky-mag-limit, not both")
    settings = {"sigma_px": args.pos_noise_px, "sigma_mag": args.mag_noise, "mag_limit": args.mag_limit,
                "false_stars": args.false_stars, "lost_stars": args.lost_stars, "min_stars": args.min_stars,
                "merge_radius_px": args.merge_radius_px, "pipeline": args.pipeline, **sky_settings(args)}
    if args.sky is not None:
        settings["sky"] = args.sky
    elif args.sky_mag_limit is not None:
        settings["sky_mag_limit"] = args.sky_mag_limit
    return settings


def resolution_type(text: str) -> tuple[int, int]:
    """``--resolution``: ``N`` (a square N x N sensor, as before) or ``WxH``."""
    parts = text.lower().replace(" ", "").split("x")
    try:
        values = [int(v) for v in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be N or WIDTHxHEIGHT in px (e.g. 1024 or 1024x768), got {text!r}") from None
    if len(values) == 1:
        return values[0], values[0]
    if len(values) == 2:
        return values[0], values[1]
    raise argparse.ArgumentTypeError(f"must be N or WIDTHxHEIGHT in px (e.g. 1024 or 1024x768), got {text!r}")


def add_camera(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("camera (default: Zhou & Ye Table 4, 1024 px, 12 um, 70.2262 mm: 10 x 10 deg)")
    g.add_argument("--camera", metavar="NAME|FILE", help="a camera preset ('starid cameras' lists them) or a "
                   "camera TOML file; the options below override its fields")
    g.add_argument("--fov-deg", type=float, help="field of view across the image width")
    g.add_argument("--resolution", type=resolution_type, metavar="N|WxH",
                   help="image size in px: N (square) or WIDTHxHEIGHT, e.g. 1024x768")
    g.add_argument("--focal-mm", type=float, help="focal length in mm")
    g.add_argument("--pixel-um", type=float, help="pixel pitch in um")


def camera_spec(args) -> dict:
    """The camera options as :class:`~starid.experiment.Experiment` camera settings (checked)."""
    given = {k: getattr(args, k) for k in ("fov_deg", "resolution", "focal_mm", "pixel_um")
             if getattr(args, k, None) is not None}
    if "fov_deg" in given and "focal_mm" in given:
        raise ConfigError("give either --fov-deg or --focal-mm, not both")
    preset = getattr(args, "camera", None)
    resolution = given.get("resolution")
    if resolution is not None and not isinstance(resolution, tuple):
        resolution = (resolution, resolution)
    if "fov_deg" in given and preset is None and (resolution is None or resolution[0] == resolution[1]):
        spec = {"fov_deg": given["fov_deg"], "resolution_px": resolution[0] if resolution else 1024,
                "pixel_um": given.get("pixel_um", 12.0)}
    else:
        spec = {} if preset is None else {"preset": preset}
        if "fov_deg" in given:
            spec["fov_deg"] = given["fov_deg"]
        if resolution is not None:
            spec["width_px"], spec["height_px"] = resolution
        if "focal_mm" in given:
            spec["focal_mm"] = given["focal_mm"]
        if "pixel_um" in given:
            spec["pixel_um"] = given["pixel_um"]
    if preset is not None or "fov_deg" in spec:
        make_camera(spec)       # checked now: a bad file or field fails before any work
    return spec


def make_camera(spec: dict) -> Camera:
    from ..cameras import camera_from_spec

    spec = dict(spec)
    if "fov_deg" in spec and "preset" not in spec and "width_px" not in spec:
        return Camera.from_fov(spec["fov_deg"], spec["resolution_px"], spec["pixel_um"])
    return camera_from_spec(spec)


def progress(args) -> bool:
    return not getattr(args, "quiet", False) and sys.stderr.isatty()


def check_out(path: Path | None) -> None:
    """Refuse an ``--out`` folder that is a file or cannot be created or written, before any work
    is done (nothing is created here: a refused run leaves nothing behind)."""
    if path is None:
        return
    if path.exists() and not path.is_dir():
        raise ConfigError(f"--out {path} is a file, not a folder")
    existing = path.resolve()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ConfigError(f"--out {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot write to --out {path}: {existing} is not writable")
