"""Shared code of the log-polar / grid family (``lpt_improved``, ``lpt``, ``grid``).

Everything the three plugins do alike lives here once:

* guide-star selection (V limit, close pairs dropped as unresolvable doubles, rows sorted by z
  so the core's reprojection kernels can band-search them) and the neighbour lists of the
  database (:func:`select_guides`, :func:`neighbour_lists`);
* the tangent-plane re-centring of the algorithm notes, section 1.4: every pattern, in the
  database and in the image, is built from unit vectors projected onto the gnomonic plane
  tangent at the reference star, scaled to pixels by the camera's focal length
  (:func:`plane_polar`), so both sides agree up to a rotation about the reference star;
* the image side: back-projection, the "double" mask, reference stars ordered from the image
  centre outwards, neighbours within R nearest first (:func:`prepare_image`,
  :func:`image_neighbours`);
* the acceptance step: an attitude seeded by the matched reference star (and its alignment
  star, or the roll a circular shift gave), refined by reprojecting the guide stars
  (``starid.kernels.reproject_assign``) and Wahba (``wahba_rows``), accepted only when enough
  guide stars it puts in the image are observed (:func:`confirm`); ``lpt_improved`` calls the
  same check as :func:`confirm_pair_near`, which gives the same answers without walking the
  catalog band (a z-bucket index, :func:`z_index`) and, for the first pass, without the two-star
  SVD (:func:`pair_attitude`, :func:`pair_first_pass`);
* the default neighbourhood radius, which scales with the field of view
  (:func:`default_radius_deg`).

Angles in radians unless a name says ``_deg``; plane distances in pixels (``_px``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from starid.camera import Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import (
    backproject_px,
    camera_frame,
    chord_rows,
    identity3,
    keep_unique,
    predicted_on_sensor,
    reproject_assign,
    sort_rows,
    verify_pairwise,
    wahba_rows,
    z_band_rows,
)
from starid.kernels.jit import inline_kernel, inner, kernel
from starid.kernels.params import frame_at  # noqa: F401 -- the kernels of grid, lpt and lpt_improved import it from here
from starid.observation import Observation
from starid.params import check_number, check_whole, param
from starid.plugin import Algorithm, Explanation, Identification
from starid.simulate import SimConfig

#: Guide-star limit when ``mag_limit`` is None and no simulator resolved it: the detection limit of
#: starid's default sensor (``SimConfig().mag_limit``).
DEFAULT_MAG_LIMIT = SimConfig().mag_limit
#: Default neighbourhood radius R: 0.3 x the smaller field of view (6 deg at 20 deg, Luo et al.'s
#: set-up), but at least the radius that holds :data:`NEIGHBOURS_TARGET` guide stars on average
#: (sparse skies, small fields: 4.0 deg for V <= 6 guide stars on the 10 deg Table 4 camera), at
#: most half the field of view and :data:`MAX_DEFAULT_RADIUS_DEG`.
RADIUS_FOV_FRACTION = 0.3
NEIGHBOURS_TARGET = 6.0
MAX_DEFAULT_RADIUS_DEG = 20.0
#: A matched pair is tried only when its separation agrees with its guide pair's within this many
#: first windows of :func:`confirm` (``Acceptance.eps0``). Measured on 1,000 images (seed 7) each of
#: the real sky at 1 px / 0.5 Mv, the V <= 6 sky, and 2 px with 3 false stars: every accepted pair
#: was within 1.5 windows; 92 % of the rejected ones were beyond 2.
SEPARATION_TOL = 2.0
#: Floor of the centroid noise the tolerances assume (px): a noise-free world still needs a window.
SIGMA_FLOOR_PX = 1.0
SKY_DEG2 = 4.0 * math.pi * (180.0 / math.pi) ** 2


def default_radius_deg(camera: Camera, n_guides: int) -> float:
    """R for a camera and a guide list of ``n_guides`` stars (see :data:`RADIUS_FOV_FRACTION`)."""
    fov = min(camera.fov_x_deg, camera.fov_y_deg)
    dense = math.sqrt(NEIGHBOURS_TARGET / (math.pi * max(n_guides, 1) / SKY_DEG2))
    return min(max(RADIUS_FOV_FRACTION * fov, min(dense, 0.5 * fov)), MAX_DEFAULT_RADIUS_DEG)


class Guides(NamedTuple):
    """Guide stars as a kernel bundle: ``unit`` float32 (g, 3) ICRS, sorted by z; ``hip`` int64 (g,)."""

    unit: np.ndarray
    hip: np.ndarray


class Acceptance(NamedTuple):
    """Tolerances of :func:`confirm`.

    eps0 : chord window of the first reprojection pass (wider when the seed attitude is coarse).
    eps : chord window of the later passes (``beta sqrt(2) sigma``).
    c_fov : chord from the boresight to the farthest image corner.
    min_matches : guide stars that must be observed where the attitude puts them.
    fraction : of the guide stars the attitude puts on the sensor, the part that must be observed.
    """

    eps0: float
    eps: float
    c_fov: float
    min_matches: int
    fraction: float


def acceptance(camera: Camera, sigma_px: float | None, beta: float, min_matches: int, fraction: float,
               eps0_extra_rad: float = 0.0) -> Acceptance:
    """Tolerance bundle: ``eps = beta sqrt(2) max(sigma_px, 1 px) / f``; ``eps0 = eps + eps0_extra_rad``."""
    sigma = max(sigma_px or 0.0, SIGMA_FLOOR_PX) / camera.f_px
    eps = beta * math.sqrt(2.0) * sigma
    c_fov = 2.0 * math.sin(camera.half_diagonal_rad / 2.0)
    return Acceptance(eps + eps0_extra_rad, eps, c_fov, int(min_matches), float(fraction))


def effective_double_px(double_px: float, radius_deg: float, camera: Camera) -> float:
    """The double-star separation in px, at most a tenth of R (a 170 deg camera's 20 px are 40 deg)."""
    return min(float(double_px), camera.f_px * math.tan(math.radians(radius_deg) / 10.0))


def select_guides(catalog: Catalog, mag_limit: float, double_px: float, camera: Camera, name: str) -> Guides:
    """Guide stars: V <= ``mag_limit``, both stars of every pair closer than ``double_px`` dropped.

    Luo et al. treat stars closer than 20 px (0.39 deg at 20 deg / 1024 px) as binaries the
    sensor cannot resolve and leave them out of the navigation list (pass the separation
    through :func:`effective_double_px`). Rows are sorted by z.
    """
    guide = catalog.brighter_than(mag_limit)
    if double_px > 0 and len(guide):
        chord = 2.0 * math.sin(0.5 * math.atan(double_px / camera.f_px))
        pairs = cKDTree(guide.unit_icrs).query_pairs(chord, output_type="ndarray")
        double = np.zeros(len(guide), dtype=bool)
        double[pairs.ravel()] = True
        guide = guide.subset(~double)
    if len(guide) < 3:
        raise ConfigError(f"{name}: only {len(guide)} usable catalog stars have V <= {mag_limit}")
    by_z = np.argsort(guide.unit_icrs[:, 2], kind="stable")
    return Guides(np.ascontiguousarray(guide.unit_icrs[by_z], dtype=np.float32),
                  np.ascontiguousarray(guide.hip[by_z], dtype=np.int64))


def neighbour_lists(unit: np.ndarray, radius_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """CSR neighbour lists: guide rows within ``radius_rad`` of each guide star, nearest first.

    Returns ``(rows int32, offsets int64)``; ties in distance are broken by row (deterministic).
    """
    u = np.asarray(unit, dtype=np.float64)
    tree = cKDTree(u)
    lists = tree.query_ball_point(u, 2.0 * math.sin(radius_rad / 2.0))
    rows, offsets = [], [0]
    for i, js in enumerate(lists):
        js = np.asarray(js, dtype=np.int64)
        js = js[js != i]
        d = np.linalg.norm(u[js] - u[i], axis=1)
        order = np.lexsort((js, d))
        rows.append(js[order])
        offsets.append(offsets[-1] + js.size)
    flat = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
    return flat.astype(np.int32), np.asarray(offsets, dtype=np.int64)


def pack_params(*bundles) -> np.ndarray:
    """The scalar bundles of a kernel call (:class:`Frame`, :class:`Acceptance`, search parameters) as one
    float64 array, fields in order (ints and bools exactly: all are far below 2**53).

    numba types a NamedTuple argument field by field in Python at every call (2-4 us each); a
    float64 array is typed in C. The kernel rebuilds the bundles (:func:`frame_at`, :func:`acceptance_at`).
    """
    return np.array([v for b in bundles for v in b], dtype=np.float64)


@kernel
def acceptance_at(p, i):
    """The :class:`Acceptance` packed at ``p[i:i+5]`` by :func:`pack_params`."""
    return Acceptance(p[i], p[i + 1], p[i + 2], int(p[i + 3]), p[i + 4])


@inner   # kernels call it only
def tangent_basis(unit, s):
    """Right-handed orthonormal ``e1, e2`` perpendicular to ``unit[s]`` (``e2 = s x e1``), as six scalars
    ``e1x, e1y, e1z, e2x, e2y, e2z`` (no arrays: nothing to allocate per call, less to compile)."""
    sx = float(unit[s, 0])
    sy = float(unit[s, 1])
    sz = float(unit[s, 2])
    # e1 = normalise(a x s) with a the coordinate axis least aligned with s
    if abs(sx) <= abs(sy) and abs(sx) <= abs(sz):
        ax, ay, az = 0.0, -sz, sy
    elif abs(sy) <= abs(sz):
        ax, ay, az = sz, 0.0, -sx
    else:
        ax, ay, az = -sy, sx, 0.0
    norm = math.sqrt(ax ** 2 + ay ** 2 + az ** 2)
    ax /= norm
    ay /= norm
    az /= norm
    return ax, ay, az, sy * az - sz * ay, sz * ax - sx * az, sx * ay - sy * ax


@kernel
def plane_polar(unit, s, rows, n_rows, f_px, r_px, phi):
    """Polar coordinates of ``unit[rows[:n_rows]]`` in the plane tangent at ``unit[s]`` (notes 1.4).

    ``r_px = f tan(angle to s)`` (the plane distance, px) and ``phi`` in ``[0, 2 pi)``
    counter-clockwise from ``e1`` of :func:`tangent_basis` about ``s``. Rotation about ``s`` only
    shifts every ``phi`` by the same amount; the same code serves catalog (ICRS) and image
    (camera-frame) vectors.
    """
    e1x, e1y, e1z, e2x, e2y, e2z = tangent_basis(unit, s)
    sx = float(unit[s, 0])
    sy = float(unit[s, 1])
    sz = float(unit[s, 2])
    for k in range(n_rows):
        j = rows[k]
        vx = float(unit[j, 0])
        vy = float(unit[j, 1])
        vz = float(unit[j, 2])
        d = vx * sx + vy * sy + vz * sz
        a = vx * e1x + vy * e1y + vz * e1z
        b = vx * e2x + vy * e2y + vz * e2z
        r_px[k] = f_px * math.sqrt(a * a + b * b) / d
        p = math.atan2(b, a)
        phi[k] = p + 2.0 * math.pi if p < 0 else p


@inner   # kernels call it only
def relative_angle(phi, phi0):
    """``phi - phi0`` wrapped to ``[0, 2 pi)``."""
    d = phi - phi0
    while d < 0:
        d += 2.0 * math.pi
    while d >= 2.0 * math.pi:
        d -= 2.0 * math.pi
    return d


@kernel
def prepare_image(x_px, y_px, sensor, double_px):
    """Back-projected unit vectors, the usable mask and the reference order of one image.

    A detection closer than ``double_px`` to another is unusable (the database dropped such
    guide pairs too; coincident detections are such pairs). Usable stars are ordered by their
    distance to the principal point, nearest first: their neighbourhoods are the most complete
    (Luo et al. take reference stars near the image centre). Returns ``(unit, usable, order)``.
    """
    n = x_px.shape[0]
    unit = backproject_px(x_px, y_px, sensor.f_px, sensor.cx_px, sensor.cy_px)
    usable = np.ones(n, dtype=np.bool_)
    d2 = double_px * double_px
    for i in range(n):
        for j in range(i + 1, n):
            dx = x_px[i] - x_px[j]
            dy = y_px[i] - y_px[j]
            if dx * dx + dy * dy < d2:
                usable[i] = False
                usable[j] = False
    key = np.empty(n)
    m = 0
    for i in range(n):
        key[i] = (x_px[i] - sensor.cx_px) ** 2 + (y_px[i] - sensor.cy_px) ** 2
        if usable[i]:
            m += 1
    order = np.empty(m, dtype=np.int64)
    m = np.int64(0)   # not a literal: one signature of sort_rows
    for i in range(n):
        if usable[i]:
            order[m] = i
            m += 1
    sort_rows(order, m, key, x_px, y_px)
    return unit, usable, order


@kernel
def image_neighbours(unit, usable, x_px, y_px, s, cos_radius, out):
    """Usable stars within the angle whose cosine is ``cos_radius`` of star ``s``, nearest first.

    Writes their indices to ``out`` and returns how many; exact ties ordered by position.
    """
    n = unit.shape[0]
    key = np.empty(n)
    k = np.int64(0)   # not a literal: one signature of sort_rows
    for j in range(n):
        if j == s or not usable[j]:
            continue
        c = unit[j, 0] * unit[s, 0] + unit[j, 1] * unit[s, 1] + unit[j, 2] * unit[s, 2]
        if c >= cos_radius:
            key[j] = -c
            out[k] = j
            k += 1
    sort_rows(out, k, key, x_px, y_px)
    return k


@inner   # kernels call it only
def seed_attitude_roll(unit, s, guides_unit, g, roll):
    """Attitude taking guide row ``g`` to image star ``s`` with a roll about it.

    The roll is the angle ``delta`` with ``phi_catalog = phi_image + delta``, both measured in
    the :func:`tangent_basis` of their own star (a circular shift of an LPT string).
    """
    e1sx, e1sy, e1sz, e2sx, e2sy, e2sz = tangent_basis(unit, s)
    e1gx, e1gy, e1gz, e2gx, e2gy, e2gz = tangent_basis(guides_unit, g)
    e1s = (e1sx, e1sy, e1sz)
    e2s = (e2sx, e2sy, e2sz)
    e1g = (e1gx, e1gy, e1gz)
    e2g = (e2gx, e2gy, e2gz)
    c = math.cos(roll)
    sn = math.sin(roll)
    A = np.zeros((3, 3))
    for a in range(3):
        u1 = c * e1s[a] - sn * e2s[a]
        u2 = sn * e1s[a] + c * e2s[a]
        for b in range(3):
            A[a, b] = (float(unit[s, a]) * float(guides_unit[g, b]) + u1 * e1g[b] + u2 * e2g[b])
    return A


@kernel
def confirm(unit, rows, attitude, guides_unit, sensor, acc, solved_from):
    """Accept or reject a seed attitude by reprojection; fills ``rows`` (guide row per star or -1).

    Passes of ``reproject_assign`` (first with ``acc.eps0``, then ``acc.eps``) and Wahba
    (``wahba_rows``) refine the attitude until the number of assigned stars stops growing
    (at most 4 passes); the assigned stars must then agree pairwise (``verify_pairwise``,
    majority). The identification stands when at least ``acc.min_matches`` stars are assigned
    and they are at least ``acc.fraction`` of the guide stars the attitude puts on the sensor;
    a random field, whose seed attitudes predict guide stars where none are seen, fails here.
    ``solved_from`` is the assignment ``attitude`` was solved from by Wahba (all -2 when it was
    not): a pass that reproduces the assignment the attitude was solved from cannot change
    anything, so the remaining passes are skipped (the result is the same as running them).
    Returns ``(accepted, attitude)``.
    """
    n = unit.shape[0]
    A = attitude
    eps = acc.eps0
    n_prev = -1
    n_seen = 0
    n_pred = 0
    solved = solved_from.copy()   # the assignment A was last solved from
    stale = False
    for it in range(5):
        n_seen, n_pred = reproject_assign(A, unit, guides_unit, acc.c_fov + eps, eps, rows, sensor.f_px,
                                          sensor.cx_px, sensor.cy_px, sensor.width_px, sensor.height_px)
        if n_seen < 2:
            return False, A
        # A solved from this very assignment already: Wahba would return A again (and, after the
        # first pass, assigning with the same A and eps would return this assignment again)
        stale = True
        for i in range(n):
            if rows[i] != solved[i]:
                stale = False
                break
        if not stale:
            A = wahba_rows(unit, rows, guides_unit)
            for i in range(n):   # a loop: an array slice assignment compiles its shape-mismatch message (~2 CPU s)
                solved[i] = rows[i]
        elif it > 0 or acc.eps0 == acc.eps:
            break   # the next pass (same A, same eps) would return this assignment and stop there
        if it > 0 and n_seen <= n_prev and eps == acc.eps:
            break
        n_prev = n_seen
        eps = acc.eps
    if not stale:   # when stale, the last pass used this A with acc.eps already
        n_seen, n_pred = reproject_assign(A, unit, guides_unit, acc.c_fov + eps, eps, rows, sensor.f_px,
                                          sensor.cx_px, sensor.cy_px, sensor.width_px, sensor.height_px)
    keep = verify_pairwise(unit, rows, guides_unit, acc.eps, np.int64(2), 0.5)
    n_keep = 0
    for i in range(n):
        if not keep[i]:
            rows[i] = -1
        else:
            n_keep += 1
    if n_keep < acc.min_matches or n_keep < acc.fraction * n_pred:
        for i in range(n):
            rows[i] = -1
        return False, A
    return True, wahba_rows(unit, rows, guides_unit)


#: :func:`prepare_image` inlined by numba into its one kernel caller, :func:`begin_identify`: one kernel fewer to
#: compile and to optimise again in every kernel above it (``prepare_image`` itself is compiled only when Python
#: calls it, for ``explain``)
_prepare_image_inline = njit(inline="always", no_cpython_wrapper=True, no_cfunc_wrapper=True)(prepare_image.py_func)


@kernel
def begin_identify(x_px, y_px, sensor, double_px, trace):
    """Start of every identify kernel: ``trace`` reset to -1, ``(rows, unit, usable, order)``.

    ``rows`` (guide row per star) is all -1; ``order`` is empty when there are fewer than 3 stars
    (no pattern to match), so the kernel's reference loop does not run.
    """
    n = x_px.shape[0]
    for t in range(trace.shape[0]):
        trace[t] = -1 if t < TRACE_WORK else 0   # the work counters (slots TRACE_WORK...) start at 0
    unit, usable, order = _prepare_image_inline(x_px, y_px, sensor, double_px)
    if n < 3:
        order = order[:0]
    return np.full(n, -1, dtype=np.int64), unit, usable, order


@inner   # kernels call it only
def no_match(rows):
    """End of every identify kernel when nothing was accepted: ``(rows all -1, identity, False)``."""
    for i in range(rows.shape[0]):
        rows[i] = -1
    return rows, identity3(), False


@kernel
def reference_pattern(unit, usable, x_px, y_px, s, cos_radius, f_px, nbrs, r_px, phi):
    """Neighbours of reference star ``s`` (:func:`image_neighbours` into ``nbrs``) and their polar coordinates.

    Returns their count; ``r_px``/``phi`` are filled only when it is at least 1.
    """
    k = image_neighbours(unit, usable, x_px, y_px, s, cos_radius, nbrs)
    if k > 0:
        plane_polar(unit, s, nbrs, k, f_px, r_px, phi)
    return k


@inner   # kernels call it only
def keep_best(best_score, best_item, found, n_best, score, item):
    """Insert ``(score, item)`` into the ``found`` best so far (``best_score`` descending); returns the new count.

    Ties keep arrival order (a later equal score goes after); when the list is full, a score not
    above the last is dropped.
    """
    if found == n_best and score <= best_score[found - 1]:
        return found
    p = found if found < n_best else n_best - 1
    while p > 0 and best_score[p - 1] < score:
        best_score[p] = best_score[p - 1]
        best_item[p] = best_item[p - 1]
        p -= 1
    best_score[p] = score
    best_item[p] = item
    return found + 1 if found < n_best else found


@kernel
def confirm_pair(unit, rows, seed, s, o, guide_s, guide_o, guides_unit, sensor, acc):
    """Seed an attitude on two matched stars (``s`` -> ``guide_s``, ``o`` -> ``guide_o``, Wahba) and :func:`confirm` it.

    A pair whose separation differs from its guide pair's by more than :data:`SEPARATION_TOL`
    first windows (``acc.eps0``, as chords) is rejected at once: a rotation keeps separations, so
    only noise can make them differ. ``seed`` is an all -1 work array (length of the image), left
    all -1. Returns ``(accepted, attitude)``.
    """
    if abs(chord_rows(unit, s, unit, o) - chord_rows(guides_unit, guide_s, guides_unit, guide_o)) > \
            SEPARATION_TOL * acc.eps0:
        return False, identity3()
    seed[s] = guide_s
    seed[o] = guide_o
    A = wahba_rows(unit, seed, guides_unit)
    ok, A = confirm(unit, rows, A, guides_unit, sensor, acc, seed)
    seed[s] = -1
    seed[o] = -1
    return ok, A


# ---- the reprojection check without scanning the catalog (issue #25, lpt_improved) ----

#: Buckets of :func:`z_index` over z in [-1, 1].
Z_BUCKETS = 4096
#: Extra half-width (chord) of the z range searched around each detection's sky position: covers the
#: attitude's departure from orthogonality (Wahba's results are orthogonal to ~1e-14) with room to spare.
Z_SLACK = 1e-6
#: Assumed bound on the difference (2-norm) between :func:`pair_attitude` and the seed Wahba
#: (``wahba_rows`` on two stars, LAPACK's SVD) computes for the same pair: both are the same rotation in
#: exact arithmetic; their rounding errors grow as machine epsilon over ``B``'s second singular value
#: ``sigma2`` (about the product of the two pairs' separations over 2), so the bound is
#: ``ATT_SCALE / sigma2`` (``sigma2`` bounded from below by ``det C / |C|_F``), at least ``ATT_FLOOR``.
#: Measured (``benchmarks/tools/lpispeed_profile.py``, every candidate of 300 images per sky): the
#: difference at most 5.8e-11 and at most 1/1000 of this bound.
ATT_SCALE = 1e-12
ATT_FLOOR = 1e-12
#: A window test decided from :func:`pair_attitude` counts only when it clears its threshold by this
#: many times the attitude bound (a rotation error ``d`` moves a prediction and the boresight at
#: most ``d``; the factor covers the rounding of the chords themselves with room).
DECIDE_FACTOR = 10.0


def z_index(unit: np.ndarray, n_buckets: int = Z_BUCKETS) -> np.ndarray:
    """First row of z-sorted ``unit`` with ``z >= -1 + 2 k / n_buckets``, k = 0..n_buckets (int64)."""
    edges = -1.0 + 2.0 * np.arange(n_buckets + 1, dtype=np.float64) / n_buckets
    return np.searchsorted(np.asarray(unit[:, 2], dtype=np.float64), edges, side="left").astype(np.int64)


@inner   # kernels call it only
def z_first(unit, z_start, z, g_lo):
    """First row, not before ``g_lo``, whose z is >= ``z`` (rows of ``unit`` sorted by z; ``z_start``
    from :func:`z_index`). Starts one bucket early (rounding of the bucket number) and walks."""
    nb = z_start.shape[0] - 1
    k = int((z + 1.0) * 0.5 * nb) - 1
    k = min(max(k, 0), nb - 1)
    g = max(z_start[k], g_lo)
    while g < unit.shape[0] and unit[g, 2] < z:
        g += 1
    return g


@inner   # kernels call it only
def settle_pairs(pair_i, pair_g, n_pairs, n_match, out_row):
    """``reproject_assign``'s bookkeeping from the (star, guide row) pairs within the window.

    A guide row within the window of exactly one star gives it that row (+1), of several gives each
    of them +2; a star keeps its row only when its count is 1 (``keep_unique``). Returns how many do.
    """
    for i in range(n_match.shape[0]):
        n_match[i] = 0
        out_row[i] = -1
    for p in range(n_pairs):
        g = pair_g[p]
        n_found = 0
        for q in range(n_pairs):
            if pair_g[q] == g:
                n_found += 1
        if n_found == 1:
            n_match[pair_i[p]] += 1
            out_row[pair_i[p]] = g
        else:
            n_match[pair_i[p]] += 2
    return keep_unique(n_match, out_row)


@kernel
def assign_near(A, v_cam, unit, z_start, c_fov, eps, out_row, pair_i, pair_g, n_match):
    """``starid.kernels.reproject_assign``'s assignment (``out_row`` and the count), without the prediction count.

    ``reproject_assign`` walks every guide row of the field's declination band and compares each
    one inside the cap with every detection. Here each detection looks up the rows whose z lies within
    ``eps`` (+ :data:`Z_SLACK`) of its own sky position ``A^T v`` (:func:`z_first`: a bucket, then a
    few rows); a row within chord ``eps`` of the detection's prediction has its z that close. Every
    row found is put to ``reproject_assign``'s own tests, the same expressions in the same floating
    point: inside the band and the cap (chord ``c_fov`` from the boresight), and the prediction
    ``A r`` within chord ``eps`` of the detection (rows whose x or y alone is farther than that from
    ``A^T v`` are skipped first). The pairs that pass are exactly the (star, row)
    pairs ``reproject_assign`` counts, and the bookkeeping (:func:`settle_pairs`) does not depend on
    the order they come in. Returns the number of stars assigned. ``pair_i``, ``pair_g`` hold the
    pairs; when they are full, the pass is made again with buffers four times as long.
    """
    n = v_cam.shape[0]
    bore = np.empty((1, 3))
    for a in range(3):
        bore[0, a] = A[2, a]
    b = np.empty((1, 3))
    g_start, g_stop = z_band_rows(unit, bore[0, 2], c_fov)
    reach = eps + Z_SLACK
    pi = pair_i
    pg = pair_g
    while True:
        n_pairs = np.int64(0)   # not a literal: one signature of settle_pairs
        full = False
        # every detection's first row first (settle_pairs overwrites out_row at the end): these look-ups
        # do not depend on one another, so their memory reads overlap when the tables are not in cache
        for i in range(n):
            dz = A[0, 2] * v_cam[i, 0] + A[1, 2] * v_cam[i, 1] + A[2, 2] * v_cam[i, 2]
            out_row[i] = z_first(unit, z_start, dz - reach, g_start)
        for i in range(n):
            dx = A[0, 0] * v_cam[i, 0] + A[1, 0] * v_cam[i, 1] + A[2, 0] * v_cam[i, 2]
            dy = A[0, 1] * v_cam[i, 0] + A[1, 1] * v_cam[i, 1] + A[2, 1] * v_cam[i, 2]
            dz = A[0, 2] * v_cam[i, 0] + A[1, 2] * v_cam[i, 1] + A[2, 2] * v_cam[i, 2]
            g = out_row[i]
            z_hi = dz + reach
            while g < g_stop and unit[g, 2] <= z_hi and not full:
                if abs(unit[g, 0] - dx) > reach or abs(unit[g, 1] - dy) > reach:
                    pass   # x or y alone is farther than the window: so is the prediction
                elif chord_rows(unit, g, bore, np.int64(0)) <= c_fov:
                    for a in range(3):
                        b[0, a] = A[a, 0] * unit[g, 0] + A[a, 1] * unit[g, 1] + A[a, 2] * unit[g, 2]
                    if chord_rows(v_cam, i, b, np.int64(0)) <= eps:
                        if n_pairs == pi.shape[0]:
                            full = True
                        else:
                            pi[n_pairs] = i
                            pg[n_pairs] = g
                            n_pairs += 1
                g += 1
        if not full:
            return settle_pairs(pi, pg, n_pairs, n_match, out_row)
        pi = np.empty(4 * pi.shape[0], dtype=np.int64)
        pg = np.empty(4 * pg.shape[0], dtype=np.int64)


@inner   # kernels call it only
def confirm_near(unit, rows, attitude, guides_unit, z_start, sensor, acc, solved_from, work, n_first):
    """:func:`confirm`, pass for pass, with :func:`assign_near` for the assignment (called directly: a
    wrapper level between them made numba re-optimise assign_near once more), and no two-star Wahba
    whose attitude is not needed.

    ``n_first`` >= 0: ``rows`` already hold the first pass's assignment (``n_first`` stars, at
    least 2, not ``solved_from``'s), as it is from ``attitude``; that pass's attitude is then never
    used again (the next step solves Wahba from the assignment), so ``attitude`` may be any
    rotation that gave the same assignment (:func:`pair_first_pass`). -1: make the first pass.
    When a pass assigns exactly two stars (nearly always a wrong candidate's: the reference star and
    one chance neighbour), :func:`confirm` solves Wahba for them (``wahba_rows`` on a rank-2 ``B``:
    LAPACK's SVD, the most expensive step of a rejection) to make the next pass. Here that pass is
    made from :func:`pair_attitude` by :func:`pair_first_pass` when every test is decided, as
    :func:`confirm_pair_near` makes its first pass; otherwise the SVD and the real pass are made.
    The two-star attitude is solved later only if the last pass was made that way and the match is
    not rejected (the prediction count needs it). The number of guide stars the attitude puts on the
    sensor (:func:`predicted_on_sensor`, one walk of the band) is needed only by the last test, and
    only when enough stars were kept to reach it; it is counted then, for the attitude and window of
    the last pass, as :func:`confirm` had it. ``work`` is :func:`pair_work`'s four arrays. Returns
    ``(accepted, attitude)``: ``rows`` and an accepted attitude are :func:`confirm`'s; a rejected
    match's attitude may differ (no caller reads it).
    """
    n = unit.shape[0]
    A = attitude
    eps = acc.eps0
    n_prev = -1
    n_seen = 0
    A_last = A
    eps_last = eps
    solved = solved_from.copy()
    P = np.empty((3, 3))                      # a two-star attitude from pair_attitude
    pair = np.empty(n, dtype=np.int64)        # the two stars P stands for (tol > 0)
    pair_last = np.empty(n, dtype=np.int64)   # the two stars of the last pass's attitude (lazy_last)
    stale = False
    tol = -1.0
    lazy_last = False
    # the passes (at most 5) and the last pass after them as one loop, so that the pass is written
    # once: ``final`` marks that last pass, made only when the assignment is not stale
    it = 0
    final = False
    given = n_first >= 0
    while True:
        if given:   # the first pass's assignment came with the call
            n_seen = n_first
            given = False
        else:
            n_seen = -1
            lazy_last = False
            if tol > 0:   # from the two-star attitude P, when every test is decided
                n_seen = pair_first_pass(P, tol, unit, guides_unit, z_start, acc.c_fov + eps, eps, work)
                if n_seen >= 0:
                    first = work[3]
                    for i in range(n):
                        rows[i] = first[i]
                        pair_last[i] = pair[i]
                    lazy_last = True
                else:
                    A = wahba_rows(unit, pair, guides_unit)
                    tol = -1.0
            if n_seen < 0:
                n_seen = assign_near(A, unit, guides_unit, z_start, acc.c_fov + eps, eps, rows, work[0], work[1],
                                     work[2])
            A_last = A
            eps_last = eps
        if final:
            break
        if n_seen < 2:
            return False, A
        stale = True
        for i in range(n):
            if rows[i] != solved[i]:
                stale = False
                break
        if not stale:
            n_two = 0
            i0 = np.int64(-1)   # not literals: one signature of pair_attitude
            i1 = np.int64(-1)
            for i in range(n):
                if rows[i] >= 0:
                    n_two += 1
                    i0, i1 = i1, i
            tol = -1.0
            if n_two == 2:
                tol = pair_attitude(unit, i0, i1, guides_unit, rows[i0], rows[i1], P)
            if tol > 0:
                for i in range(n):
                    pair[i] = rows[i]
            else:
                A = wahba_rows(unit, rows, guides_unit)
            for i in range(n):   # a loop: an array slice assignment compiles its shape-mismatch message (~2 CPU s)
                solved[i] = rows[i]
        elif it > 0 or acc.eps0 == acc.eps:
            break
        if it > 0 and n_seen <= n_prev and eps == acc.eps:
            final = True
        else:
            n_prev = n_seen
            eps = acc.eps
            it += 1
            final = it == 5
        if final and stale:
            break
    keep = verify_pairwise(unit, rows, guides_unit, acc.eps, np.int64(2), 0.5)
    n_keep = 0
    for i in range(n):
        if not keep[i]:
            rows[i] = -1
        else:
            n_keep += 1
    reject = n_keep < acc.min_matches
    if not reject:
        if lazy_last:   # the last pass was made from a two-star attitude: solve it now
            A_last = wahba_rows(unit, pair_last, guides_unit)
        n_pred = predicted_on_sensor(A_last, guides_unit, acc.c_fov + eps_last, sensor.f_px, sensor.cx_px,
                                     sensor.cy_px, sensor.width_px, sensor.height_px)
        reject = n_keep < acc.fraction * n_pred
    if reject:
        for i in range(n):
            rows[i] = -1
        return False, A
    return True, wahba_rows(unit, rows, guides_unit)


@inner   # kernels call it only
def plane_frame(x0, y0, z0, x1, y1, z1):
    """Right-handed orthonormal ``p1, p2, p3`` with ``p1`` along ``(x0, y0, z0)`` and ``p2`` in the plane
    of the two vectors (Gram-Schmidt), as nine scalars; ``p3`` = 0 when they are parallel."""
    n0 = math.sqrt(x0 * x0 + y0 * y0 + z0 * z0)
    ax, ay, az = x0 / n0, y0 / n0, z0 / n0
    d = x1 * ax + y1 * ay + z1 * az
    bx, by, bz = x1 - d * ax, y1 - d * ay, z1 - d * az
    n1 = math.sqrt(bx * bx + by * by + bz * bz)
    if not n1 > 1e-12:
        return ax, ay, az, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    bx, by, bz = bx / n1, by / n1, bz / n1
    return ax, ay, az, bx, by, bz, ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@inner   # kernels call it only
def pair_attitude(unit, s, o, guides_unit, guide_s, guide_o, A):
    """The rotation Wahba's problem gives for the two pairs ``s -> guide_s``, ``o -> guide_o`` (equal
    weights), written to ``A`` (3 x 3).

    With two stars ``B = v_s r_s^T + v_o r_o^T`` has rank 2, and ``wahba_rows`` takes LAPACK's SVD
    (a few microseconds). In exact arithmetic its answer is this: with ``P`` an orthonormal basis of
    the plane of ``v_s, v_o`` and ``Q`` of the plane of ``r_s, r_o`` (Gram-Schmidt, right-handed with
    their normals ``p3``, ``q3``), ``B = P C Q^T``; ``C`` (2 x 2) has a positive determinant, its
    polar factor is the rotation by the angle of ``(C00 + C11, C10 - C01)``, and the optimal rotation
    is ``P R2 Q^T + p3 q3^T``. Returns the bound on the difference from the seed Wahba
    (:data:`ATT_SCALE`), or -1 for a degenerate pair (``A`` then unspecified).
    """
    vx0, vy0, vz0 = np.float64(unit[s, 0]), np.float64(unit[s, 1]), np.float64(unit[s, 2])
    vx1, vy1, vz1 = np.float64(unit[o, 0]), np.float64(unit[o, 1]), np.float64(unit[o, 2])
    # np.float64, not float(): numba's float() keeps a float32 a float32
    rx0, ry0, rz0 = np.float64(guides_unit[guide_s, 0]), np.float64(guides_unit[guide_s, 1]), \
        np.float64(guides_unit[guide_s, 2])
    rx1, ry1, rz1 = np.float64(guides_unit[guide_o, 0]), np.float64(guides_unit[guide_o, 1]), \
        np.float64(guides_unit[guide_o, 2])
    p1x, p1y, p1z, p2x, p2y, p2z, p3x, p3y, p3z = plane_frame(vx0, vy0, vz0, vx1, vy1, vz1)
    q1x, q1y, q1z, q2x, q2y, q2z, q3x, q3y, q3z = plane_frame(rx0, ry0, rz0, rx1, ry1, rz1)
    if p3x == 0.0 and p3y == 0.0 and p3z == 0.0 or q3x == 0.0 and q3y == 0.0 and q3z == 0.0:
        return -1.0
    # C = P^T B Q, B = sum_k v_k r_k^T
    a0 = p1x * vx0 + p1y * vy0 + p1z * vz0
    a1 = p1x * vx1 + p1y * vy1 + p1z * vz1
    b0 = p2x * vx0 + p2y * vy0 + p2z * vz0
    b1 = p2x * vx1 + p2y * vy1 + p2z * vz1
    c0 = rx0 * q1x + ry0 * q1y + rz0 * q1z
    c1 = rx1 * q1x + ry1 * q1y + rz1 * q1z
    d0 = rx0 * q2x + ry0 * q2y + rz0 * q2z
    d1 = rx1 * q2x + ry1 * q2y + rz1 * q2z
    C00 = a0 * c0 + a1 * c1
    C01 = a0 * d0 + a1 * d1
    C10 = b0 * c0 + b1 * c1
    C11 = b0 * d0 + b1 * d1
    det = C00 * C11 - C01 * C10
    if not det > 0:
        return -1.0
    sigma2 = det / math.sqrt(C00 * C00 + C01 * C01 + C10 * C10 + C11 * C11)   # <= the smaller singular value
    h = math.sqrt((C00 + C11) ** 2 + (C10 - C01) ** 2)
    c = (C00 + C11) / h
    sn = (C10 - C01) / h
    # A = P R2 Q^T + p3 q3^T, R2 = [[c, -sn], [sn, c]]
    e1x, e1y, e1z = c * q1x - sn * q2x, c * q1y - sn * q2y, c * q1z - sn * q2z   # row 0 of R2 Q^T
    e2x, e2y, e2z = sn * q1x + c * q2x, sn * q1y + c * q2y, sn * q1z + c * q2z   # row 1
    A[0, 0] = p1x * e1x + p2x * e2x + p3x * q3x
    A[0, 1] = p1x * e1y + p2x * e2y + p3x * q3y
    A[0, 2] = p1x * e1z + p2x * e2z + p3x * q3z
    A[1, 0] = p1y * e1x + p2y * e2x + p3y * q3x
    A[1, 1] = p1y * e1y + p2y * e2y + p3y * q3y
    A[1, 2] = p1y * e1z + p2y * e2z + p3y * q3z
    A[2, 0] = p1z * e1x + p2z * e2x + p3z * q3x
    A[2, 1] = p1z * e1y + p2z * e2y + p3z * q3y
    A[2, 2] = p1z * e1z + p2z * e2z + p3z * q3z
    return max(ATT_FLOOR, ATT_SCALE / sigma2)


@inner   # kernels call it only
def band_z(z_centre, c_radius):
    """The z limits of :func:`starid.kernels.z_band_rows`'s band (the same expressions): a row of the
    z-sorted catalog lies in the rows it returns exactly when its z is within ``[z_lo, z_hi]``."""
    half = 2.0 * math.asin(min(1.0, 0.5 * c_radius))
    dec0 = math.asin(max(-1.0, min(1.0, float(z_centre))))
    return math.sin(max(-0.5 * math.pi, dec0 - half)), math.sin(min(0.5 * math.pi, dec0 + half))


@inner   # kernels call it only
def pair_first_pass(A, tol, v_cam, unit, z_start, c_fov, eps, work):
    """:func:`confirm`'s first pass from the seed Wahba gives for a pair, made with ``A`` when it can be.

    ``A`` is :func:`pair_attitude`, within ``tol`` of that seed. Every test of the pass
    (:func:`assign_near`'s, window ``eps``, cap ``c_fov``) is made with ``A`` and counts only when
    it clears its threshold by :data:`DECIDE_FACTOR` x ``tol``, which the seed's predictions, at
    most ``tol`` away, cannot cross; the band's limits are taken for the boresight's z moved by
    ``tol`` both ways (they move monotonically with it). When every test that matters is decided,
    the assignment is the seed's to the last row: it is left in ``work[3]`` and its count
    returned. When one is not (or the pair buffer is full), -1: the caller makes the real pass.
    Rows are looked up around each detection's sky position ``A^T v`` within the window plus the
    margins, and skipped early when x or y alone is already too far.
    """
    n = v_cam.shape[0]
    pair_i, pair_g, n_match, out_row = work
    margin = DECIDE_FACTOR * tol
    bx, by, bz = A[2, 0], A[2, 1], A[2, 2]
    z_lo = band_z(bz + tol, c_fov)[0]   # inside the band for every boresight z within tol
    z_hi = band_z(bz - tol, c_fov)[1]
    reach = eps + margin + Z_SLACK
    n_pairs = np.int64(0)   # not a literal: one signature of settle_pairs
    for i in range(n):   # the first rows first, their reads overlapping (as in assign_near)
        v0, v1, v2 = np.float64(v_cam[i, 0]), np.float64(v_cam[i, 1]), np.float64(v_cam[i, 2])
        dz = A[0, 2] * v0 + A[1, 2] * v1 + A[2, 2] * v2
        out_row[i] = z_first(unit, z_start, dz - reach, np.int64(0))
    for i in range(n):
        v0, v1, v2 = np.float64(v_cam[i, 0]), np.float64(v_cam[i, 1]), np.float64(v_cam[i, 2])
        dx = A[0, 0] * v0 + A[1, 0] * v1 + A[2, 0] * v2
        dy = A[0, 1] * v0 + A[1, 1] * v1 + A[2, 1] * v2
        dz = A[0, 2] * v0 + A[1, 2] * v1 + A[2, 2] * v2
        g = out_row[i]
        while g < unit.shape[0] and unit[g, 2] <= dz + reach:
            ux, uy, uz = np.float64(unit[g, 0]), np.float64(unit[g, 1]), np.float64(unit[g, 2])
            g += 1
            if abs(ux - dx) > reach or abs(uy - dy) > reach:
                continue
            px = A[0, 0] * ux + A[0, 1] * uy + A[0, 2] * uz - v0
            py = A[1, 0] * ux + A[1, 1] * uy + A[1, 2] * uz - v1
            pz = A[2, 0] * ux + A[2, 1] * uy + A[2, 2] * uz - v2
            d = math.sqrt(px * px + py * py + pz * pz)
            if d > eps + margin:
                continue
            if d > eps - margin:
                return -1   # too near the window's edge to tell
            d = math.sqrt((ux - bx) ** 2 + (uy - by) ** 2 + (uz - bz) ** 2)
            if d > c_fov + margin:
                continue
            if d > c_fov - margin or uz < z_lo or uz > z_hi or n_pairs == pair_i.shape[0]:
                return -1   # the cap's or the band's edge, or too many pairs: undecided
            pair_i[n_pairs] = i
            pair_g[n_pairs] = g - 1
            n_pairs += 1
    return settle_pairs(pair_i, pair_g, n_pairs, n_match, out_row)


@kernel
def pair_work(n):
    """Work arrays of :func:`confirm_pair_near`: ``(pair_i, pair_g, n_match, out_row), A0 (3 x 3)``."""
    cap = 4 * n + 16
    return (np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64), np.zeros(n, dtype=np.int64),
            np.empty(n, dtype=np.int64)), np.empty((3, 3))


@kernel
def confirm_pair_near(unit, rows, seed, s, o, guide_s, guide_o, guides_unit, z_start, sensor, acc, work, A0):
    """:func:`confirm_pair`, the same answer, cheaper.

    After the separation check, :func:`pair_first_pass` makes :func:`confirm`'s first pass with
    :func:`pair_attitude` instead of the seed Wahba (LAPACK's SVD for two stars). When it is decided
    (nearly always), its assignment is the seed's: fewer than 2 stars, or only the seed's two
    (stale: :func:`confirm` stops and rejects), reject the pair without more work; any other goes
    on with :func:`confirm_near` from that assignment, and the seed attitude is never needed
    (the next step solves Wahba from the assignment). An undecided pass takes the seed Wahba and
    :func:`confirm_near` in full. ``work``, ``A0`` are :func:`pair_work` of the image's size.
    (This holds for ``acc.eps0 == acc.eps``; otherwise every pair takes the full path.)
    """
    if abs(chord_rows(unit, s, unit, o) - chord_rows(guides_unit, guide_s, guides_unit, guide_o)) > \
            SEPARATION_TOL * acc.eps0:
        return False, identity3()
    seed[s] = guide_s
    seed[o] = guide_o
    n_first = np.int64(-1)
    A = A0
    if acc.eps0 == acc.eps:
        # int64 guide rows, as confirm_near passes them: one signature of pair_attitude
        tol = pair_attitude(unit, s, o, guides_unit, np.int64(guide_s), np.int64(guide_o), A0)
        if tol > 0:
            n_first = pair_first_pass(A0, tol, unit, guides_unit, z_start, acc.c_fov + acc.eps0, acc.eps0, work)
    if n_first >= 0:
        first = work[3]
        if n_first < 2 or n_first == 2 and first[s] == guide_s and first[o] == guide_o:
            seed[s] = -1
            seed[o] = -1
            return False, identity3()
        for i in range(rows.shape[0]):   # a loop, not rows[:] = first (see confirm)
            rows[i] = first[i]
    else:
        A = wahba_rows(unit, seed, guides_unit)
    ok, A = confirm_near(unit, rows, A, guides_unit, z_start, sensor, acc, seed, work, n_first)
    seed[s] = -1
    seed[o] = -1
    return ok, A


#: ``trace`` slots from this one on are per-image work counters (when the trace is that long):
#: reference patterns formed, database entries compared with them, attitudes verified
TRACE_WORK = 4
WORK_COUNTERS = ("patterns", "comparisons", "verifications")


@inline_kernel
def count_work(trace, k, n):
    """Add ``n`` to work counter ``k`` (0 patterns, 1 comparisons, 2 verifications) of ``trace``
    when ``trace`` has room for it (a 4-slot trace counts nothing)."""
    if trace.shape[0] > TRACE_WORK + k:
        trace[TRACE_WORK + k] += n


_TRACE = np.array([-1] * TRACE_WORK + [0] * len(WORK_COUNTERS), dtype=np.int64)


def new_trace() -> np.ndarray:
    """The ``trace`` of a kernel call: 4 explain slots (-1) and the :data:`WORK_COUNTERS` (0)."""
    return _TRACE.copy()


def trace_counters(trace: np.ndarray, skip=()) -> dict | None:
    """The work counters of a kernel's ``trace`` as ``Identification.counters`` (names in ``skip``
    left out: a kernel that does not count them)."""
    if not isinstance(trace, np.ndarray) or trace.shape[0] < TRACE_WORK + len(WORK_COUNTERS):
        return None
    values = trace[TRACE_WORK:].tolist()
    if not skip:
        return dict(zip(WORK_COUNTERS, values, strict=False))
    return {k: v for k, v in zip(WORK_COUNTERS, values, strict=False) if k not in skip}


@kernel
def rows_to_hip(rows, hip):
    """Catalog ids of guide ``rows`` (-1 stays -1)."""
    out = np.full(rows.shape[0], -1, dtype=np.int64)
    for i in range(rows.shape[0]):
        if rows[i] >= 0:
            out[i] = hip[rows[i]]
    return out


# ---- Python shared by the three plugin classes ----

@dataclass(frozen=True)
class PlanarAlgorithm(Algorithm):
    """Parameters, checks and ``identify`` the three log-polar / grid plugins share (subclass as a frozen dataclass).

    mag_limit : guide stars V <= this (None = follow the simulator's detection limit, as the papers'
    navigation lists end where the sensor stops seeing; outside the harness the default sensor's
    6.0). radius_deg : neighbourhood radius R (None = :func:`default_radius_deg`).
    double_px : pairs closer than this (px) are unresolvable doubles. max_refs : reference stars tried.
    n_candidates : database matches tried per pattern. sigma_px : centroid noise the windows assume
    (None = follow the simulator; floor :data:`SIGMA_FLOOR_PX`). beta : window in sigmas.
    min_matches, confirm_fraction : acceptance by reprojection (:func:`confirm`).
    A subclass defines ``_run(database, observation) -> (rows, attitude, accepted, trace)``.
    """

    follows: ClassVar[dict] = {"sigma_px": "sigma_px", "mag_limit": "mag_limit"}
    query_only: ClassVar[tuple[str, ...]] = ('sigma_px',)   # only identify reads them (conformance 'query_only')

    mag_limit: float | None = param(
        None, help="guide stars have V <= this; None follows the simulator's detection limit (6.0 outside)", unit="mag")
    radius_deg: float | None = param(
        None, unit="deg",
        help="neighbourhood radius R of a pattern; None = derived from the camera and the guide count")
    double_px: float = param(
        20.0, help="stars closer than this (at most R/10) are unresolvable doubles, unused on both sides", unit="px")
    max_refs: int = param(10, help="reference stars of the image tried before giving up")
    n_candidates: int = param(3, help="best database matches per reference pattern, each tried as a seed attitude")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="half-width of the match windows in units of sigma")
    min_matches: int = param(4, help="guide stars that must be observed where the attitude puts them to accept it")
    confirm_fraction: float = param(
        0.5, help="fraction of the guide stars the attitude puts in the image that must be observed")

    def __post_init__(self):
        if self.mag_limit is not None:
            check_number("mag_limit", self.mag_limit)
        if self.radius_deg is not None:
            check_number("radius_deg", self.radius_deg, lo=0, hi=60, lo_open=True)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, lo=0)
        check_number("double_px", self.double_px, lo=0)
        check_number("beta", self.beta, lo=0, lo_open=True)
        check_whole("max_refs", self.max_refs, 1)
        check_whole("n_candidates", self.n_candidates, 1)
        check_whole("min_matches", self.min_matches, 3)
        check_number("confirm_fraction", self.confirm_fraction, lo=0, hi=1)

    def derived(self, catalog: Catalog, camera: Camera) -> PlanarAlgorithm:
        """``mag_limit`` None (not resolved from a simulator) -> the default sensor's detection limit,
        :data:`DEFAULT_MAG_LIMIT`; ``radius_deg`` None -> :func:`default_radius_deg` for ``camera`` and
        the guide stars' number."""
        mag_limit = DEFAULT_MAG_LIMIT if self.mag_limit is None else self.mag_limit
        radius_deg = self.radius_deg
        if radius_deg is None:
            radius_deg = default_radius_deg(camera, int(np.count_nonzero(catalog.v_mag <= mag_limit)))
        if (mag_limit, radius_deg) == (self.mag_limit, self.radius_deg):
            return self
        return dataclasses.replace(self, mag_limit=mag_limit, radius_deg=radius_deg)

    _uncounted: ClassVar[tuple] = ()

    def _kernel_args(self, database, camera: Camera) -> tuple:
        """The subclass's :meth:`_make_kernel_args` for this database and camera, kept from the last call.

        The bundles (tolerances, search parameters, database tables) depend only on the parameters,
        the database and the camera, all frozen, so the last ones are reused while both are the same
        objects (every image of a run): building them in Python cost a few microseconds per image.
        """
        return self.kept("kernel_args", (database, camera), lambda: self._make_kernel_args(database, camera))

    def identify(self, database, observation: Observation) -> Identification:
        rows, attitude, ok, trace = self._run(database, observation)
        return Identification(rows_to_hip(rows, database.guide_hip), attitude if ok else None,
                              counters=trace_counters(trace, self._uncounted))


