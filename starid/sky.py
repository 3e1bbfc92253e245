"""The sky and the spacecraft: world effects the simulator can add (every one off by default).

* **Motion smear** (``rate_deg_s``, ``exposure_s``, ``rate_axis``): the camera turns at
  ``rate_deg_s`` about an axis (camera frame; drawn uniformly on the sphere per trial from
  ``default_rng([seed, trial, 3])`` unless ``rate_axis`` gives it) during the exposure, so each
  star draws a streak (:mod:`starid.kernels.smear`, LOST's motion model). Centroid mode: the
  star's centroid is the streak's light-weighted centre and its centroid noise is stretched
  along the streak by ``sqrt(1 + L^2 / (12 s^2))`` (:func:`starid.kernels.smear.smear_noise`,
  ``s`` = :data:`SMEAR_PSF_SIGMA_PX`). Image mode: the PSF is summed over sub-exposures along
  the streak (:func:`streak_stars`), so the peak falls and faint stars drop below threshold.
* **Planets** (``planets``, ``moon``, ``epoch``): Mercury..Neptune (and the Moon) at their
  geocentric apparent places (astropy's built-in ephemeris, nothing downloaded) with magnitudes
  from :func:`planet_v_mag`; they carry no HIP (truth id -1, like a false star).
* **Planets in view** (``planets_in_view`` = k, with ``epoch``): k of the five naked-eye planets
  (:data:`NAKED_EYE`, a random choice per trial, nested: the k + 1 field holds the k field's
  planets and one more) are imaged in every field at their apparent magnitudes at the epoch and
  at positions drawn uniformly on the sensor (stream 3), so "planets in view" is a controlled
  axis (:func:`forced_planets`); the real planets are seldom within one field of each other.
* **Near the ecliptic** (``near_ecliptic``): boresights drawn uniformly in the band
  ``|ecliptic latitude| <= NEAR_ECLIPTIC_DEG`` (the roll and the draw stream unchanged).
* **Proper motion** (``epoch``): the stars imaged at their places at the epoch, propagated from
  J2000.0 with the embedded Hipparcos proper motions (:func:`star_units`); the algorithms'
  catalog stays at J2000.0.
* **Stellar aberration** (``velocity_kms``): every star displaced by the observer's velocity
  (special-relativistic formula, :func:`aberrate`), direction uniform per trial from stream 3;
  the algorithms' catalog is not corrected.

Exposure: ``SimConfig.exposure_s = None`` means the camera's (``getattr(camera, "exposure_s",
None)``), else :data:`DEFAULT_EXPOSURE_S`.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta
from functools import lru_cache

import numpy as np

from .errors import ConfigError
from .kernels.smear import rotate_all, smear_noise, streak_px, streak_samples_px

#: Exposure (s) when neither the settings nor the camera give one (RenderConfig's default).
DEFAULT_EXPOSURE_S = 0.1
#: The PSF sigma (px) the centroid-mode smear noise model assumes (Zhou & Ye Table 4: 2 px).
SMEAR_PSF_SIGMA_PX = 2.0
#: The per-trial random stream of the world effects (simulator 0 and 1, render 2).
SKY_STREAM = 3
#: Speed of light (km/s).
C_KMS = 299_792.458
#: Half-width (deg) in ecliptic latitude of the band ``near_ecliptic`` draws boresights in.
NEAR_ECLIPTIC_DEG = 5.0
#: Mean obliquity of the ecliptic at J2000 (IAU 2006), deg.
OBLIQUITY_DEG = 23.439279
#: Sub-exposure spacing (in PSF sigmas) of the image-mode streak.
STREAK_STEP_SIGMAS = 0.5
#: The planets, in order, and the truth id they get (no HIP).
PLANETS = ("mercury", "venus", "mars", "jupiter", "saturn", "uranus", "neptune")
PLANET_ID = -1
#: The planets ``planets_in_view`` draws from: the five seen with the naked eye (V < 6 at any epoch).
NAKED_EYE = ("mercury", "venus", "mars", "jupiter", "saturn")
#: V(1, 0) and phase coefficients (per deg, deg^2, deg^3) of the planets' magnitudes: Meeus,
#: Astronomical Algorithms (2nd ed. 1998), ch. 41, the Astronomical Almanac (1984) formulae;
#: Saturn without its rings' term (up to ~1 mag too faint at the rings' widest).
_MAG_COEFFS = {
    "mercury": (-0.42, 0.0380, -0.000273, 0.000002),
    "venus": (-4.40, 0.0009, 0.000239, -0.00000065),
    "mars": (-1.52, 0.016, 0.0, 0.0),
    "jupiter": (-9.40, 0.005, 0.0, 0.0),
    "saturn": (-8.88, 0.0, 0.0, 0.0),
    "uranus": (-7.19, 0.0, 0.0, 0.0),
    "neptune": (-6.87, 0.0, 0.0, 0.0),
}


def exposure_s(config, camera, default_s: float = DEFAULT_EXPOSURE_S) -> float:
    """The exposure (s): the settings', else the camera's, else ``default_s`` (the render's
    exposure in the image pipeline, :data:`DEFAULT_EXPOSURE_S` in centroid mode)."""
    if getattr(config, "exposure_s", None) is not None:
        return float(config.exposure_s)
    cam = getattr(camera, "exposure_s", None)
    return float(cam) if cam is not None else float(default_s)


def parse_epoch(epoch) -> datetime | None:
    """``epoch`` (ISO UTC text, or a year as a number, e.g. 2030.0 = J2030.0) as a UTC datetime."""
    if epoch is None:
        return None
    if isinstance(epoch, (int, float)) and not isinstance(epoch, bool):
        if not 1000 <= epoch <= 3000:
            raise ConfigError(f"epoch as a year must lie in 1000..3000, got {epoch!r}")
        # Julian epoch: J2000.0 = 2000-01-01T12:00 TT, 365.25 days a year (UTC ~ TT here, < 70 s)
        return datetime(2000, 1, 1, 12, tzinfo=UTC) + timedelta(days=(epoch - 2000.0) * 365.25)
    try:
        text = str(epoch).strip().replace("Z", "+00:00")
        when = datetime.fromisoformat(text)
    except ValueError:
        raise ConfigError(f"epoch must be ISO UTC (e.g. 2030-01-01T00:00:00) or a year, got {epoch!r}") from None
    return when.replace(tzinfo=UTC) if when.tzinfo is None else when.astimezone(UTC)


def check_config(config) -> None:
    """The sky settings of a :class:`~starid.simulate.SimConfig`, checked (called by it)."""
    from .params import check_number

    check_number("rate_deg_s", config.rate_deg_s, lo=0, hi=180)
    if config.exposure_s is not None:
        check_number("exposure_s", config.exposure_s, lo=0, hi=60)
    check_number("velocity_kms", config.velocity_kms, lo=0, hi=10_000)
    if config.rate_axis is not None:
        rate_axis(config)
    if (config.planets or config.moon) and config.epoch is None:
        raise ConfigError("planets and moon need an epoch (ISO UTC, e.g. --epoch 2030-01-01T00:00:00)")
    k = config.planets_in_view
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= len(NAKED_EYE):
        raise ConfigError(f"planets_in_view must be a whole number from 0 to {len(NAKED_EYE)}, got {k!r}")
    if k and config.epoch is None:
        raise ConfigError("planets_in_view needs an epoch (the planets' magnitudes), e.g. epoch = 2030-01-01T00:00:00")
    if k and config.pipeline != "centroids":
        raise ConfigError("planets_in_view is a centroid-mode setting; use planets = true with --pipeline image")
    parse_epoch(config.epoch)


def rate_axis(config) -> np.ndarray | None:
    """The given rotation axis (camera frame), unit, or None (drawn per trial)."""
    if config.rate_axis is None:
        return None
    try:
        v = np.array([float(t) for t in str(config.rate_axis).replace(";", ",").split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.size != 3 or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise ConfigError(f"rate_axis must be three numbers 'X,Y,Z' (camera frame), not all 0, "
                          f"got {config.rate_axis!r}")
    return v / np.linalg.norm(v)


def _unit_sphere(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def trial_draws(config, seed: int, trial: int) -> dict:
    """The world effects' per-trial draws (stream 3): smear axis and velocity direction."""
    rng = np.random.default_rng([int(seed), int(trial), SKY_STREAM])
    smear_axis = _unit_sphere(rng)
    apex = _unit_sphere(rng)
    given = rate_axis(config)
    out = {"smear_axis": given if given is not None else smear_axis, "apex": apex}
    if getattr(config, "planets_in_view", 0):   # after the draws above, which stay the same
        n = len(NAKED_EYE)
        out["planet_order"] = rng.permutation(n)
        out["planet_uv"] = rng.uniform(0.0, 1.0, (2, n))
        out["planet_z"] = rng.normal(0.0, 1.0, (3, n))
    return out


