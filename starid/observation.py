"""Observations: what a star tracker hands to an identification algorithm.

An :class:`Observation` is one image's detections as arrays; a :class:`TrialSet` is many
images stored flat with offsets (struct of arrays), which is what the simulator produces and
the harness consumes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import Camera
from .errors import ObservationError


@dataclass(frozen=True, eq=False)
class Observation:
    """Detections of one image.

    Attributes
    ----------
    x_px, y_px : float64 (n,) centroids, pixel (0, 0) = top-left corner, x right, y down.
    mag : float64 (n,) measured (noisy) magnitudes.
    camera : the camera that took the image as the tracker knows it (its assumed calibration,
        distortion included); the centroids are raw sensor pixels.
    truth_hip : int64 (n,) true catalog id of each detection (-1 = false star), or ``None``
        when unknown. Algorithms must not read it; only the harness does.
    """

    x_px: np.ndarray
    y_px: np.ndarray
    mag: np.ndarray
    camera: Camera = field(default_factory=Camera)
    truth_hip: np.ndarray | None = None

    def __post_init__(self):
        arrays = {}
        for name in ("x_px", "y_px", "mag"):
            value = getattr(self, name)
            try:
                arr = np.ascontiguousarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                raise ObservationError(f"observation {name} must be numeric") from None
            if arr.ndim != 1:
                raise ObservationError(f"observation {name} must be 1-D, got shape {arr.shape}")
            arrays[name] = arr
        n = arrays["x_px"].size
        for name, arr in arrays.items():
            if arr.size != n:
                raise ObservationError(f"observation arrays differ in length: x_px has {n}, {name} has {arr.size}")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise ObservationError(f"observation {name} has a non-finite value at star {bad[0]}")
            object.__setattr__(self, name, _read_only(arr))  # one numba signature: kernels see read-only arrays
        off = np.flatnonzero(~self.camera.in_image(arrays["x_px"], arrays["y_px"]))
        if off.size:
            i = off[0]
            raise ObservationError(
                f"star {i} at ({arrays['x_px'][i]:.3f}, {arrays['y_px'][i]:.3f}) px lies outside the "
                f"{self.camera.width_px}x{self.camera.height_px} image")
        if self.truth_hip is not None:
            truth = np.ascontiguousarray(self.truth_hip, dtype=np.int64)
            if truth.shape != (n,):
                raise ObservationError(f"truth_hip must have shape ({n},), got {truth.shape}")
            object.__setattr__(self, "truth_hip", truth)

    def __len__(self) -> int:
        return int(self.x_px.size)

    def unit_cam(self) -> np.ndarray:
        """Camera-frame unit vectors ``(n, 3)`` of the detections."""
        return self.camera.backproject(self.x_px, self.y_px)

    def permuted(self, order: np.ndarray) -> Observation:
        """The same detections in another order."""
        return Observation(self.x_px[order], self.y_px[order], self.mag[order], self.camera,
                           None if self.truth_hip is None else self.truth_hip[order])

    def for_plugin(self) -> Observation:
        """What an algorithm is handed: read-only arrays and no truth, in a pinhole frame.

        With a distorted camera the centroids are first undistorted with its calibration into
        :attr:`Camera.pinhole_frame` (what flight software does), so every plugin works on a
        pinhole camera; without distortion the arrays and camera are these, unchanged."""
        if self.camera.distorted:
            x, y = self.camera.undistort(self.x_px, self.y_px)
            x, y, m = (_read_only(a) for a in (x, y, self.mag))
            return Observation(x, y, m, self.camera.pinhole_frame)
        # this observation's arrays were checked when it was made (and are read-only): not again per image
        return Observation._checked(_read_only(self.x_px), _read_only(self.y_px), _read_only(self.mag), self.camera)

    @classmethod
    def _checked(cls, x_px, y_px, mag, camera, truth_hip=None) -> Observation:
        """An observation of arrays already known to pass :meth:`__post_init__`'s checks (read-only float64
        1-D arrays of one length, finite, on the sensor; ``truth_hip`` int64 of that length or ``None``),
        made without checking them again: the harness makes two per image."""
        obs = object.__new__(cls)
        for name, value in (("x_px", x_px), ("y_px", y_px), ("mag", mag), ("camera", camera),
                            ("truth_hip", truth_hip)):
            object.__setattr__(obs, name, value)
        return obs

    def to_frame(self):
        """The detections as a pandas DataFrame (``star, x_px, y_px, mag[, truth_hip]``)."""
        import pandas as pd

        data = {"star": np.arange(len(self)), "x_px": self.x_px, "y_px": self.y_px, "mag": self.mag}
        if self.truth_hip is not None:
            data["truth_hip"] = self.truth_hip
        return pd.DataFrame(data)


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (a copy when ``a`` itself may still be written through)."""
    if a.flags.writeable:
        a = a.copy()
        a.flags.writeable = False
    return a.view()


