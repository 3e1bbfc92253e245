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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kernels import backproject_px, project_cam
from .params import check_number, check_whole


@dataclass(frozen=True)
class Camera:
    """An ideal pinhole camera (no distortion).

    Attributes
    ----------
    width_px, height_px : image size in pixels.
    pixel_um : pixel pitch in micrometres (square pixels).
    focal_mm : focal length in millimetres.
    cx_px, cy_px : principal point in pixels (``None`` = image centre).
    """

    width_px: int = 1024
    height_px: int = 1024
    pixel_um: float = 12.0
    focal_mm: float = 70.2262
    cx_px: float | None = None
    cy_px: float | None = None

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

    @classmethod
    def from_fov(cls, fov_deg: float, resolution_px: int = 1024, pixel_um: float = 12.0) -> "Camera":
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
        dx = max(self.cx_px, self.width_px - self.cx_px)
        dy = max(self.cy_px, self.height_px - self.cy_px)
        return math.atan(math.hypot(dx, dy) / self.f_px)

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
        return project_cam(v_cam, self.f_px, self.cx_px, self.cy_px)

    def backproject(self, x_px: np.ndarray, y_px: np.ndarray) -> np.ndarray:
        """Camera-frame unit vectors ``(n, 3)`` of the pixel positions (exact inverse of ``project``)."""
        x_px = np.ascontiguousarray(x_px, dtype=np.float64).ravel()
        y_px = np.ascontiguousarray(y_px, dtype=np.float64).ravel()
        return backproject_px(x_px, y_px, self.f_px, self.cx_px, self.cy_px)

    def in_image(self, x_px: np.ndarray, y_px: np.ndarray) -> np.ndarray:
        """True where a position lies on the sensor, ``0 <= x < width`` and ``0 <= y < height``."""
        return (x_px >= 0) & (x_px < self.width_px) & (y_px >= 0) & (y_px < self.height_px)

    def as_dict(self) -> dict:
        return {"width_px": self.width_px, "height_px": self.height_px, "pixel_um": self.pixel_um,
                "focal_mm": self.focal_mm, "cx_px": self.cx_px, "cy_px": self.cy_px}


#: The camera starid's default parameters were chosen on: Zhou & Ye's Table 4 (10 x 10 deg,
#: 1024 x 1024 px). Plugins derive camera-dependent defaults relative to it (``Camera.pixel_ratio``).
REFERENCE_CAMERA = Camera()