def smear_on(config) -> bool:
    return config.rate_deg_s > 0


def sweep_rad(config, camera, default_s: float = DEFAULT_EXPOSURE_S) -> float:
    """The angle the camera turns during the exposure (rad)."""
    return math.radians(config.rate_deg_s) * exposure_s(config, camera, default_s)


def streak_offsets_px(v_cam, axis, sweep: float, camera):
    """``(centre_dx, centre_dy, length_dx, length_dy)`` (px) of each star's streak on ``camera``'s
    sensor (:func:`starid.kernels.smear.streak_px`; through the lens when it distorts: the
    directions at start, middle and end of the exposure projected with ``camera.project``)."""
    v_cam = np.ascontiguousarray(v_cam, dtype=np.float64).reshape(-1, 3)
    axis = np.ascontiguousarray(axis, dtype=np.float64)
    if not getattr(camera, "distorted", False):
        return streak_px(v_cam, axis, sweep, camera.f_px, camera.cx_px, camera.cy_px)
    x0, y0 = camera.project(v_cam)
    xa, ya = camera.project(rotate_all(v_cam, axis, 0.5 * sweep))     # t = -T/2
    xb, yb = camera.project(rotate_all(v_cam, axis, -0.5 * sweep))    # t = +T/2
    return (xa + xb - 2.0 * x0) / 6.0, (ya + yb - 2.0 * y0) / 6.0, xb - xa, yb - ya


