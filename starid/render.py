"""Star images from pixels: a simulated trial rendered to a 16-bit image, and back to detections.

The simulator (:mod:`starid.simulate`) hands the algorithms ideal centroids plus Gaussian noise.
This module renders the same trial -- the same attitude, from ``(seed, trial)`` -- as a sensor
would record it, so that centroid error, lost faint stars, blends and false detections come
from the pixels instead of from a noise model:

1. every star of the simulator's sky (catalog and ``sky_mag_limit``) whose PSF reaches the
   sensor is projected with the camera (:mod:`starid.camera` conventions);
2. its signal is ``exposure_s * 10 ** (-0.4 (V - zero_point_mag))`` electrons, spread by a
   Gaussian PSF of ``psf_sigma_px`` integrated over each pixel (error functions; pixel ``j``
   covers ``[j, j + 1)``), added as vectorised stamps of +-5 sigma;
3. a flat sky of ``sky_e_per_px`` electrons, Poisson shot noise on signal + sky, Gaussian read
   noise ``read_noise_e``, saturation at ``full_well_e``, optional hot pixels (pixels that no
   star reaches draw sky shot noise + read noise as one Gaussian when the sky has at least
   ``GAUSSIAN_SKY_E`` = 20 electrons: the Poisson distribution's normal limit, 5x faster);
4. ``ADU = bias_adu + electrons / gain_e_per_adu``, rounded and clipped to ``[0, 2**bits - 1]``.

Every draw comes from ``numpy.random.default_rng([seed, trial, 2])`` (the simulator uses
streams 0 and 1), so the same ``(seed, trial)`` gives the same image.

Defaults (:class:`RenderConfig`) follow Zhou & Ye's Table 4 sensor: ``psf_sigma_px = 2`` (their
"point spread function 2 pixels", read as the Gaussian sigma), and a zero point chosen so
that the render -> extract chain detects half of the V = 6.0 stars (their "sensitivity of star
magnitude 6.0 Mv"); docs/images.md has the measured detection curve.

:func:`observation_from_image` renders a trial, extracts its centroids
(:func:`starid.extract.extract`) and matches each detection to the brightest true star within
``match_radius_px`` (2 px; wider at the sensor's edges): the result is an :class:`~starid.observation.Observation` with
truth, ready for the harness. :func:`image_trials` does it for a range of trials and returns a
:class:`~starid.observation.TrialSet` plus per-trial image statistics (detection rate, rms
centroid error, false detections), the hook for an ``--pipeline image`` option of the engine.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import ndtr

from . import sky
from .camera import Camera
from .errors import ConfigError
from .observation import Observation, TrialSet
from .params import check_number, check_whole
from .simulate import WARMUP_TRIAL, Simulator

#: Half-width of a star's stamp in PSF sigmas (beyond it a V = -1.5 star adds < 1 e per pixel).
STAMP_SIGMAS = 5.0
#: The per-trial random stream of the render (the simulator uses 0 and 1).
RENDER_STREAM = 2
#: From this sky level (e per pixel) on, sky-only pixels draw their shot noise in the Gaussian limit.
GAUSSIAN_SKY_E = 20.0


@dataclass(frozen=True)
class RenderConfig:
    """Sensor and exposure parameters of a rendered image (units in the names).

    Attributes
    ----------
    psf_sigma_px : Gaussian PSF sigma in pixels (Zhou & Ye Table 4: 2 px).
    zero_point_mag : magnitude that gives 1 electron per second.
    exposure_s : exposure time in seconds.
    sky_e_per_px : sky background in electrons per pixel (per exposure).
    read_noise_e : Gaussian read noise sigma in electrons per pixel.
    gain_e_per_adu : electrons per ADU.
    bias_adu : offset added to every pixel (keeps negative noise above 0).
    full_well_e : a pixel saturates at this many electrons.
    bits : ADC depth: 16 (uint16) or 8 (uint8) -- the ADC also clips at ``2**bits - 1``.
    hot_pixels : number of hot pixels (uniformly placed) per image.
    hot_pixel_e : electrons a hot pixel adds.
    """

    psf_sigma_px: float = 2.0
    zero_point_mag: float = 16.9
    exposure_s: float = 0.1
    sky_e_per_px: float = 100.0
    read_noise_e: float = 10.0
    gain_e_per_adu: float = 1.0
    bias_adu: float = 200.0
    full_well_e: float = 60000.0
    bits: int = 16
    hot_pixels: int = 0
    hot_pixel_e: float = 20000.0

    def __post_init__(self):
        check_number("psf_sigma_px", self.psf_sigma_px, lo=0.1, hi=50)
        check_number("zero_point_mag", self.zero_point_mag, lo=-50, hi=50)
        for name in ("exposure_s", "gain_e_per_adu", "full_well_e"):
            check_number(name, getattr(self, name), lo=0, lo_open=True)
        for name in ("sky_e_per_px", "read_noise_e", "bias_adu", "hot_pixel_e"):
            check_number(name, getattr(self, name), lo=0)
        if self.bits not in (8, 16) or isinstance(self.bits, bool):
            raise ConfigError(f"bits must be 8 or 16, got {self.bits!r}")
        check_whole("hot_pixels", self.hot_pixels, 0, 1_000_000)

    @property
    def max_adu(self) -> int:
        return 2 ** self.bits - 1

    @property
    def adu_zero_point_mag(self) -> float:
        """Magnitude of a source of 1 ADU in total: ``extract(..., zero_point_mag=this)`` gives V."""
        return self.zero_point_mag + 2.5 * math.log10(self.exposure_s / self.gain_e_per_adu)

    def signal_e(self, v_mag: np.ndarray) -> np.ndarray:
        """Total electrons of stars of magnitude ``v_mag``."""
        return self.exposure_s * 10.0 ** (-0.4 * (np.asarray(v_mag, dtype=np.float64) - self.zero_point_mag))

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class RenderedTrial:
    """One rendered trial.

    Attributes
    ----------
    image : uint16 (or uint8) ``(height, width)`` array, rows = y.
    attitude : float64 (3, 3) true attitude (ICRS -> camera).
    x_px, y_px, v_mag, hip : the rendered stars (true positions, catalog magnitudes and ids),
        including stars just off the sensor whose PSF reaches it.
    trial : the trial index.
    """

    image: np.ndarray
    attitude: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    v_mag: np.ndarray
    hip: np.ndarray
    trial: int
    n_redraws: int = 0


@dataclass(frozen=True, eq=False)
class ImageTrial:
    """A rendered trial turned into detections with truth.

    Attributes
    ----------
    observation : the detections (extracted centroids and magnitudes) with ``truth_hip``:
        the nearest true star within ``match_radius_px``, else -1 (a false detection).
    flux : float64 (n,) extracted flux of each detection (ADU).
    rendered : the :class:`RenderedTrial`.
    stats : detection statistics, see :func:`match_stats`.
    """

    observation: Observation
    flux: np.ndarray
    rendered: RenderedTrial
    stats: dict = field(default_factory=dict)


class Renderer:
    """Renders the trials of ``simulator`` (same seed, camera, sky and attitudes) with ``config``."""

    def __init__(self, simulator: Simulator, config: RenderConfig | None = None):
        self.simulator = simulator
        self.config = config or RenderConfig()
        cat = simulator.catalog
        sky_limit = simulator.config.sky_mag_limit
        unit, v_mag, hip, body = sky.world_stars(sky.star_units(cat, simulator.config), cat.v_mag, cat.hip,
                                                 simulator.config)
        keep = np.ones(len(hip), dtype=bool) if sky_limit is None else (v_mag <= sky_limit) | body
        self._unit_icrs = unit[keep]
        self._v_mag = v_mag[keep]
        self._hip = hip[keep]
        self._tree = cKDTree(self._unit_icrs)
        cam = simulator.camera
        self._margin_px = STAMP_SIGMAS * self.config.psf_sigma_px + 2.0
        half = cam.reach_rad(self._margin_px)     # the true camera, its lens included
        if half >= math.pi / 2:
            raise ConfigError("the camera's field of view is too wide to render (>= 180 deg)")
        self._chord = 2.0 * math.sin(half / 2.0)

    @property
    def camera(self) -> Camera:
        return self.simulator.camera

    def stars(self, attitude: np.ndarray, draws: dict | None = None, with_v_cam: bool = False):
        """The stars whose PSF reaches the sensor: ``(x_px, y_px, v_mag, hip)``, catalog order
        (aberrated with the trial's ``draws`` when the simulator's ``velocity_kms`` > 0;
        ``with_v_cam`` adds their camera-frame vectors)."""
        cam = self.camera
        idx = np.sort(np.asarray(self._tree.query_ball_point(attitude[2], self._chord), dtype=np.int64))
        unit = self._unit_icrs[idx]
        if draws is not None:
            unit = sky.apparent(unit, self.simulator.config, draws)
        v_cam = unit @ attitude.T
        front = v_cam[:, 2] > 1e-9
        idx, v_cam = idx[front], v_cam[front]
        x, y = cam.project(v_cam)
        m = self._margin_px
        near = (x >= -m) & (x < cam.width_px + m) & (y >= -m) & (y < cam.height_px + m)
        idx = idx[near]
        if with_v_cam:
            return x[near], y[near], self._v_mag[idx], self._hip[idx].astype(np.int64), v_cam[near]
        return x[near], y[near], self._v_mag[idx], self._hip[idx].astype(np.int64)

    def render(self, trial: int) -> RenderedTrial:
        """Trial ``trial`` (the simulator's attitude for ``(seed, trial)``) as an image."""
        draw = self.simulator.draw(trial)
        attitude = draw[0]
        scfg = self.simulator.config
        draws = sky.trial_draws(scfg, self.simulator.seed, trial)
        x, y, v_mag, hip, v_cam = self.stars(attitude, draws, with_v_cam=True)
        rng = np.random.default_rng([self.simulator.seed, int(trial), RENDER_STREAM])
        xs, ys, signal = x, y, self.config.signal_e(v_mag)
        if sky.smear_on(scfg):   # the PSF summed along each star's streak; truth at the streak's centre
            xs, ys, signal, x, y = sky.streak_stars(x, y, signal, v_cam, self.camera, scfg, draws["smear_axis"],
                                                    self.config.psf_sigma_px, self.config.exposure_s)
        image = render_image(xs, ys, signal, self.camera.width_px, self.camera.height_px, self.config, rng)
        return RenderedTrial(image, attitude, x, y, v_mag, hip, int(trial), int(draw[5]))


def _pixel_fractions(center_px: np.ndarray, lo: np.ndarray, width: int, sigma_px: float) -> np.ndarray:
    """Fraction of a unit 1-D Gaussian at ``center_px`` falling in pixels ``lo .. lo + width - 1``."""
    edges = lo[:, None] + np.arange(width + 1)[None, :]
    cdf = ndtr((edges - center_px[:, None]) / sigma_px)
    return np.diff(cdf, axis=1)


def render_image(x_px: np.ndarray, y_px: np.ndarray, signal_e: np.ndarray, width_px: int, height_px: int,
                 config: RenderConfig, rng: np.random.Generator) -> np.ndarray:
    """Stars at ``(x_px, y_px)`` with ``signal_e`` electrons each, on a noisy sensor (see the module).

    Vectorised: each star is a separable ``(2r + 1)^2`` stamp of pixel-integrated Gaussians,
    accumulated with one ``bincount``.
    """
    sigma = config.psf_sigma_px
    r = int(math.ceil(STAMP_SIGMAS * sigma))
    w = 2 * r + 1
    x_px = np.asarray(x_px, dtype=np.float64)
    y_px = np.asarray(y_px, dtype=np.float64)
    signal_e = np.asarray(signal_e, dtype=np.float64)
    n_px = height_px * width_px
    sky = config.sky_e_per_px
    if sky >= GAUSSIAN_SKY_E:
        # sky-only pixels: Poisson(sky) + read noise in its Gaussian limit, one draw per pixel
        electrons = rng.standard_normal(n_px)
        electrons *= math.sqrt(sky + config.read_noise_e ** 2)
        electrons += sky
    else:
        electrons = rng.poisson(sky, n_px).astype(np.float64)
        if config.read_noise_e > 0:
            electrons += rng.normal(0.0, config.read_noise_e, n_px)
    if x_px.size:
        x0 = np.floor(x_px).astype(np.int64) - r
        y0 = np.floor(y_px).astype(np.int64) - r
        fx = _pixel_fractions(x_px, x0, w, sigma)           # (n, w)
        fy = _pixel_fractions(y_px, y0, w, sigma)
        stamps = signal_e[:, None, None] * fy[:, :, None] * fx[:, None, :]
        ix = x0[:, None, None] + np.arange(w)[None, None, :]
        iy = y0[:, None, None] + np.arange(w)[None, :, None]
        ix, iy = np.broadcast_to(ix, stamps.shape), np.broadcast_to(iy, stamps.shape)
        inside = (ix >= 0) & (ix < width_px) & (iy >= 0) & (iy < height_px)
        flat = iy[inside] * width_px + ix[inside]
        star = np.bincount(flat, weights=stamps[inside], minlength=n_px)
        # pixels a star reaches: exact Poisson shot noise of star + sky, plus read noise
        lit = np.flatnonzero(star)
        electrons[lit] = rng.poisson(star[lit] + sky)
        if config.read_noise_e > 0:
            electrons[lit] += rng.normal(0.0, config.read_noise_e, lit.size)
    if config.hot_pixels:
        hot = rng.integers(0, electrons.size, config.hot_pixels)
        electrons[hot] += config.hot_pixel_e
    np.minimum(electrons, config.full_well_e, out=electrons)
    adu = np.rint(config.bias_adu + electrons / config.gain_e_per_adu)
    np.clip(adu, 0, config.max_adu, out=adu)
    return adu.astype(np.uint16 if config.bits == 16 else np.uint8).reshape(height_px, width_px)


def match_truth(x_px, y_px, true_x_px, true_y_px, true_hip, radius_px=2.0, true_mag=None, flux=None):
    """Each detection's true star: the brightest true star within ``radius_px``, one detection per star.

    ``radius_px`` is a number or one radius per detection. Detections are taken brightest
    first (by ``flux``; input order without it), each gets the brightest true star within its
    radius that no earlier detection took (by ``true_mag``; the nearest without it) -- the
    simulator's rule for blends, whose truth is the brighter star. A detection with no free
    star within its radius gets -1 (false). Returns ``(truth_hip, matched_row)``, the row of the
    true star or -1.
    """
    n = len(x_px)
    truth = np.full(n, -1, dtype=np.int64)
    row = np.full(n, -1, dtype=np.int64)
    if n == 0 or len(true_x_px) == 0:
        return truth, row
    radius = np.broadcast_to(np.asarray(radius_px, dtype=np.float64), (n,))
    tree = cKDTree(np.column_stack([true_x_px, true_y_px]))
    near = tree.query_ball_point(np.column_stack([x_px, y_px]), radius)
    taken = np.zeros(len(true_x_px), dtype=bool)
    order = np.arange(n) if flux is None else np.argsort(-np.asarray(flux), kind="stable")
    tx, ty = np.asarray(true_x_px), np.asarray(true_y_px)
    for d in order:
        cand = np.asarray([s for s in near[d] if not taken[s]], dtype=np.int64)
        if cand.size == 0:
            continue
        dist = np.hypot(tx[cand] - x_px[d], ty[cand] - y_px[d])
        key = (dist,) if true_mag is None else (dist, np.asarray(true_mag)[cand])
        s = cand[np.lexsort(key)[0]]
        row[d] = s
        taken[s] = True
    truth[row >= 0] = np.asarray(true_hip, dtype=np.int64)[row[row >= 0]]
    return truth, row


def match_radius(x_px, y_px, camera: Camera, radius_px: float, psf_sigma_px: float) -> np.ndarray:
    """``radius_px``, widened by ``3 psf_sigma_px`` for detections within that of the sensor's edge
    (the edge cuts the PSF and pulls the centroid inwards by up to a few pixels)."""
    edge = 3.0 * psf_sigma_px
    dist = np.minimum(np.minimum(x_px, camera.width_px - x_px), np.minimum(y_px, camera.height_px - y_px))
    return np.where(dist < edge, radius_px + edge, radius_px)


def match_stats(rendered: RenderedTrial, x_px, y_px, row, camera: Camera, mag_limit: float) -> dict:
    """Detection statistics of one image.

    ``n_detectable``: true stars on the sensor with V <= ``mag_limit``; ``n_detected``: those
    matched by a detection; ``n_false``: detections matched to no star; ``sq_err_px2_sum`` and
    ``n_matched``: squared centroid errors of all matched detections (for an rms).
    """
    on = camera.in_image(rendered.x_px, rendered.y_px) & (rendered.v_mag <= mag_limit)
    matched = row >= 0
    hit = np.zeros(rendered.x_px.size, dtype=bool)
    hit[row[matched]] = True
    dx = np.asarray(x_px)[matched] - rendered.x_px[row[matched]]
    dy = np.asarray(y_px)[matched] - rendered.y_px[row[matched]]
    return {"n_detectable": int(on.sum()), "n_detected": int((hit & on).sum()),
            "n_detections": int(len(row)), "n_false": int((~matched).sum()), "n_matched": int(matched.sum()),
            "sq_err_px2_sum": float(np.sum(dx * dx + dy * dy))}


def observation_from_image(simulator: Simulator, trial: int, config: RenderConfig | None = None, *,
                           renderer: Renderer | None = None, match_radius_px: float = 2.0,
                           **extract_options) -> ImageTrial:
    """Render trial ``trial`` of ``simulator``, extract its centroids and match them to the truth.

    Truth: the brightest true star within ``match_radius_px`` of each detection (the
    simulator's rule for blends), the radius widened near the sensor's edges
    (:func:`match_radius`); see :func:`match_truth`.
    The detections' magnitudes use the render's own zero point (a calibrated sensor);
    ``extract_options`` go to :func:`starid.extract.extract` (``psf_sigma_px`` defaults to the
    render's). Statistics count stars to the simulator's ``mag_limit`` as detectable.
    """
    from .extract import extract

    renderer = renderer or Renderer(simulator, config)
    cfg = renderer.config
    rendered = renderer.render(trial)
    options = {"psf_sigma_px": cfg.psf_sigma_px, "zero_point_mag": cfg.adu_zero_point_mag, **extract_options}
    x, y, mag, flux = extract(rendered.image, **options)
    camera = renderer.camera
    radius = match_radius(x, y, camera, match_radius_px, cfg.psf_sigma_px)
    truth, row = match_truth(x, y, rendered.x_px, rendered.y_px, rendered.hip, radius, rendered.v_mag, flux)
    obs = Observation(x, y, mag, simulator.assumed, truth)    # what the tracker believes the camera is
    stats = match_stats(rendered, x, y, row, camera, simulator.config.mag_limit)
    return ImageTrial(obs, flux, rendered, stats)


def image_trials(simulator: Simulator, n_trials: int, start: int = 0, config: RenderConfig | None = None,
                 **extract_options):
    """Trials ``start .. start + n_trials - 1`` through render -> extract, as the harness takes them.

    Returns ``(trials, stats)``: a :class:`~starid.observation.TrialSet` of the extracted
    detections (truth matched, attitudes the simulator's; its warm-up image rendered too) and a
    pandas DataFrame with one row per trial (``trial`` and the :func:`match_stats` columns).
    """
    import pandas as pd

    if n_trials < 0:
        raise ConfigError(f"n_trials must be >= 0, got {n_trials}")
    renderer = Renderer(simulator, config)
    items = [observation_from_image(simulator, t, renderer=renderer, **extract_options)
             for t in range(start, start + n_trials)]
    obs = [it.observation for it in items]
    counts = np.array([len(o) for o in obs], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    def cat(name, dtype):
        return np.concatenate([getattr(o, name) for o in obs]).astype(dtype) if obs else np.zeros(0, dtype)

    warm = observation_from_image(simulator, WARMUP_TRIAL, renderer=renderer, **extract_options).observation
    trials = TrialSet(trial=np.arange(start, start + n_trials, dtype=np.int64), offsets=offsets,
                      x_px=cat("x_px", np.float64), y_px=cat("y_px", np.float64), mag=cat("mag", np.float64),
                      truth_hip=cat("truth_hip", np.int64),
                      attitude=np.array([it.rendered.attitude for it in items]).reshape(n_trials, 3, 3),
                      n_redraws=np.array([it.rendered.n_redraws for it in items], dtype=np.int64),
                      camera=simulator.assumed, warmup=warm,
                      true_camera=None if simulator.assumed is simulator.camera else simulator.camera)
    stats = pd.DataFrame([{"trial": it.rendered.trial, **it.stats} for it in items])
    return trials, stats


def summarize_stats(stats) -> dict:
    """Detection rate, false detections per image and rms centroid error (px) over many images."""
    n_det = float(stats["n_detectable"].sum())
    n_match = float(stats["n_matched"].sum())
    return {"images": int(len(stats)),
            "detection_rate": float(stats["n_detected"].sum()) / n_det if n_det else float("nan"),
            "false_per_image": float(stats["n_false"].mean()) if len(stats) else float("nan"),
            "detections_per_image": float(stats["n_detections"].mean()) if len(stats) else float("nan"),
            "rms_centroid_err_px": (math.sqrt(float(stats["sq_err_px2_sum"].sum()) / n_match) if n_match
                                    else float("nan"))}


__all__ = ["ImageTrial", "RenderConfig", "RenderedTrial", "Renderer", "image_trials", "match_stats", "match_radius",
           "match_truth",
           "observation_from_image", "render_image", "summarize_stats"]
