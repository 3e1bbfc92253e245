"""The one star-image simulator every algorithm is scored on.

Each trial is reproducible from ``(seed, trial index)`` alone, so any trial can be regenerated
for inspection without generating the ones before it. Two streams per trial give **common
random numbers**: attitudes come from ``default_rng([seed, trial, 0])`` and every noise draw
from ``default_rng([seed, trial, 1])``, so trial ``k`` has the same attitude at every noise
level, sky and false-star count (unless the ``min_stars`` filter redraws it), and two grid
points or algorithms can be compared trial by trial.

The **sky** is which catalog stars are imaged at all: ``sky_mag_limit = None`` (the *real*
sky) images every star of the catalog (the embedded one goes to V 8), so magnitude noise can
bring stars that are in no guide list into the image; ``sky_mag_limit = 6`` (the *paper's*
sky) images only the papers' guide stars, so magnitude noise can only remove stars.
:data:`SKIES` names them.

One trial (defaults in :class:`SimConfig`):

1. draw an attitude uniformly over SO(3) (:func:`starid.attitude.random_attitude`);
2. take the sky's catalog stars (all of them, or those with V <= ``sky_mag_limit``) near the
   boresight with a k-d tree on unit vectors, and project them
   (:mod:`starid.camera` conventions);
3. stars closer than ``merge_radius_px`` become one detection at the flux-weighted centroid
   with the combined magnitude; its truth is the brighter star;
4. add N(0, ``sigma_mag``) to each magnitude; a star is detected when its noisy magnitude
   is <= ``mag_limit`` (the algorithms see noisy magnitudes);
5. add N(0, ``sigma_px``) to x and y; stars pushed off the sensor are dropped;
6. remove ``lost_stars`` random detections and add ``false_stars`` uniform on the sensor with
   magnitudes uniform over the detected range (truth id -1);
7. redraw the attitude while fewer than ``min_stars`` true stars are detected (Zhou & Ye keep
   images with "more than five stars"); the number of redraws is recorded;
8. shuffle the detections, so no algorithm can lean on catalog order.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from starid.kernels.jit import kernel

from . import sky
from .attitude import random_attitude
from .camera import Camera
from .catalog import Catalog
from .errors import ConfigError
from .observation import Observation, TrialSet
from .params import check_choice, check_number, check_whole

MAX_REDRAWS = 10_000
#: Centroid-noise margin (px) around the sensor inside which stars get noise draws at any noise level.
CRN_MARGIN_PX = 50.0
#: The trial index of the warm-up image (never part of a scored range).
WARMUP_TRIAL = 2**62


@dataclass(frozen=True)
class SimConfig:
    """Simulator parameters (units in the names)."""

    sigma_px: float = 0.0
    sigma_mag: float = 0.0
    mag_limit: float = 6.0
    false_stars: int = 0
    lost_stars: int = 0
    min_stars: int = 6
    merge_radius_px: float = 2.0
    sky_mag_limit: float | None = None
    #: "centroids": Gaussian noise on ideal centroids (the default); "image": every trial is
    #: rendered to pixels and its stars extracted (:mod:`starid.render`, :mod:`starid.extract`);
    #: the render's own noise then replaces ``sigma_px`` and ``sigma_mag``.
    pipeline: str = "centroids"
    #: The camera the algorithm assumes versus the one that imaged the sky (docs/cameras.md): its
    #: focal length off by this many percent, its principal point off by this many px (along the
    #: +x+y diagonal), and its distortion ``"true"`` (calibrated) or ``"none"`` (a pinhole assumed).
    focal_error_pct: float = 0.0
    principal_point_error_px: float = 0.0
    assumed_distortion: str = "true"
    #: World effects (:mod:`starid.sky`), all off by default: angular rate (deg/s) about
    #: ``rate_axis`` ("X,Y,Z" camera frame; None = drawn per trial) during ``exposure_s`` (None =
    #: the camera's), ``epoch`` (ISO UTC or a year), ``planets`` / ``moon`` in the sky,
    #: boresights ``near_ecliptic``, observer ``velocity_kms`` (stellar aberration).
    rate_deg_s: float = 0.0
    exposure_s: float | None = None
    rate_axis: str | None = None
    epoch: str | float | None = None
    planets: bool = False
    moon: bool = False
    near_ecliptic: bool = False
    velocity_kms: float = 0.0
    #: that many of the naked-eye planets imaged in every field (:func:`starid.sky.forced_planets`)
    planets_in_view: int = 0

    def __post_init__(self):
        for name in ("planets", "moon", "near_ecliptic"):   # 0/1 from a numeric grid axis
            value = getattr(self, name)
            if value in (0, 1) and not isinstance(value, bool):
                object.__setattr__(self, name, bool(value))
            elif not isinstance(value, bool):
                raise ConfigError(f"{name} must be true or false, got {value!r}")
        if isinstance(self.planets_in_view, float) and self.planets_in_view.is_integer():   # 2.0 from --param
            object.__setattr__(self, "planets_in_view", int(self.planets_in_view))
        sky.check_config(self)
        for name in ("sigma_px", "sigma_mag", "merge_radius_px"):
            check_number(name, getattr(self, name), lo=0)
        check_number("mag_limit", self.mag_limit)
        if self.sky_mag_limit is not None:
            check_number("sky_mag_limit", self.sky_mag_limit)
        check_choice("pipeline", self.pipeline, PIPELINES)
        check_number("focal_error_pct", self.focal_error_pct, lo=-50, hi=50)
        check_number("principal_point_error_px", self.principal_point_error_px)
        check_choice("assumed_distortion", self.assumed_distortion, ASSUMED_DISTORTION)
        for name in ("false_stars", "lost_stars", "min_stars"):
            check_whole(name, getattr(self, name), 0)

    def as_dict(self) -> dict:
        return asdict(self)


PIPELINES = ("centroids", "image")
ASSUMED_DISTORTION = ("true", "none")


def assumed_camera(camera: Camera, config: SimConfig) -> Camera:
    """The calibration an algorithm is given for ``camera`` under ``config``'s camera errors
    (``camera`` itself when there are none)."""
    changes = {}
    if config.focal_error_pct != 0.0:
        changes["focal_mm"] = camera.focal_mm * (1.0 + config.focal_error_pct / 100.0)
    if config.principal_point_error_px != 0.0:
        d = config.principal_point_error_px / math.sqrt(2.0)
        changes["cx_px"], changes["cy_px"] = camera.cx_px + d, camera.cy_px + d
    if config.assumed_distortion == "none" and camera.distorted:
        changes["distortion"] = (0.0, 0.0, 0.0, 0.0, 0.0)
    return camera.replace(**changes) if changes else camera

#: Named skies: the settings that decide which stars are imaged (see the module docstring).
#: ``fig10`` is calibrated on Zhou & Ye's Fig. 10 (mean 14.18 stars in the field, noise-free):
#: imaging and detection limit V <= 6.15 gives a mean of 14.2 (V <= 6.0 gives 12.1); see
#: docs/simulator.md for what it does not reproduce (the share of fields with more than 8 stars).
SKIES = {
    "real": {"sky_mag_limit": None},
    "paper": {"sky_mag_limit": 6.0},
    "fig10": {"sky_mag_limit": 6.15, "mag_limit": 6.15},
}


@kernel
def _merge_labels(x_px, y_px, radius_px):
    """Union-find labels of stars closer than ``radius_px`` (label = smallest member index)."""
    n = x_px.shape[0]
    parent = np.arange(n)
    r2 = radius_px * radius_px
    for i in range(n):
        for j in range(i + 1, n):
            dx = x_px[i] - x_px[j]
            dy = y_px[i] - y_px[j]
            if dx * dx + dy * dy < r2:
                a = i
                while parent[a] != a:
                    a = parent[a]
                b = j
                while parent[b] != b:
                    b = parent[b]
                if a != b:
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
    for i in range(n):
        a = i
        while parent[a] != a:
            a = parent[a]
        parent[i] = a
    return parent


class Simulator:
    """Generates reproducible star images of ``catalog`` seen by ``camera``."""

    def __init__(self, catalog: Catalog, camera: Camera | None = None, config: SimConfig | None = None,
                 seed: int = 0):
        self.catalog = catalog
        self.camera = camera or Camera()
        self.config = config or SimConfig()
        if int(seed) != seed or seed < 0:
            raise ConfigError(f"seed must be a whole number >= 0, got {seed!r}")
        self.seed = int(seed)
        cfg = self.config
        #: the camera the algorithms are given (the true one unless the config says otherwise)
        self.assumed = assumed_camera(self.camera, cfg)
        # Candidates: every star that magnitude noise could bring to the detection limit, and every
        # star near enough to the sensor for centroid noise to push it in. Both bounds are fixed
        # (not scaled by the noise up to 0.5 Mv and 8 px) so that the candidates -- and with them
        # each star's noise draws -- are the same at every noise level and in every sky.
        bright = catalog.v_mag <= cfg.mag_limit + max(3.0, 6.0 * cfg.sigma_mag) + 1.5
        self._hip = catalog.hip[bright]
        self._v_mag = catalog.v_mag[bright]
        self._unit_icrs = sky.star_units(catalog, cfg)[bright]   # J2000, or at the epoch (proper motion)
        self._unit_icrs, self._v_mag, self._hip, body = sky.world_stars(self._unit_icrs, self._v_mag, self._hip, cfg)
        self._in_sky = np.ones(self._hip.size, dtype=bool) if cfg.sky_mag_limit is None \
            else self._v_mag <= cfg.sky_mag_limit
        self._in_sky = self._in_sky | body               # planets and the Moon are always in the sky
        self._tree = cKDTree(self._unit_icrs)
        self._margin_px = cfg.merge_radius_px + max(CRN_MARGIN_PX, 6.0 * cfg.sigma_px + 1.0)
        half_diag_rad = self.camera.reach_rad(self._margin_px)
        if half_diag_rad >= math.pi / 2:
            raise ConfigError("the camera's field of view is too wide for the simulator (>= 180 deg)")
        self._query_chord = 2.0 * math.sin(half_diag_rad / 2.0)

    def params(self) -> dict:
        """Everything that determines the trials, flat, for result rows."""
        return {"seed": self.seed, **{f"sim_{k}": v for k, v in self.config.as_dict().items()},
                **self.camera.columns(),
                "catalog": self.catalog.name, "catalog_stars": len(self.catalog)}

    def _draw_once(self, att_rng: np.random.Generator, rng: np.random.Generator, draws: dict | None = None):
        cfg, cam = self.config, self.camera
        attitude = random_attitude(att_rng)
        if cfg.near_ecliptic:
            attitude = sky.near_ecliptic_attitude(attitude, att_rng)
        idx = np.sort(np.asarray(self._tree.query_ball_point(attitude[2], self._query_chord), dtype=np.int64))
        v_cam = sky.apparent(self._unit_icrs[idx], cfg, draws) @ attitude.T
        front = v_cam[:, 2] > 1e-9
        idx, v_cam = idx[front], v_cam[front]
        x_px, y_px = cam.project(v_cam)    # through the true camera (its lens included)
        m = self._margin_px
        near = (x_px >= -m) & (x_px < cam.width_px + m) & (y_px >= -m) & (y_px < cam.height_px + m)
        idx, x_px, y_px = idx[near], x_px[near], y_px[near]
        smear = sky.smear_on(cfg)
        if smear:   # each star at its streak's centre; streak vectors for the noise
            cdx, cdy, ldx, ldy = sky.smear_centroids(v_cam[near], cam, cfg, draws["smear_axis"])
            x_px, y_px = x_px + cdx, y_px + cdy
        # each candidate star's own noise draws (common random numbers), then the sky's cut
        z = rng.normal(0.0, 1.0, (3, idx.size))
        in_sky = self._in_sky[idx]
        idx, x_px, y_px, z = idx[in_sky], x_px[in_sky], y_px[in_sky], z[:, in_sky]
        if smear:
            ldx, ldy = ldx[in_sky], ldy[in_sky]
        v_mag = self._v_mag[idx]
        hip = self._hip[idx]
        if cfg.merge_radius_px > 0 and idx.size > 1:
            x_px, y_px, v_mag, hip, rep = self._merge(x_px, y_px, v_mag, hip)
            z = z[:, rep]
            if smear:
                ldx, ldy = ldx[rep], ldy[rep]
        if smear:   # centroid noise stretched along the streak (starid.kernels.smear.smear_noise)
            z = np.stack([z[0], *sky.smear_noise_draws(z[1], z[2], ldx, ldy)])
        mag = v_mag + z[0] * cfg.sigma_mag
        x_px = x_px + z[1] * cfg.sigma_px
        y_px = y_px + z[2] * cfg.sigma_px
        forced = sky.forced_planets(cfg, cam, draws) if cfg.planets_in_view else None
        if forced is not None:   # planets_in_view: planets put into the field (truth id -1)
            x_px, y_px, mag = (np.concatenate([a, b]) for a, b in zip((x_px, y_px, mag), forced, strict=True))
            hip = np.concatenate([hip, np.full(forced[0].size, sky.PLANET_ID, dtype=hip.dtype)])
        keep = (mag <= cfg.mag_limit) & cam.in_image(x_px, y_px)
        x_px, y_px, mag, hip = x_px[keep], y_px[keep], mag[keep], hip[keep]
        if cfg.lost_stars:
            drop = rng.choice(hip.size, size=min(cfg.lost_stars, hip.size), replace=False)
            keep = np.ones(hip.size, dtype=bool)
            keep[drop] = False
            x_px, y_px, mag, hip = x_px[keep], y_px[keep], mag[keep], hip[keep]
        if cfg.false_stars:
            k = cfg.false_stars
            lo, hi = (mag.min(), mag.max()) if mag.size else (cfg.mag_limit - 1.0, cfg.mag_limit)
            x_px = np.concatenate([x_px, rng.uniform(0.0, cam.width_px, k)])
            y_px = np.concatenate([y_px, rng.uniform(0.0, cam.height_px, k)])
            mag = np.concatenate([mag, rng.uniform(lo, hi, k)])
            hip = np.concatenate([hip, np.full(k, -1, dtype=hip.dtype)])
        return attitude, x_px, y_px, mag, hip

    @staticmethod
    def _merge_groups(x_px, y_px, v_mag, hip, labels):
        groups, inverse = np.unique(labels, return_inverse=True)
        flux = 10.0 ** (-0.4 * v_mag)
        total = np.bincount(inverse, weights=flux)
        x_out = np.bincount(inverse, weights=flux * x_px) / total
        y_out = np.bincount(inverse, weights=flux * y_px) / total
        mag_out = -2.5 * np.log10(total)
        # truth (and noise draws): the brightest member of each group
        order = np.lexsort((v_mag, inverse))
        first = np.ones(order.size, dtype=bool)
        first[1:] = inverse[order][1:] != inverse[order][:-1]
        rep = order[first]
        return x_out, y_out, mag_out, hip[rep], rep

    def _merge(self, x_px, y_px, v_mag, hip):
        """Blends merged; also returns each detection's representative (brightest) input row."""
        labels = _merge_labels(x_px, y_px, self.config.merge_radius_px)
        if np.all(labels == np.arange(labels.size)):
            return x_px, y_px, v_mag, hip, np.arange(labels.size)
        return self._merge_groups(x_px, y_px, v_mag, hip, labels)

    def draw(self, trial: int):
        """One trial: ``(attitude, x_px, y_px, mag, truth_hip, n_redraws)``, detections shuffled."""
        att_rng = np.random.default_rng([self.seed, int(trial), 0])
        rng = np.random.default_rng([self.seed, int(trial), 1])
        draws = sky.trial_draws(self.config, self.seed, trial)
        for redraws in range(MAX_REDRAWS):
            attitude, x_px, y_px, mag, hip = self._draw_once(att_rng, rng, draws)
            if int(np.count_nonzero(hip >= 0)) >= self.config.min_stars:
                order = rng.permutation(hip.size)
                return attitude, x_px[order], y_px[order], mag[order], hip[order].astype(np.int64), redraws
        raise ConfigError(f"no attitude in {MAX_REDRAWS} draws had {self.config.min_stars} detectable stars; "
                          f"lower min_stars or raise mag_limit")

    def observation(self, trial: int) -> Observation:
        """Trial ``trial`` as an :class:`Observation` (with truth)."""
        _, x_px, y_px, mag, hip, _ = self.draw(trial)
        return Observation(x_px, y_px, mag, self.assumed, hip)

    def generate(self, n_trials: int, start: int = 0) -> TrialSet:
        """Trials ``start .. start + n_trials - 1`` as a :class:`TrialSet`.

        Its ``warmup`` image is trial 2**62, outside every scored range.
        """
        if n_trials < 0:
            raise ConfigError(f"n_trials must be >= 0, got {n_trials}")
        parts = [self.draw(t) for t in range(start, start + n_trials)]
        counts = np.array([p[4].size for p in parts], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

        def cat(k, dtype):
            return np.concatenate([p[k] for p in parts]).astype(dtype) if parts else np.zeros(0, dtype)

        return TrialSet(
            trial=np.arange(start, start + n_trials, dtype=np.int64), offsets=offsets,
            x_px=cat(1, np.float64), y_px=cat(2, np.float64), mag=cat(3, np.float64),
            truth_hip=cat(4, np.int64),
            attitude=np.array([p[0] for p in parts]).reshape(n_trials, 3, 3),
            n_redraws=np.array([p[5] for p in parts], dtype=np.int64),
            camera=self.assumed, warmup=self.observation(WARMUP_TRIAL),
            true_camera=None if self.assumed is self.camera else self.camera)