def streak_sample_offsets_px(v_cam, axis, sweep: float, n_samples: int, camera):
    """Offsets ``(n, n_samples)`` of each star at the midpoint-rule times of the exposure
    (:func:`starid.kernels.smear.streak_samples_px`; through the lens when it distorts)."""
    v_cam = np.ascontiguousarray(v_cam, dtype=np.float64).reshape(-1, 3)
    axis = np.ascontiguousarray(axis, dtype=np.float64)
    if not getattr(camera, "distorted", False):
        return streak_samples_px(v_cam, axis, sweep, n_samples, camera.f_px, camera.cx_px, camera.cy_px)
    x0, y0 = camera.project(v_cam)
    dx, dy = np.empty((len(v_cam), n_samples)), np.empty((len(v_cam), n_samples))
    for k in range(n_samples):   # one vectorised projection per sub-exposure
        xk, yk = camera.project(rotate_all(v_cam, axis, -sweep * ((k + 0.5) / n_samples - 0.5)))
        dx[:, k], dy[:, k] = xk - x0, yk - y0
    return dx, dy


def smear_centroids(v_cam, camera, config, axis):
    """Centroid mode: ``(centre_dx, centre_dy, length_dx, length_dy)`` of each star's streak (px)
    on the true ``camera``."""
    return streak_offsets_px(v_cam, axis, sweep_rad(config, camera), camera)


def smear_noise_draws(z_x, z_y, length_dx, length_dy):
    """Centroid-noise unit draws stretched along the streaks (:func:`starid.kernels.smear.smear_noise`)."""
    return smear_noise(np.ascontiguousarray(z_x), np.ascontiguousarray(z_y), np.ascontiguousarray(length_dx),
                       np.ascontiguousarray(length_dy), SMEAR_PSF_SIGMA_PX)


def streak_stars(x_px, y_px, signal_e, v_cam, camera, config, axis, psf_sigma_px,
                 default_exposure_s=DEFAULT_EXPOSURE_S):
    """Image mode: each star split into sub-exposures along its streak.

    Returns ``(x_sub, y_sub, signal_sub, x_centre, y_centre)``: ``K`` points per star at the
    midpoint-rule times of the exposure, each with ``signal / K`` (``K`` so that neighbouring
    points are at most ``STREAK_STEP_SIGMAS`` PSF sigmas apart: the sum of Gaussians then equals
    the PSF integrated along the streak -- LOST's analytic erf form -- to well under 1 %), and
    each star's light-weighted centre (the truth the detections are matched to).
    """
    v_cam = np.ascontiguousarray(v_cam, dtype=np.float64)
    axis = np.ascontiguousarray(axis, dtype=np.float64)
    sweep = sweep_rad(config, camera, default_exposure_s)
    _, _, ldx, ldy = streak_offsets_px(v_cam, axis, sweep, camera)
    longest = float(np.max(np.hypot(ldx, ldy))) if ldx.size else 0.0
    k = max(1, int(math.ceil(longest / (STREAK_STEP_SIGMAS * psf_sigma_px))) + 1)
    dx, dy = streak_sample_offsets_px(v_cam, axis, sweep, k, camera)
    xs = (np.asarray(x_px)[:, None] + dx).ravel()
    ys = (np.asarray(y_px)[:, None] + dy).ravel()
    sig = np.repeat(np.asarray(signal_e, dtype=np.float64) / k, k)
    return xs, ys, sig, np.asarray(x_px) + dx.mean(axis=1), np.asarray(y_px) + dy.mean(axis=1)


