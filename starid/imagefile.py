"""Star images as files: read FITS, TIFF (8/16-bit), PNG and JPEG; write TIFF, FITS and PNG.

Readers (``pip install 'starid-bench[images]'``): FITS through astropy (the first HDU holding a 2-D
image, or a 3-plane colour cube), TIFF through tifffile, PNG and JPEG through Pillow. Every
image comes back as a float64 ``(height, width)`` array of pixel values, rows = y (top row
first, as the file stores it): colour images become their luminance ``0.2126 R + 0.7152 G +
0.0722 B`` (Rec. 709 weights on the stored values), an alpha channel is dropped, FITS pixels
that are NaN (blank) take the median of the others. A file that cannot be read, or holds no
2-D image, raises :class:`starid.ObservationError` naming the file.

Writers take a uint16 (or uint8) image (:mod:`starid.render`) and write it losslessly; with
``bits=8`` a 16-bit image is first stretched to 8 bits by :func:`to_8bit`. FITS is always
16-bit. Files are written atomically.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .errors import ConfigError, ObservationError
from .io import atomic_write_bytes

FITS_SUFFIXES = (".fits", ".fit", ".fts")
TIFF_SUFFIXES = (".tif", ".tiff")
PIL_SUFFIXES = (".png", ".jpg", ".jpeg")
#: Every suffix :func:`read_image` accepts (lower case).
IMAGE_SUFFIXES = FITS_SUFFIXES + TIFF_SUFFIXES + PIL_SUFFIXES
#: Suffixes :func:`write_image` writes.
WRITE_SUFFIXES = FITS_SUFFIXES + TIFF_SUFFIXES + (".png",)
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def is_image_file(path) -> bool:
    """True when ``path``'s suffix is one :func:`read_image` reads (by name only)."""
    return Path(str(path)).suffix.lower() in IMAGE_SUFFIXES


def _need(module: str, package: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ObservationError(f"reading and writing image files needs {package}: pip install 'starid-bench[images]'") \
            from None


def _to_grey(data: np.ndarray, path: Path) -> np.ndarray:
    data = np.asarray(data)
    if data.dtype.kind not in "uif" and data.dtype != np.bool_:
        raise ObservationError(f"{path}: unsupported pixel type {data.dtype}")
    data = data.astype(np.float64)
    data = np.squeeze(data)
    if data.ndim == 3:
        if data.shape[-1] in (3, 4) and data.shape[0] > 4:        # (h, w, RGB[A])
            data = data[..., :3] @ LUMINANCE
        elif data.shape[0] in (3, 4) and data.shape[-1] > 4:      # planar (RGB[A], h, w)
            data = np.tensordot(LUMINANCE, data[:3], axes=1)
        elif data.shape[-1] == 2:                                  # grey + alpha
            data = data[..., 0]
    if data.ndim != 2:
        raise ObservationError(f"{path}: not a 2-D image (array shape {data.shape})")
    if data.shape[0] < 8 or data.shape[1] < 8:
        raise ObservationError(f"{path}: image too small ({data.shape[1]}x{data.shape[0]} px)")
    bad = ~np.isfinite(data)
    if bad.any():
        if bad.all():
            raise ObservationError(f"{path}: every pixel is blank (NaN)")
        data[bad] = np.median(data[~bad])
    return data


def _read_fits(path: Path) -> np.ndarray:
    fits = _need("astropy.io.fits", "astropy")
    try:
        with fits.open(path, memmap=False) as hdul:
            for hdu in hdul:
                data = getattr(hdu, "data", None)
                if data is not None and getattr(data, "ndim", 0) >= 2 and data.dtype.fields is None:
                    return np.array(data)
    except (OSError, ValueError, TypeError, IndexError) as exc:
        raise ObservationError(f"{path}: not a readable FITS file ({exc})") from None
    raise ObservationError(f"{path}: the FITS file holds no image")


def _read_tiff(path: Path) -> np.ndarray:
    tifffile = _need("tifffile", "tifffile")
    try:
        return tifffile.imread(path)
    except Exception as exc:   # tifffile raises TiffFileError, ValueError, ... on bad files
        raise ObservationError(f"{path}: not a readable TIFF file ({exc})") from None


def _read_pil(path: Path) -> np.ndarray:
    Image = _need("PIL.Image", "Pillow")
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode == "P":
                im = im.convert("RGB")
            elif im.mode in ("I;16", "I;16B", "I;16L"):
                return np.array(im, dtype=np.uint16)
            return np.array(im)
    except (OSError, ValueError, SyntaxError) as exc:
        raise ObservationError(f"{path}: not a readable image ({exc})") from None


def read_image(path) -> np.ndarray:
    """The image in ``path`` as a float64 ``(height, width)`` grey array (see the module)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise ObservationError(f"{path}: unsupported image type {suffix or '(no suffix)'}; "
                               f"starid reads {', '.join(IMAGE_SUFFIXES)}")
    if not path.is_file():
        raise ObservationError(f"{path}: no such file")
    if suffix in FITS_SUFFIXES:
        data = _read_fits(path)
    elif suffix in TIFF_SUFFIXES:
        data = _read_tiff(path)
    else:
        data = _read_pil(path)
    return _to_grey(data, path)


def to_8bit(image: np.ndarray) -> np.ndarray:
    """A linear stretch to uint8: the background median minus 2 rms -> 0, 3 counts per rms.

    Keeps faint stars above the quantisation (a plain ``>> 8`` would leave the sky and most
    stars at 0); stars brighter than about 85 rms above the sky clip at 255.
    """
    data = np.asarray(image, dtype=np.float64)
    sample = data[::4, ::4] if min(data.shape) >= 32 else data
    level = float(np.median(sample))
    rms = 1.4826 * float(np.median(np.abs(sample - level))) or 1.0
    lo = level - 2.0 * rms
    return np.clip(np.rint((data - lo) * (3.0 / rms)), 0, 255).astype(np.uint8)


def write_image(path, image: np.ndarray, bits: int = 16) -> Path:
    """Write ``image`` (uint16 or uint8, rows = y) as TIFF, FITS or PNG, chosen by the suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_SUFFIXES:
        raise ConfigError(f"cannot write {path}: the suffix must be one of {', '.join(WRITE_SUFFIXES)}")
    if bits not in (8, 16):
        raise ConfigError(f"bits must be 8 or 16, got {bits!r}")
    data = np.asarray(image)
    if data.ndim != 2:
        raise ConfigError(f"write_image needs a 2-D image, got shape {data.shape}")
    if suffix in FITS_SUFFIXES:
        bits = 16
    if bits == 8:
        data = data.astype(np.uint8) if data.dtype == np.uint8 else to_8bit(data)
    else:
        data = np.clip(data, 0, 65535).astype(np.uint16)
    buf = io.BytesIO()
    if suffix in TIFF_SUFFIXES:
        tifffile = _need("tifffile", "tifffile")
        tifffile.imwrite(buf, data, photometric="minisblack")
    elif suffix in FITS_SUFFIXES:
        fits = _need("astropy.io.fits", "astropy")
        hdu = fits.PrimaryHDU(data)
        hdu.header["CREATOR"] = "starid render"
        hdu.writeto(buf)
    else:
        Image = _need("PIL.Image", "Pillow")
        Image.fromarray(data).save(buf, format="PNG")
    atomic_write_bytes(path, buf.getvalue())
    return path


__all__ = ["IMAGE_SUFFIXES", "WRITE_SUFFIXES", "is_image_file", "read_image", "to_8bit", "write_image"]
