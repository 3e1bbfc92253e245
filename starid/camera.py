"""Pinhole camera model and the image-frame conventions shared by every algorithm.

Conventions (tested as exact inverses in ``tests/test_camera.py``):

* pixel ``(0, 0)`` is the top-left corner of the image, ``x_px`` grows to the right and
  ``y_px`` grows downwards;
* the camera frame is right-handed with the boresight along ``+z``, ``+x`` along the image
  rows (to the right) and ``+y`` along the image columns (downwards);
* a camera-frame unit vector ``(vx, vy, vz)`` with ``vz > 0`` lands at
  ``x_px = cx_px + f_px * vx / vz`` and ``y_px = cy_px + f_px * vy / vz``;
* an attitude is a 3x3 rotation matrix mapping inertial (ICRS) vectors to the camera frame,
  ``v_cam = A @ r_icrs``.

The default camera is Table 4 of Zhou & Ye (2015): 1024 x 1024 px, 12 um pixels, focal length
70.2262 mm, principal point (512, 512), i.e. a 10 x 10 deg field of view.

A camera may have lens distortion, ``distortion = (k1, k2, p1, p2, k3)`` in OpenCV's model, order
and convention on normalized coordinates (:mod:`starid.kernels.distortion`). ``project`` and
``backproject`` are the one pair of functions every path uses; with zero distortion they are the
pinhole kernels above, bit for bit. :meth:`Camera.pinhole_frame` is the distortion-free frame a
plugin is handed (:meth:`starid.Observation.for_plugin` undistorts the centroids into it).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from .errors import ConfigError
from .kernels import backproject_px, project_cam
from .kernels.distortion import backproject_distorted, project_distorted, undistort_px
from .params import check_number, check_whole

#: The names of the distortion coefficients, in OpenCV's order.
DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3")
NO_DISTORTION = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Camera:
    """A star camera: sensor, focal length, principal point and lens distortion.

    Attributes
    ----------
    width_px, height_px : image size in pixels (rectangular sensors allowed).
    pixel_um : pixel pitch in micrometres (square pixels).
    focal_mm : focal length in millimetres.
    cx_px, cy_px : principal point in pixels (``None`` = image centre).
    distortion : ``(k1, k2, p1, p2, k3)``, OpenCV's coefficients on normalized coordinates
        (all zero = an ideal pinhole).
    name, source : optional label and where the specification comes from.
    exposure_s : optional exposure time of the preset in seconds (``None`` = not given).
    """

    width_px: int = 1024
    height_px: int = 1024
    pixel_um: float = 12.0
    focal_mm: float = 70.2262
    cx_px: float | None = None
    cy_px: float | None = None
    distortion: tuple = NO_DISTORTION
    name: str = ""
    source: str = ""
    exposure_s: float | None = None

    def __post_init__(self):
        for name in ("width_px", "height_px"):
            check_whole(f"camera {name}", getattr(self, name), 1, 1_000_000)
        for name in ("pixel_um", "focal_mm"):
            check_number(f"camera {name}", getattr(self, name), lo=0, lo_open=True)
        if self.cx_px is None:
            object.__setattr__(self, "cx_px", self.width_px / 2.0)
        if self.cy_px is None:
            object.__setattr__(self, "cy_px", self.height_px / 2.0)
        for name in ("cx_px", "cy_px"):
            check_number(f"camera {name}", getattr(self, name))
        dist = self.distortion
        if isinstance(dist, (str, bytes)) or not hasattr(dist, "__len__") or len(dist) != 5:
            raise ConfigError(f"camera distortion must be 5 numbers (k1, k2, p1, p2, k3), got {dist!r}")
        for key, value in zip(DISTORTION_NAMES, dist, strict=True):
            check_number(f"camera distortion {key}", value)
        object.__setattr__(self, "distortion", tuple(float(v) for v in dist))
        for key in ("name", "source"):
            if not isinstance(getattr(self, key), str):
                raise ConfigError(f"camera {key} must be text, got {getattr(self, key)!r}")
        if self.exposure_s is not None:
            check_number("camera exposure_s", self.exposure_s, lo=0, lo_open=True)

    @classmethod
    def from_fov(cls, fov_deg: float, resolution_px: int = 1024, pixel_um: float = 12.0) -> Camera:
        """A square camera whose full field of view across the image width is ``fov_deg``."""
        check_number("fov_deg", fov_deg, lo=0, hi=180, lo_open=True, hi_open=True)
        check_whole("resolution_px", resolution_px, 1, 1_000_000)
        f_px = (resolution_px / 2.0) / math.tan(math.radians(fov_deg) / 2.0)
        return cls(width_px=resolution_px, height_px=resolution_px, pixel_um=pixel_um,
                   focal_mm=f_px * pixel_um / 1000.0)

    @property
    def f_px(self) -> float:
        """Focal length in pixels."""
        return self.focal_mm * 1000.0 / self.pixel_um

    @property
    def fov_x_deg(self) -> float:
        """Full field of view across the image width (through the principal point)."""
        return math.degrees(2.0 * math.atan(self.width_px / 2.0 / self.f_px))

    @property
    def fov_y_deg(self) -> float:
        return math.degrees(2.0 * math.atan(self.height_px / 2.0 / self.f_px))

    @property
    def half_diagonal_rad(self) -> float:
        """Largest angle between the boresight and any point of the sensor."""
        return self.reach_rad(0.0)

    @property
    def distorted(self) -> bool:
        """True when the lens has any distortion (``project`` is then not the pinhole)."""
        return any(v != 0.0 for v in self.distortion)

    def reach_rad(self, margin_px: float = 0.0) -> float:
        """Largest angle between the boresight and any point of the sensor grown by ``margin_px``.

        With distortion the outline is back-projected point by point (64 per edge)."""
        if not self.distorted:
            dx = max(self.cx_px, self.width_px - self.cx_px) + margin_px
            dy = max(self.cy_px, self.height_px - self.cy_px) + margin_px
            return math.atan(math.hypot(dx, dy) / self.f_px)
        x, y = self.outline_px(margin_px)
        v = self.backproject(x, y)
        return float(np.max(np.arccos(np.clip(v[:, 2], -1.0, 1.0))))

    def outline_px(self, margin_px: float = 0.0, per_edge: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """Points along the sensor's edge (grown by ``margin_px``), corners included."""
        t = np.linspace(0.0, 1.0, per_edge + 1)
        x0, x1, y0, y1 = -margin_px, self.width_px + margin_px, -margin_px, self.height_px + margin_px
        xs = np.concatenate([x0 + (x1 - x0) * t, np.full(t.size, x1), x1 - (x1 - x0) * t, np.full(t.size, x0)])
        ys = np.concatenate([np.full(t.size, y0), y0 + (y1 - y0) * t, np.full(t.size, y1), y1 - (y1 - y0) * t])
        return xs, ys

    @functools.cached_property
    def pinhole_frame(self) -> Camera:
        """The distortion-free camera a plugin works in: same focal length and pixel, the sensor's
        undistorted outline's bounding box (1 px margin) as its sensor, the principal point moved
        with it. ``self`` when there is no distortion."""
        if not self.distorted:
            return self
        x, y = self.outline_px()
        ux, uy = undistort_px(x, y, self.f_px, self.cx_px, self.cy_px, np.asarray(self.distortion), 0.0, 0.0)
        x0, x1 = math.floor(float(ux.min())) - 1.0, math.ceil(float(ux.max())) + 1.0
        y0, y1 = math.floor(float(uy.min())) - 1.0, math.ceil(float(uy.max())) + 1.0
        return Camera(int(x1 - x0), int(y1 - y0), self.pixel_um, self.focal_mm, -x0, -y0, NO_DISTORTION,
                      self.name, self.source, self.exposure_s)

    def undistort(self, x_px: np.ndarray, y_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor pixels to the pixels of :attr:`pinhole_frame` (the same arrays without distortion)."""
        x_px = np.ascontiguousarray(x_px, dtype=np.float64).ravel()
        y_px = np.ascontiguousarray(y_px, dtype=np.float64).ravel()
        if not self.distorted:
            return x_px, y_px
        frame = self.pinhole_frame
        return undistort_px(x_px, y_px, self.f_px, self.cx_px, self.cy_px, np.asarray(self.distortion),
                            frame.cx_px, frame.cy_px)

    def replace(self, **changes) -> Camera:
        """A copy with some fields changed (checked)."""
        return dataclasses.replace(self, **changes)

    @property
    def pixel_rad(self) -> float:
        """Angular size of one pixel at the boresight (the IFOV)."""
        return 1.0 / self.f_px

    @property
    def pixel_ratio(self) -> float:
        """This camera's pixel (IFOV) in pixels of :data:`REFERENCE_CAMERA` (exactly 1.0 for ``Camera()``).

        Plugins whose defaults were chosen on the reference camera scale pixel-sized limits with it.
        """
        return REFERENCE_CAMERA.f_px / self.f_px

    @property
    def solid_angle_sr(self) -> float:
        """Solid angle of the rectangular sensor seen through the principal point (sr)."""
        x0, x1 = -self.cx_px / self.f_px, (self.width_px - self.cx_px) / self.f_px
        y0, y1 = -self.cy_px / self.f_px, (self.height_px - self.cy_px) / self.f_px

        def corner(x, y):   # solid angle of the rectangle [0, x] x [0, y] on the plane z = 1 (signed)
            return math.atan2(x * y, math.sqrt(1.0 + x * x + y * y))

        return corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)

    def project(self, v_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project camera-frame vectors ``(n, 3)`` (``vz > 0``) to pixel coordinates."""
        v_cam = np.ascontiguousarray(v_cam, dtype=np.float64).reshape(-1, 3)
        if self.distorted:
            return project_distorted(v_cam, self.f_px, self.cx_px, self.cy_px, np.asarray(self.distortion))
        return project_cam(v_cam, self.f_px, self.cx_px, self.cy_px)

    def backproject(self, x_px: np.ndarray, y_px: np.ndarray) -> np.ndarray:
        """Camera-frame unit vectors ``(n, 3)`` of the pixel positions (exact inverse of ``project``)."""
        x_px = np.ascontiguousarray(x_px, dtype=np.float64).ravel()
        y_px = np.ascontiguousarray(y_px, dtype=np.float64).ravel()
        if self.distorted:
            return backproject_distorted(x_px, y_px, self.f_px, self.cx_px, self.cy_px, np.asarray(self.distortion))
        return backproject_px(x_px, y_px, self.f_px, self.cx_px, self.cy_px)

    def in_image(self, x_px: np.ndarray, y_px: np.ndarray) -> np.ndarray:
        """True where a position lies on the sensor, ``0 <= x < width`` and ``0 <= y < height``."""
        return (x_px >= 0) & (x_px < self.width_px) & (y_px >= 0) & (y_px < self.height_px)

    def as_dict(self) -> dict:
        """Every field as a flat scalar (the ``camera_*`` columns of result rows and the manifest's
        ``camera``): the distortion as ``k1 .. k3``; ``exposure_s`` only when given."""
        d = {"width_px": self.width_px, "height_px": self.height_px, "pixel_um": self.pixel_um,
             "focal_mm": self.focal_mm, "cx_px": self.cx_px, "cy_px": self.cy_px,
             **dict(zip(DISTORTION_NAMES, self.distortion, strict=True)), "name": self.name, "source": self.source}
        if self.exposure_s is not None:
            d["exposure_s"] = self.exposure_s
        return d

    def columns(self) -> dict:
        """:meth:`as_dict` with each key prefixed ``camera_``: the camera's columns in result rows."""
        return {f"camera_{k}": v for k, v in self.as_dict().items()}

    def spec(self) -> dict:
        """The fields as a camera file's ``[camera]`` table (``Camera(**spec)`` rebuilds it)."""
        d = {"width_px": self.width_px, "height_px": self.height_px, "pixel_um": self.pixel_um,
             "focal_mm": self.focal_mm, "cx_px": self.cx_px, "cy_px": self.cy_px,
             "distortion": list(self.distortion)}
        for key in ("name", "source"):
            if getattr(self, key):
                d[key] = getattr(self, key)
        if self.exposure_s is not None:
            d["exposure_s"] = self.exposure_s
        return d


#: The camera starid's default parameters were chosen on: Zhou & Ye's Table 4 (10 x 10 deg,
#: 1024 x 1024 px). Plugins derive camera-dependent defaults relative to it (``Camera.pixel_ratio``).
REFERENCE_CAMERA = Camera()