# --- aberration --------------------------------------------------------------------------------

def apparent(unit, config, draws) -> np.ndarray:
    """``unit`` (n, 3) as the observer sees it: aberrated by :func:`aberrate` towards the trial's
    ``draws["apex"]`` when ``config.velocity_kms`` > 0, else ``unit`` itself."""
    if config.velocity_kms > 0:
        return aberrate(unit, config.velocity_kms, draws["apex"])
    return unit


def aberrate(unit, velocity_kms: float, apex) -> np.ndarray:
    """Apparent directions of ``unit`` (n, 3) for an observer moving at ``velocity_kms`` towards ``apex``.

    Special relativity (e.g. Kaplan et al. 1989, AJ 97, 1197, eq. 3.5 in vector form):
    ``u' = (u / g + b + (u.b) b / (1 + 1/g)) / (1 + u.b)``, ``b = v/c apex``, ``g = 1/sqrt(1 - b^2)``;
    a star at 90 deg from the apex moves by ``asin(v/c)`` towards it (20.64 arcsec at 30 km/s).
    """
    u = np.asarray(unit, dtype=np.float64)
    beta = velocity_kms / C_KMS
    b = beta * np.asarray(apex, dtype=np.float64)
    g = 1.0 / math.sqrt(1.0 - beta * beta)
    ub = u @ b
    out = (u / g + b[None, :] + (ub / (1.0 + 1.0 / g))[:, None] * b[None, :]) / (1.0 + ub)[:, None]
    return out / np.linalg.norm(out, axis=1)[:, None]


# --- ecliptic band -----------------------------------------------------------------------------

def ecliptic_to_icrs(lon_rad, lat_rad) -> np.ndarray:
    """Unit vectors (n, 3) of ecliptic (J2000 mean) longitude/latitude in ICRS axes."""
    lon, lat = np.atleast_1d(lon_rad), np.atleast_1d(lat_rad)
    e = math.radians(OBLIQUITY_DEG)
    x = np.cos(lat) * np.cos(lon)
    y_ecl = np.cos(lat) * np.sin(lon)
    z_ecl = np.sin(lat)
    return np.column_stack([x, y_ecl * math.cos(e) - z_ecl * math.sin(e), y_ecl * math.sin(e) + z_ecl * math.cos(e)])


