"""Shared numba kernels: every algorithm reuses these instead of writing its own.

All are ``@njit(cache=True, no_cfunc_wrapper=True)`` (except the k-vector builders, which run once per database,
and :func:`rad_to_chord`, which only Python calls) and
take plain numpy arrays or named bundles of them (:class:`KVector`), so they can be called from
Python or from other kernels. Units: angles in radians; unit vectors are 3-vectors in the frame
the caller says (camera frame for observed stars, ICRS for catalog stars); a "chord" is the
Euclidean distance between two unit vectors, ``2 sin(theta / 2)`` (:func:`rad_to_chord`).

* :mod:`.geometry` -- pinhole projection, chords and angles, triangle sides;
* :mod:`.kvector` -- Mortari's k-vector range search;
* :mod:`.verify` -- pairwise angular verification, identification by reprojection;
* :mod:`.attitude` -- Wahba's problem;
* :mod:`.lapack` -- the 3x3 SVD, determinants and products it needs, as direct BLAS / LAPACK calls;
* :mod:`.order` -- brightest (or nearest) first, input-order free;
* :mod:`.assign` -- the final step: with the attitude, assign every detection (``assign_all``, ending
  with ``merge_assigned``), and
  the whole-image check of a hypothesis (``explained``).
"""

from .assign import (
                     DeepSky,
                     Frame,
                     assign_all,
                     camera_frame,
                     check_stars,
                     deep_sky,
                     explained,
                     field_chord,
                     merge_assigned,
                     refine_explained,
)
from .attitude import guide_rows_f64, identity3, wahba_rows
from .geometry import (
                     angular_distance_rad,
                     backproject_px,
                     chord,
                     chord_rows,
                     chord_to_rad,
                     pairwise_chords,
                     project_cam,
                     rad_to_chord,
                     triangle_sides,
                     triple_product,
)
from .kvector import KVector, kvector_build, kvector_make, kvector_query, kvector_range, kvector_slice
from .order import before, order_by, sort_rows
from .verify import keep_unique, predicted_on_sensor, reproject_assign, verify_pairwise, z_band_rows, z_bound

__all__ = [
    "angular_distance_rad", "assign_all", "backproject_px", "before", "camera_frame", "check_stars", "chord",
    "chord_rows", "chord_to_rad", "deep_sky", "DeepSky", "explained", "field_chord", "Frame", "guide_rows_f64",
    "identity3", "keep_unique", "KVector", "kvector_build", "kvector_make", "kvector_query", "kvector_range",
    "kvector_slice", "merge_assigned", "order_by", "pairwise_chords", "predicted_on_sensor", "project_cam",
    "rad_to_chord", "refine_explained", "reproject_assign", "sort_rows", "triangle_sides", "triple_product",
    "verify_pairwise", "wahba_rows", "z_band_rows", "z_bound",
]