def explain_pattern(observation: Observation, rows: np.ndarray, guide_hip: np.ndarray, ref: int, align: int,
                    radius_px: float, double_px: float, rays: np.ndarray, caption: str) -> Explanation:
    """Explanation of a reference-star pattern on the image.

    Segments: the reference star to each usable neighbour within R (the one to the alignment
    star highlighted), then rays from the reference star at the given angles (radians from the
    direction of the alignment star, counter-clockwise in the tangent plane, which is clockwise
    on screen with y down: the same sense as ``atan2(dy, dx)`` in pixels) of length ``radius_px``.
    Points: the reference star, its alignment star and every identified star, labelled.
    """
    x, y = observation.x_px, observation.y_px
    sensor = camera_frame(observation.camera)
    segments, labels, points = [], [], []
    highlight = []
    if ref >= 0:
        unit, usable, _ = prepare_image(x, y, sensor, double_px)
        nbrs = np.empty(len(x), dtype=np.int64)
        k = image_neighbours(unit, usable, x, y, ref, math.cos(radius_px / sensor.f_px), nbrs)
        for j in nbrs[:k]:
            if j == align:
                highlight.append(len(segments))
            segments.append([[x[ref], y[ref]], [x[j], y[j]]])
        base = math.atan2(y[align] - y[ref], x[align] - x[ref]) if align >= 0 else 0.0
        for a in rays:
            segments.append([[x[ref], y[ref]], [x[ref] + radius_px * math.cos(base + a),
                                                y[ref] + radius_px * math.sin(base + a)]])
        points.append([x[ref], y[ref]])
        labels.append(f"reference{'' if rows[ref] < 0 else ' HIP ' + str(int(guide_hip[rows[ref]]))}")
        if align >= 0:
            points.append([x[align], y[align]])
            labels.append(f"alignment{'' if rows[align] < 0 else ' HIP ' + str(int(guide_hip[rows[align]]))}")
    for i in np.flatnonzero(rows >= 0):
        if i not in (ref, align):
            points.append([x[i], y[i]])
            labels.append(f"HIP {int(guide_hip[rows[i]])}")
    return Explanation(segments=np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2),
                       points=np.asarray(points, dtype=np.float64).reshape(-1, 2), labels=tuple(labels),
                       caption=caption, highlight=np.asarray(highlight, dtype=np.int64))