def near_ecliptic_attitude(attitude: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``attitude`` turned (minimal rotation) so its boresight lies uniformly in the ecliptic band."""
    lon = rng.uniform(0.0, 2 * math.pi)
    s = math.sin(math.radians(NEAR_ECLIPTIC_DEG))
    lat = math.asin(rng.uniform(-s, s))
    b = ecliptic_to_icrs(lon, lat)[0]
    a = attitude[2]
    axis = np.cross(a, b)
    sin_t, cos_t = np.linalg.norm(axis), float(a @ b)
    if sin_t < 1e-15:
        return attitude if cos_t > 0 else -attitude * np.array([[1.0], [-1.0], [-1.0]])
    k = axis / sin_t
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    Q = np.eye(3) + sin_t * K + (1 - cos_t) * (K @ K)     # Q a = b
    return attitude @ Q.T


def boresight_radec_deg(attitude: np.ndarray) -> tuple[float, float]:
    """Right ascension and declination (deg) of the boresight (the attitude's third row)."""
    z = attitude[2]
    return float(np.degrees(np.arctan2(z[1], z[0])) % 360.0), float(np.degrees(np.arcsin(np.clip(z[2], -1, 1))))


# --- planets -----------------------------------------------------------------------------------

def planet_v_mag(name: str, r_au: float, delta_au: float, phase_deg: float) -> float:
    """V magnitude: ``V(1,0) + 5 log10(r delta) + a i + b i^2 + c i^3`` (see ``_MAG_COEFFS``);
    the Moon: ``0.23 + 5 log10(r delta) + 0.026 |i| + 4e-9 i^4`` (Allen's Astrophysical
    Quantities, 4th ed., 12.2; V = -12.7 at full moon)."""
    i = abs(phase_deg)
    if name == "moon":
        return 0.23 + 5 * math.log10(r_au * delta_au) + 0.026 * i + 4e-9 * i ** 4
    v0, a, b, c = _MAG_COEFFS[name]
    return v0 + 5 * math.log10(r_au * delta_au) + a * i + b * i * i + c * i ** 3


@lru_cache(maxsize=32)
def planet_places(epoch_iso: str, moon: bool = False):
    """``(names, unit_icrs (n, 3), v_mag (n,))`` of the planets (and the Moon) at ``epoch_iso``.

    Places: astropy ``get_body`` (built-in ephemeris, geocentric apparent: light time and the
    Earth's aberration included, GCRS axes = ICRS axes to < 0.1 arcsec); distances for the
    magnitudes from ``get_body_barycentric``.
    """
    try:
        from astropy.coordinates import get_body, get_body_barycentric, solar_system_ephemeris
        from astropy.time import Time
    except ImportError:  # pragma: no cover
        raise ConfigError("planets need astropy: pip install starid[images]") from None
    import warnings

    names = PLANETS + (("moon",) if moon else ())
    units, mags = [], []
    with solar_system_ephemeris.set("builtin"), warnings.catch_warnings():
        warnings.simplefilter("ignore")   # ERFA's "dubious year": UTC beyond the leap-second table
        t = Time(epoch_iso, scale="utc")
        sun = get_body_barycentric("sun", t).xyz.to_value("au")
        earth = get_body_barycentric("earth", t).xyz.to_value("au")
        for name in names:
            c = get_body(name, t)
            ra, dec = c.ra.rad, c.dec.rad
            units.append([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
            p = get_body_barycentric(name, t).xyz.to_value("au")
            r, delta = np.linalg.norm(p - sun), np.linalg.norm(p - earth)
            cos_i = float((p - sun) @ (p - earth)) / (r * delta)
            mags.append(planet_v_mag(name, float(r), float(delta), math.degrees(math.acos(np.clip(cos_i, -1, 1)))))
    return names, np.array(units), np.array(mags)


def world_stars(unit_icrs, v_mag, hip, config):
    """The sky the simulator images: the catalog stars plus, with ``planets``/``moon``, the
    bodies (truth id :data:`PLANET_ID`). Returns ``(unit_icrs, v_mag, hip, is_body)``;
    unchanged arrays (and an all-False mask) with every effect off."""
    body = np.zeros(len(hip), dtype=bool)
    if not (config.planets or config.moon):
        return unit_icrs, v_mag, hip, body
    when = parse_epoch(config.epoch).strftime("%Y-%m-%dT%H:%M:%S.%f")
    names, u, m = planet_places(when, bool(config.moon))
    if not config.planets:
        u, m = u[-1:], m[-1:]
    return (np.concatenate([unit_icrs, u]), np.concatenate([v_mag, m]),
            np.concatenate([hip, np.full(len(m), PLANET_ID, dtype=hip.dtype)]),
            np.concatenate([body, np.ones(len(m), dtype=bool)]))


@lru_cache(maxsize=8)
def naked_eye_v_mag(epoch_iso: str) -> np.ndarray:
    """V magnitudes of :data:`NAKED_EYE` at ``epoch_iso`` (:func:`planet_places`)."""
    names, _, mags = planet_places(epoch_iso)
    return np.array([mags[names.index(n)] for n in NAKED_EYE])


def forced_planets(config, camera, draws):
    """The ``planets_in_view`` planets of one trial as detections before the detection cut:
    ``(x_px, y_px, mag)``, each uniform on the sensor with the trial's centroid and magnitude
    noise (the same unit draws at every k, so the k-planet field is the (k-1)-planet field plus
    one planet). Blending with a star closer than the merge radius is not modelled."""
    k = config.planets_in_view
    if not k:
        return None
    pick = draws["planet_order"][:k]
    when = parse_epoch(config.epoch).strftime("%Y-%m-%dT%H:%M:%S.%f")
    u, v = draws["planet_uv"][:, pick]
    z = draws["planet_z"][:, pick]
    return (u * camera.width_px + z[1] * config.sigma_px, v * camera.height_px + z[2] * config.sigma_px,
            naked_eye_v_mag(when)[pick] + z[0] * config.sigma_mag)


# --- the trial nearest a boresight ------------------------------------------------------------

def parse_radec(text: str) -> tuple[float, float]:
    """``"RA,DEC"`` in degrees (RA any value, taken mod 360; DEC in [-90, 90])."""
    try:
        ra, dec = (float(t) for t in str(text).split(","))
    except ValueError:
        raise ConfigError(f"--boresight takes RA,DEC in degrees (e.g. 83.6,-5.4), got {text!r}") from None
    if not (math.isfinite(ra) and -90.0 <= dec <= 90.0):
        raise ConfigError(f"--boresight: DEC must lie in [-90, 90] deg and RA be finite, got {text!r}")
    return ra % 360.0, dec


def nearest_trial(simulator, ra_deg: float, dec_deg: float, n_search: int = 2000) -> tuple[int, float]:
    """The trial among ``0 .. n_search - 1`` whose boresight (the simulator's attitude, redraws
    included) lies nearest ``(ra_deg, dec_deg)``, and its distance in deg. Trials are drawn in
    full (about 1 ms each); 2,000 trials leave a random direction within about 3 deg."""
    if n_search < 1:
        raise ConfigError(f"the number of trials searched must be >= 1, got {n_search}")
    ra, dec = math.radians(ra_deg), math.radians(dec_deg)
    target = np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])
    z = np.array([simulator.draw(t)[0][2] for t in range(int(n_search))])
    cos_sep = np.clip(z @ target, -1.0, 1.0)
    best = int(np.argmax(cos_sep))
    return best, float(np.degrees(np.arccos(cos_sep[best])))


# --- proper motion -----------------------------------------------------------------------------

#: The embedded catalog's companion file of proper motions (starid.catalog_build).
PM_FILE = "hipparcos_v8_pm.npz"
MAS_TO_RAD = math.pi / (180.0 * 3600.0 * 1000.0)


@lru_cache(maxsize=1)
def _embedded_proper_motions():
    from importlib import resources

    with resources.files("starid.data").joinpath(PM_FILE).open("rb") as fh, np.load(fh, allow_pickle=False) as d:
        return d["hip"].astype(np.int64), d["pmra_masyr"].astype(np.float64), d["pmde_masyr"].astype(np.float64)


def proper_motions(catalog) -> tuple[np.ndarray, np.ndarray]:
    """``(pmra_masyr, pmde_masyr)`` of each star of ``catalog`` (``pmra`` = mu_alpha*, i.e. times
    cos(dec)), from the embedded Hipparcos file by HIP; 0 for ids it does not hold."""
    hip, pmra, pmde = _embedded_proper_motions()
    pos = np.clip(np.searchsorted(hip, catalog.hip), 0, hip.size - 1)
    found = hip[pos] == catalog.hip
    return np.where(found, pmra[pos], 0.0), np.where(found, pmde[pos], 0.0)


def years_since_j2000(epoch) -> float:
    """Julian years from J2000.0 (2000-01-01T12:00) to ``epoch``."""
    when = parse_epoch(epoch)
    return (when - datetime(2000, 1, 1, 12, tzinfo=UTC)).total_seconds() / (86400.0 * 365.25)


def star_units(catalog, config) -> np.ndarray:
    """The catalog's ICRS unit vectors at ``config.epoch``: ``catalog.unit_icrs`` itself when the
    epoch is unset; else each star moved from J2000.0 along the tangent plane by its proper
    motion, ``r(t) = normalise(r0 + dt (pmra e_ra + pmde e_dec))`` (the formula that built the
    catalog from J1991.25, :func:`starid.catalog_build.propagate_to_j2000`; parallax and radial
    velocity ignored). The algorithms keep the J2000 catalog."""
    if getattr(config, "epoch", None) is None:
        return catalog.unit_icrs
    dt = years_since_j2000(config.epoch)
    pmra, pmde = proper_motions(catalog)
    ra, dec = np.radians(catalog.ra_deg), np.radians(catalog.dec_deg)
    e_ra = np.stack([-np.sin(ra), np.cos(ra), np.zeros_like(ra)], axis=-1)
    e_dec = np.stack([-np.sin(dec) * np.cos(ra), -np.sin(dec) * np.sin(ra), np.cos(dec)], axis=-1)
    r = catalog.unit_icrs + dt * MAS_TO_RAD * (pmra[:, None] * e_ra + pmde[:, None] * e_dec)
    return np.ascontiguousarray(r / np.linalg.norm(r, axis=1, keepdims=True))


__all__ = ["aberrate", "boresight_radec_deg", "exposure_s", "near_ecliptic_attitude", "nearest_trial", "parse_epoch",
           "parse_radec", "proper_motions", "star_units",
           "planet_places", "planet_v_mag", "smear_centroids", "streak_stars", "trial_draws", "world_stars"]