@dataclass(frozen=True, eq=False)
class TrialSet:
    """Many simulated images, stored flat: star ``j`` of trial ``i`` is row ``offsets[i] + j``.

    Attributes
    ----------
    trial : int64 (t,) trial indices (reproducible from ``(seed, trial)`` alone).
    offsets : int64 (t + 1,) row offsets into the star arrays.
    x_px, y_px, mag, truth_hip : per-star arrays (see :class:`Observation`).
    attitude : float64 (t, 3, 3) true attitudes (ICRS -> camera).
    n_redraws : int64 (t,) attitudes rejected by the ``min_stars`` filter before this trial.
    camera : the camera the algorithms assume (its calibration; the observations carry it).
    warmup : an image outside the set (never scored) on which the harness warms the JIT up.
    true_camera : the camera that imaged the sky (``None`` = the same as ``camera``).

    The arrays are made read-only: a plugin handed a view cannot change the images the next
    algorithm is scored on. What made the trials (seed, settings) is the caller's to record.
    """

    trial: np.ndarray
    offsets: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    mag: np.ndarray
    truth_hip: np.ndarray
    attitude: np.ndarray
    n_redraws: np.ndarray
    camera: Camera
    warmup: Observation | None = None
    true_camera: Camera | None = None

    def __post_init__(self):
        for name in ("trial", "offsets", "x_px", "y_px", "mag", "truth_hip", "attitude", "n_redraws"):
            arr = getattr(self, name)
            if arr.flags.writeable:
                arr = arr.copy() if arr.base is not None else arr
                arr.flags.writeable = False
                object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.trial.size)

    def n_stars(self) -> np.ndarray:
        return np.diff(self.offsets)

    def observation(self, i: int, truth: bool = True) -> Observation:
        """The ``i``-th image of the set (position ``i``, not trial index); read-only views.

        ``truth=False`` leaves the truth out, as handed to an algorithm.
        """
        a, b = self.offsets[i], self.offsets[i + 1]
        if self._all_valid():     # the checks Observation makes, made once for the whole set
            return Observation._checked(self.x_px[a:b].view(), self.y_px[a:b].view(), self.mag[a:b].view(),
                                        self.camera, self.truth_hip[a:b] if truth else None)
        return Observation(self.x_px[a:b], self.y_px[a:b], self.mag[a:b], self.camera,
                           self.truth_hip[a:b] if truth else None)

    def _all_valid(self) -> bool:
        """True when every image passes :class:`Observation`'s checks as it is: float64 1-D star arrays of
        one length (read-only, C-contiguous), finite, on the sensor, int64 truth, offsets within the
        arrays. Computed once per set; an image of a set that does not pass is checked (and refused) on
        its own, as before."""
        valid = self.__dict__.get("_valid")
        if valid is None:
            arrays = (self.x_px, self.y_px, self.mag)
            n = self.x_px.shape[0] if self.x_px.ndim == 1 else -1
            offsets = self.offsets
            valid = bool(
                all(a.dtype == np.float64 and a.ndim == 1 and a.shape[0] == n and a.flags.c_contiguous
                    and not a.flags.writeable for a in arrays)
                and self.truth_hip.dtype == np.int64 and self.truth_hip.ndim == 1 and self.truth_hip.shape[0] == n
                and self.truth_hip.flags.c_contiguous
                and offsets.ndim == 1 and offsets.size == self.trial.size + 1 and offsets.size >= 1
                and np.issubdtype(offsets.dtype, np.integer) and offsets[0] == 0 and offsets[-1] == n
                and bool(np.all(np.diff(offsets) >= 0))
                and all(bool(np.isfinite(a).all()) for a in arrays)
                and bool(self.camera.in_image(self.x_px, self.y_px).all()))
            object.__setattr__(self, "_valid", valid)
        return valid

    def to_frame(self):
        """Every detection as a tidy DataFrame (``trial, star, x_px, y_px, mag, truth_hip``)."""
        import pandas as pd

        counts = self.n_stars()
        return pd.DataFrame({"trial": np.repeat(self.trial, counts),
                             "star": np.arange(self.x_px.size) - np.repeat(self.offsets[:-1], counts),
                             "x_px": self.x_px, "y_px": self.y_px, "mag": self.mag, "truth_hip": self.truth_hip})

    def select(self, positions: np.ndarray) -> TrialSet:
        """A subset of the images, by position."""
        positions = np.asarray(positions, dtype=np.int64)
        counts = np.diff(self.offsets)[positions]
        rows = np.concatenate([np.arange(self.offsets[p], self.offsets[p + 1]) for p in positions]) \
            if positions.size else np.zeros(0, dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return TrialSet(self.trial[positions], offsets, self.x_px[rows], self.y_px[rows], self.mag[rows],
                        self.truth_hip[rows], self.attitude[positions], self.n_redraws[positions],
                        self.camera, self.warmup, self.true_camera)
