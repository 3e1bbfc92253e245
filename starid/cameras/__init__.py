"""Camera files and the presets shipped with starid.

A camera file is TOML with one ``[camera]`` table whose keys are :class:`starid.Camera`'s fields::

    [camera]
    name = "my_tracker"                      # optional
    source = "datasheet rev. C, table 2"     # optional: where the numbers come from
    width_px = 1024
    height_px = 768
    pixel_um = 5.5
    focal_mm = 25.0
    cx_px = 512.0                            # optional (default: the image centre)
    cy_px = 384.0
    distortion = [-0.12, 0.03, 0.0, 0.0, 0.0]   # optional: OpenCV (k1, k2, p1, p2, k3)
    exposure_s = 0.1                         # optional

``width_px``, ``height_px``, ``pixel_um`` and ``focal_mm`` are required; any other key is an error
naming it. The presets are the ``*.toml`` files of this package (``starid cameras`` lists them).
"""

from __future__ import annotations

import math
import tomllib
from importlib import resources
from pathlib import Path

from ..camera import Camera
from ..errors import ConfigError

#: The default preset (Zhou & Ye's Table 4, ``Camera()``).
DEFAULT = "table4"
REQUIRED = ("width_px", "height_px", "pixel_um", "focal_mm")
OPTIONAL = ("name", "source", "cx_px", "cy_px", "distortion", "exposure_s")


def preset_names() -> list[str]:
    """The names of the shipped presets, sorted."""
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir() if p.name.endswith(".toml"))


def _read_table(text: str, where: str) -> dict:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML: {exc}") from None
    extra = sorted(set(data) - {"camera"})
    if extra:
        raise ConfigError(f"{where}: only a [camera] table is allowed, found {extra}")
    table = data.get("camera")
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: no [camera] table")
    return check_table(table, where)


def check_table(table: dict, where: str = "camera") -> dict:
    """The ``[camera]`` table, its keys checked (unknown or missing fields named)."""
    unknown = sorted(set(table) - set(REQUIRED) - set(OPTIONAL))
    if unknown:
        raise ConfigError(f"{where}: unknown camera field {unknown[0]!r}; valid: {', '.join(REQUIRED + OPTIONAL)}")
    missing = [k for k in REQUIRED if k not in table]
    if missing:
        raise ConfigError(f"{where}: camera field {missing[0]!r} is missing (required: {', '.join(REQUIRED)})")
    return dict(table)


def _make(table: dict, where: str) -> Camera:
    try:
        return Camera(**table)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def preset_table(name_or_path: str | Path) -> tuple[dict, str]:
    """The checked ``[camera]`` table of a preset name or a TOML file, and where it came from."""
    text = str(name_or_path)
    if text in preset_names():
        return _read_table(resources.files(__name__).joinpath(f"{text}.toml").read_text(), f"camera {text}"), text
    path = Path(text)
    if path.suffix.lower() == ".toml" or path.exists():
        if not path.is_file():
            raise ConfigError(f"camera file {path} does not exist")
        return _read_table(path.read_text(), f"camera file {path}"), str(path)
    raise ConfigError(f"unknown camera {text!r}: give a preset ({', '.join(preset_names())}) or a .toml file")


def load_camera(name_or_path: str | Path) -> Camera:
    """A preset by name, or a camera file (TOML)."""
    table, where = preset_table(name_or_path)
    return _make(table, f"camera {where}")


def camera_from_spec(spec: dict) -> Camera:
    """A camera from experiment/command-line settings: ``preset`` (a name or file) and field
    overrides, or ``fov_deg`` (+ ``resolution_px`` or ``width_px``/``height_px``, ``pixel_um``),
    or :class:`Camera` fields. Overrides of the sensor size re-centre a principal point the
    preset did not give; ``fov_deg`` sets the focal length across the width."""
    spec = dict(spec)
    preset = spec.pop("preset", None)
    if preset is not None:
        table, where = preset_table(preset)
    else:
        table, where = {}, "camera"
    if "resolution_px" in spec:
        res = spec.pop("resolution_px")
        w, h = res if isinstance(res, (tuple, list)) else (res, res)
        spec.setdefault("width_px", w)
        spec.setdefault("height_px", h)
    fov = spec.pop("fov_deg", None)
    if fov is not None and "focal_mm" in spec:
        raise ConfigError("camera: give either fov_deg or focal_mm, not both")
    unknown = sorted(set(spec) - set(REQUIRED) - set(OPTIONAL))
    if unknown:
        raise ConfigError(f"camera: unknown camera field {unknown[0]!r}; valid: "
                          f"{', '.join(REQUIRED + OPTIONAL)}, preset, fov_deg, resolution_px")
    resized = any(k in spec for k in ("width_px", "height_px"))
    table = {**table, **spec}
    if resized and preset is not None:
        for k in ("cx_px", "cy_px"):
            if k not in spec:
                table.pop(k, None)
    if fov is not None:
        from ..params import check_number

        check_number("fov_deg", fov, lo=0, hi=180, lo_open=True, hi_open=True)
        width = table.get("width_px", 1024)
        pixel = table.get("pixel_um", 12.0)
        table.setdefault("width_px", width)
        table.setdefault("height_px", width)
        table.setdefault("pixel_um", pixel)
        f_px = (width / 2.0) / math.tan(math.radians(fov) / 2.0)     # as Camera.from_fov
        table["focal_mm"] = f_px * pixel / 1000.0
    return _make(table, f"camera {where}" if preset is not None else "camera")


def describe(camera: Camera) -> dict:
    """One ``starid cameras`` row: size, field of view, pixel scale, distortion, source."""
    return {"name": camera.name, "size_px": f"{camera.width_px}x{camera.height_px}",
            "fov_deg": f"{camera.fov_x_deg:.2f} x {camera.fov_y_deg:.2f}",
            "arcsec_per_px": round(math.degrees(camera.pixel_rad) * 3600.0, 2),
            "distortion": "none" if not camera.distorted else ", ".join(
                f"{k}={v:g}" for k, v in zip(("k1", "k2", "p1", "p2", "k3"), camera.distortion, strict=True) if v),
            "source": camera.source}
