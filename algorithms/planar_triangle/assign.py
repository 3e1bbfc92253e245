"""The standard final step, shared by the planar-triangle and triangle-voting plugins.

Once an identification gives the attitude, every remaining image star is assigned to the catalog
star that projects within a tolerance of it (``starid.kernels.reproject_assign``), over a deeper
star list than the guide stars (:class:`DeepSky`: every catalog star the database was built
from). Candidate for the core; kept here until the core offers it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from starid.catalog import Catalog
from starid.kernels import rad_to_chord, reproject_assign, wahba_rows, z_band_rows


class DeepSky(NamedTuple):
    """Every catalog star, for assigning the image stars once the attitude is known.

    unit: float32 (m, 3) ICRS unit vectors sorted by z (what ``reproject_assign`` reads);
    hip: int64 (m,) their catalog ids; v_mag: float32 (m,) their V magnitudes.
    """

    unit: np.ndarray
    hip: np.ndarray
    v_mag: np.ndarray


class Sensor(NamedTuple):
    """The camera in pixels, and the chord from the boresight that holds the whole sensor."""

    f_px: float
    cx_px: float
    cy_px: float
    width_px: float
    height_px: float
    c_fov: float


def sensor_of(camera) -> Sensor:
    return Sensor(float(camera.f_px), float(camera.cx_px), float(camera.cy_px), float(camera.width_px),
                  float(camera.height_px), float(rad_to_chord(min(camera.half_diagonal_rad, np.pi / 2))))


@njit(cache=True)
def coverage(attitude, deep, mag_max, found_hip, sensor):
    """``(predicted, missed)``: stars of ``deep`` with V <= ``mag_max`` that ``attitude`` puts on the
    sensor, and how many of them are not among ``found_hip`` (sorted ids of the identified stars).

    A true identification explains the bright stars of its field; a chance match among noise
    points or wrong stars predicts bright stars that are not there.
    """
    start, stop = z_band_rows(deep.unit, attitude[2, 2], sensor.c_fov)
    predicted = 0
    missed = 0
    for g in range(start, stop):
        if deep.v_mag[g] > mag_max:
            continue
        u0, u1, u2 = float(deep.unit[g, 0]), float(deep.unit[g, 1]), float(deep.unit[g, 2])
        pz = attitude[2, 0] * u0 + attitude[2, 1] * u1 + attitude[2, 2] * u2
        if pz <= 0.0:
            continue
        x = sensor.cx_px + sensor.f_px * (attitude[0, 0] * u0 + attitude[0, 1] * u1 + attitude[0, 2] * u2) / pz
        y = sensor.cy_px + sensor.f_px * (attitude[1, 0] * u0 + attitude[1, 1] * u1 + attitude[1, 2] * u2) / pz
        if not (0.0 <= x < sensor.width_px and 0.0 <= y < sensor.height_px):
            continue
        predicted += 1
        pos = np.searchsorted(found_hip, deep.hip[g])
        if pos >= found_hip.shape[0] or found_hip[pos] != deep.hip[g]:
            missed += 1
    return predicted, missed


def explains_bright_stars(hip: np.ndarray, attitude: np.ndarray, mag: np.ndarray, deep: DeepSky, camera,
                          mag_limit: float, margin_mag: float, max_missed_fraction: float) -> bool:
    """The coverage check: of the stars with V <= ``min(mag_limit, faintest image star) - margin_mag``
    that ``attitude`` puts on the sensor, at most ``max(1, max_missed_fraction x their number)``
    may lack an identified star."""
    if max_missed_fraction >= 1.0 or attitude is None:
        return True
    found = np.sort(hip[hip >= 0])
    mag_max = float(min(mag_limit, mag.max()) - margin_mag)
    predicted, missed = coverage(np.ascontiguousarray(attitude), deep, mag_max, found, sensor_of(camera))
    return missed <= 1 or missed <= max_missed_fraction * predicted


def deep_sky(catalog: Catalog) -> DeepSky:
    """The z-sorted star list of ``catalog``."""
    order = np.lexsort((catalog.hip, catalog.unit_icrs[:, 2]))
    unit = np.ascontiguousarray(catalog.unit_icrs[order], dtype=np.float32)
    # z-order of the float32 values (rounding may swap neighbours)
    z_order = np.argsort(unit[:, 2], kind="stable")
    return DeepSky(np.ascontiguousarray(unit[z_order]), catalog.hip[order][z_order].astype(np.int64),
                   catalog.v_mag[order][z_order].astype(np.float32))


class Verdict(NamedTuple):
    """What the final step settles for one image (see:func:`finish`)."""

    hip: np.ndarray  # int64 (n,) the ids to report
    attitude: np.ndarray | None


def finish(v_cam: np.ndarray, mag: np.ndarray, rows: np.ndarray, guide_unit: np.ndarray, guide_hip: np.ndarray,
           deep: DeepSky, camera, eps_chord: float, mag_margin: float, mag_limit: float, coverage_margin_mag: float,
           max_missed_fraction: float, assign_all: bool) -> Verdict:
    """Attitude, the standard final assignment, and the coverage check, for ``rows`` (guide rows or -1).

    1. The attitude is solved from the identified stars (Wahba, ``starid.kernels.wahba_rows``).
    2. It predicts every star of ``deep`` on the sensor (``starid.kernels.reproject_assign``); an
       unidentified image star within ``eps_chord`` of exactly one prediction (no other image
       star near it) gets that star's id, unless the id is already given or the star is more
       than ``mag_margin`` fainter than the image star's measured ``mag`` (a false detection near
       a faint catalog star is not it).
    3. Coverage (:func:`explains_bright_stars`, on the ids of step 2): the identification is
       dropped when its attitude predicts bright stars the image does not show.
    The ids of step 2 are reported only with ``assign_all``; otherwise those of ``rows``.
    """
    found = rows >= 0
    n = rows.shape[0]
    hip = np.where(found, guide_hip[np.maximum(rows, 0)], -1).astype(np.int64)
    if found.sum() < 2:
        return Verdict(np.full(n, -1, dtype=np.int64), None)
    attitude = wahba_rows(v_cam, rows, guide_unit)
    out = np.empty(n, dtype=np.int64)
    sensor = sensor_of(camera)
    reproject_assign(attitude, v_cam, deep.unit, sensor.c_fov + eps_chord, eps_chord, out, sensor.f_px,
                     sensor.cx_px, sensor.cy_px, sensor.width_px, sensor.height_px)
    new = np.flatnonzero(~found & (out >= 0))
    cand = deep.hip[out[new]]
    ok = ~np.isin(cand, hip[found]) & (deep.v_mag[out[new]] <= mag[new] + mag_margin)
    hip_all = hip.copy()
    hip_all[new[ok]] = cand[ok]
    if not explains_bright_stars(hip_all, attitude, mag, deep, camera, mag_limit, coverage_margin_mag,
                                 max_missed_fraction):
        return Verdict(np.full(n, -1, dtype=np.int64), None)
    return Verdict(hip_all if assign_all else hip, attitude)
