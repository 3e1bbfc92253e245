"""The standard final step of a star tracker: once the attitude is known, assign every image star.

An identification from guide stars gives an attitude; every other detection is then given the
catalog star predicted within a tolerance of it, over a deeper star list than the guide stars
(:class:`DeepSky`). Any plugin can offer it as a parameter (``assign_all``); star recall then
measures the tracker, not only the pattern match.

The same reprojection judges a hypothesis: :func:`explained` counts the detections an attitude
explains against the guide stars and the fainter :func:`check_stars`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .attitude import wahba_rows
from .geometry import backproject_px
from .jit import inner, kernel
from .verify import reproject_assign


class DeepSky(NamedTuple):
    """Catalog stars to assign: ``unit`` float32 (m, 3) ICRS unit vectors sorted by z (what
    :func:`~starid.kernels.reproject_assign` reads), ``hip`` int64 (m,) their ids."""

    unit: np.ndarray
    hip: np.ndarray

    @property
    def nbytes(self) -> int:
        return int(self.unit.nbytes + self.hip.nbytes)


class Frame(NamedTuple):
    """The camera as numbers a kernel reads: focal length and principal point in pixels, sensor size."""

    f_px: float
    cx_px: float
    cy_px: float
    width_px: float
    height_px: float


def camera_frame(camera) -> Frame:
    """The :class:`Frame` of a :class:`starid.Camera`."""
    return Frame(float(camera.f_px), float(camera.cx_px), float(camera.cy_px), float(camera.width_px),
                 float(camera.height_px))


def deep_sky(catalog, mag_limit: float | None = None) -> DeepSky:
    """The stars of ``catalog`` (to ``mag_limit``; all when ``None``), z-sorted for assignment.

    An empty :class:`DeepSky` (``mag_limit = -inf``) costs nothing when assignment is off.
    """
    if mag_limit is not None:
        catalog_hip, unit = catalog.hip[catalog.v_mag <= mag_limit], catalog.unit_icrs[catalog.v_mag <= mag_limit]
    else:
        catalog_hip, unit = catalog.hip, catalog.unit_icrs
    unit32 = np.ascontiguousarray(unit, dtype=np.float32)
    order = np.lexsort((catalog_hip, unit32[:, 2]))     # by float32 z, then id: a strict order
    return DeepSky(np.ascontiguousarray(unit32[order]), np.ascontiguousarray(catalog_hip[order], dtype=np.int64))


@kernel
def field_chord(frame):
    """Chord from the boresight to the farthest corner of the sensor."""
    corners = backproject_px(np.array([0.0, frame.width_px, 0.0, frame.width_px]),
                             np.array([0.0, 0.0, frame.height_px, frame.height_px]), frame.f_px, frame.cx_px,
                             frame.cy_px)
    c = 0.0
    for i in range(4):
        c = max(c, math.sqrt(corners[i, 0] ** 2 + corners[i, 1] ** 2 + (corners[i, 2] - 1.0) ** 2))
    return c


@kernel
def assign_all(attitude, x_px, y_px, frame, deep, eps_chord, hip):
    """Assign every detection to the deep star ``attitude`` predicts within chord ``eps_chord`` of it.

    One-to-one (:func:`~starid.kernels.reproject_assign`); a detection left unassigned keeps the id it
    had in ``hip`` unless that id went to another detection. ``hip`` (int64, the plugin's answer so
    far) is updated in place; returns how many detections have an id afterwards.
    """
    n = x_px.shape[0]
    v_all = backproject_px(x_px, y_px, frame.f_px, frame.cx_px, frame.cy_px)
    rows = np.empty(n, dtype=np.int64)
    reproject_assign(attitude, v_all, deep.unit, field_chord(frame) + eps_chord, eps_chord, rows, frame.f_px,
                     frame.cx_px, frame.cy_px, frame.width_px, frame.height_px)
    return merge_assigned(rows, deep.hip, hip)


@inner   # kernels call it only
def merge_assigned(rows, deep_hip, hip):
    """``hip`` (int64, updated in place) merged with a reprojection's assignment: ``deep_hip[rows[i]]`` where
    ``rows[i] >= 0``; a detection reprojection left unassigned keeps its id from ``hip`` unless that id went to
    another detection. Returns how many detections have an id afterwards (:func:`assign_all`'s last step; a
    plugin with its own reprojection, triangle voting's cone search, ends with it too)."""
    n = rows.shape[0]
    out = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        if rows[i] >= 0:
            out[i] = deep_hip[rows[i]]
    count = 0
    for i in range(n):
        if out[i] < 0 and hip[i] >= 0:
            taken = False
            for j in range(n):
                if out[j] == hip[i]:
                    taken = True
            if not taken:
                out[i] = hip[i]
        hip[i] = out[i]
        if out[i] >= 0:
            count += 1
    return count


def check_stars(catalog, guide_hip: np.ndarray, mag_limit: float) -> np.ndarray:
    """The stars a whole-image check may explain detections with besides the guide stars: float32 ICRS
    unit vectors (m, 3) of the catalog stars with V <= ``mag_limit`` that are not in ``guide_hip``,
    sorted by z (what :func:`explained` reads). A real sensor images every star to its limit, so an
    attitude is judged against these too."""
    keep = (catalog.v_mag <= mag_limit) & ~np.isin(catalog.hip, guide_hip)
    unit = catalog.unit_icrs[keep].astype(np.float32)
    return np.ascontiguousarray(unit[np.lexsort((unit[:, 1], unit[:, 0], unit[:, 2]))])


@kernel
def explained(attitude, v_cam, guide_unit, extra_unit, frame, c_fov, eps_chord, rows_guide, rows_extra):
    """Whole-image check: how many detections ``attitude`` explains.

    A detection is explained when it lies within chord ``eps_chord`` of exactly one predicted
    star (:func:`~starid.kernels.reproject_assign`, one-to-one per list) among the guide stars
    (rows in ``rows_guide``) or the :func:`check_stars` (rows in ``rows_extra``); ``c_fov`` is
    the chord from the boresight within which stars are predicted. Returns ``(n_explained,
    n_guide_seen, n_guide_predicted)``.
    """
    n_seen, n_predicted = reproject_assign(attitude, v_cam, guide_unit, c_fov, eps_chord, rows_guide, frame.f_px,
                                           frame.cx_px, frame.cy_px, frame.width_px, frame.height_px)
    if extra_unit.shape[0] > 0:
        reproject_assign(attitude, v_cam, extra_unit, c_fov, eps_chord, rows_extra, frame.f_px, frame.cx_px,
                         frame.cy_px, frame.width_px, frame.height_px)
    else:
        rows_extra[:] = -1
    count = 0
    for i in range(v_cam.shape[0]):
        if rows_guide[i] >= 0 or rows_extra[i] >= 0:
            count += 1
    return count, n_seen, n_predicted


@kernel
def refine_explained(v_cam, guide_unit, extra_unit, frame, c_fov, eps_chord, rows_guide, rows_extra):
    """The attitude (Wahba) from every detection :func:`explained` assigned, then :func:`explained`
    again with it (``rows_guide`` / ``rows_extra`` updated). Returns ``(attitude, n_explained,
    n_guide_seen, n_guide_predicted)``."""
    n = v_cam.shape[0]
    rows = np.empty(n, dtype=np.int64)
    cat_vec = np.empty((n, 3))
    for i in range(n):
        rows[i] = -1
        if rows_guide[i] >= 0 or rows_extra[i] >= 0:
            rows[i] = i
            for a in range(3):
                cat_vec[i, a] = guide_unit[rows_guide[i], a] if rows_guide[i] >= 0 else extra_unit[rows_extra[i], a]
    attitude = wahba_rows(v_cam, rows, cat_vec)
    count, n_seen, n_predicted = explained(attitude, v_cam, guide_unit, extra_unit, frame, c_fov, eps_chord,
                                           rows_guide, rows_extra)
    return attitude, count, n_seen, n_predicted
