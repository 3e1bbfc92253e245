"""Centroid extraction: star positions, fluxes and magnitudes from an image.

One function, :func:`extract`, does the whole chain a star tracker runs before identification:

1. **background**: a smooth background map (SExtractor's mesh of sigma-clipped modes) and its
   global rms;
2. **threshold**: pixels of the PSF-filtered, background-subtracted image brighter than
   ``threshold_sigma`` x rms;
3. **connected components** of at least ``min_area_px`` pixels, deblended when two stars
   touch; a component whose brightest pixel stands alone (a hot pixel or a cosmic ray, which
   the detection filter spreads over several pixels) is dropped;
4. **intensity-weighted centroids** over each component (the first moments of the
   background-subtracted pixels), refined by SExtractor's windowed (Gaussian-weighted)
   centroid when ``windowed`` is set;
5. **flux** in a circular aperture of radius ``aperture_sigmas`` x the PSF sigma, and
   ``mag = zero_point_mag - 2.5 log10(flux)`` (``zero_point_mag`` is the magnitude of a source
   of 1 ADU in total; 0 gives instrumental magnitudes).

With the ``sep`` package installed (SExtractor's core as a library, ``pip install
'starid-bench[images]'``) every step is SExtractor's; without it a plain scipy.ndimage version of
the same steps runs (``method="scipy"`` forces it). docs/images.md compares the two on
rendered images.

Positions follow starid's convention: pixel ``(0, 0)`` is the top-left *corner* of the image,
so the centre of the first pixel is ``(0.5, 0.5)`` (SExtractor's is ``(0, 0)``: 0.5 is added).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ConfigError, ObservationError
from .params import check_choice, check_flag, check_number, check_whole

METHODS = ("auto", "sep", "scipy")


def sep_available() -> bool:
    """True when the ``sep`` package can be imported."""
    try:
        import sep  # noqa: F401
    except ImportError:
        return False
    return True


def _as_image(image) -> np.ndarray:
    try:
        data = np.asarray(image, dtype=np.float64)
    except (TypeError, ValueError):
        raise ObservationError("the image must be a numeric 2-D array") from None
    if data.ndim != 2:
        raise ObservationError(f"the image must be a 2-D (grey) array, got shape {data.shape}")
    if data.shape[0] < 8 or data.shape[1] < 8:
        raise ObservationError(f"the image is too small for star extraction: {data.shape[1]}x{data.shape[0]} px")
    if not np.all(np.isfinite(data)):
        raise ObservationError("the image has non-finite pixels (NaN or inf)")
    return np.ascontiguousarray(data)


def _gauss_kernel(sigma_px: float) -> np.ndarray:
    r = max(1, int(math.ceil(2.0 * sigma_px)))
    t = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (t / sigma_px) ** 2)
    k = np.outer(g, g)
    return k / k.sum()


def _extract_sep(data, threshold_sigma, min_area_px, psf_sigma_px, windowed, aperture_px, max_stars):
    import sep

    bw = int(min(64, max(8, min(data.shape) // 4)))
    bkg = sep.Background(data, bw=bw, bh=bw, fw=3, fh=3)
    sub = data - bkg.back()
    rms = float(bkg.globalrms)
    if not math.isfinite(rms) or rms <= 0:
        rms = float(np.std(sub)) or 1.0
    sep.set_extract_pixstack(max(300_000, data.size // 2))
    sep.set_sub_object_limit(4096)
    try:
        objects = sep.extract(sub, threshold_sigma, err=rms, minarea=min_area_px,
                              filter_kernel=_gauss_kernel(psf_sigma_px), deblend_nthresh=32, deblend_cont=0.005)
    except Exception as exc:   # sep raises plain Exceptions (e.g. object or pixel stack overflow)
        raise ObservationError(f"centroid extraction failed: {exc}") from None
    if objects.size > max_stars:   # keep the brightest (a noise image can give thousands)
        objects = objects[np.argsort(-objects["flux"], kind="stable")[:max_stars]]
    x = np.asarray(objects["x"], dtype=np.float64)
    y = np.asarray(objects["y"], dtype=np.float64)
    if x.size and windowed:
        xw, yw, flag = sep.winpos(sub, x, y, psf_sigma_px)
        ok = (flag == 0) & np.isfinite(xw) & np.isfinite(yw) & (np.hypot(xw - x, yw - y) < 2.0 * psf_sigma_px)
        x = np.where(ok, xw, x)
        y = np.where(ok, yw, y)
    if x.size:
        flux, _, _ = sep.sum_circle(sub, x, y, aperture_px, err=rms, subpix=5)
        flux = np.asarray(flux, dtype=np.float64)
    else:
        flux = np.zeros(0)
    return x + 0.5, y + 0.5, flux, sub


def _background_scipy(data: np.ndarray) -> tuple[np.ndarray, float]:
    """A coarse background map: sigma-clipped medians of 32 px cells, smoothed, bilinearly resampled."""
    from scipy import ndimage

    h, w = data.shape
    cell = int(min(32, max(8, min(h, w) // 4)))
    ny, nx = -(-h // cell), -(-w // cell)
    pad = np.pad(data, ((0, ny * cell - h), (0, nx * cell - w)), mode="edge")
    blocks = pad.reshape(ny, cell, nx, cell).transpose(0, 2, 1, 3).reshape(ny, nx, -1)
    med = np.median(blocks, axis=2)
    mad = np.median(np.abs(blocks - med[..., None]), axis=2)
    for _ in range(2):   # clip stars out of each cell
        keep = np.abs(blocks - med[..., None]) <= 3.0 * 1.4826 * mad[..., None] + 1e-12
        masked = np.where(keep, blocks, np.nan)
        med = np.nanmedian(masked, axis=2)
    med = ndimage.median_filter(med, size=3, mode="nearest")
    yy = (np.arange(h) + 0.5) / cell - 0.5
    xx = (np.arange(w) + 0.5) / cell - 0.5
    back = ndimage.map_coordinates(med, np.meshgrid(yy, xx, indexing="ij"), order=1, mode="nearest")
    resid = data - back
    rms = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    return back, rms if rms > 0 else (float(np.std(resid)) or 1.0)


def _extract_scipy(data, threshold_sigma, min_area_px, psf_sigma_px, windowed, aperture_px, max_stars):
    from scipy import ndimage

    back, rms = _background_scipy(data)
    sub = data - back
    kernel = _gauss_kernel(psf_sigma_px)
    smooth = ndimage.convolve(sub, kernel, mode="nearest")
    # threshold in units of the rms of the *unfiltered* image, as SExtractor does with a filter
    mask = smooth > threshold_sigma * rms
    labels, n = ndimage.label(mask)
    if n == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0), sub
    index = np.arange(1, n + 1)
    area = ndimage.sum_labels(np.ones_like(sub), labels, index)
    weights = np.clip(sub, 0.0, None)
    wsum = ndimage.sum_labels(weights, labels, index)
    keep = (area >= min_area_px) & (wsum > 0)
    index = index[keep]
    if index.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0), sub
    yy, xx = np.indices(sub.shape, dtype=np.float64)
    wsum = wsum[keep]
    x = ndimage.sum_labels(weights * xx, labels, index) / wsum
    y = ndimage.sum_labels(weights * yy, labels, index) / wsum
    if x.size > max_stars:
        order = np.argsort(-wsum, kind="stable")[:max_stars]
        x, y = x[order], y[order]
    # aperture flux (whole pixels within the radius of the centroid)
    r = int(math.ceil(aperture_px))
    off = np.arange(-r, r + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")
    ix = np.rint(x).astype(np.int64)[:, None, None] + ox
    iy = np.rint(y).astype(np.int64)[:, None, None] + oy
    inside = ((ix + 0.0 - x[:, None, None]) ** 2 + (iy + 0.0 - y[:, None, None]) ** 2 <= aperture_px ** 2)
    inside &= (ix >= 0) & (ix < sub.shape[1]) & (iy >= 0) & (iy < sub.shape[0])
    inside_px = sub[np.clip(iy, 0, sub.shape[0] - 1), np.clip(ix, 0, sub.shape[1] - 1)]
    flux = np.where(inside, inside_px, 0.0).sum(axis=(1, 2))
    return x + 0.5, y + 0.5, flux, sub


def _psf_neighbour_ratio(psf_sigma_px: float) -> float:
    """Mean of the 8 neighbours of a Gaussian's peak pixel over the peak (0.86 for sigma 2 px)."""
    s2 = psf_sigma_px * psf_sigma_px
    return 0.5 * (math.exp(-0.5 / s2) + math.exp(-1.0 / s2))


def _clean_hot_pixels(data: np.ndarray, psf_sigma_px: float) -> np.ndarray:
    """``data`` with lone bright pixels (5 rms above the median, neighbours below a quarter of what
    the PSF predicts) replaced by the mean of their 8 neighbours."""
    from scipy import ndimage

    sample = data[::4, ::4]
    level = float(np.median(sample))
    rms = 1.4826 * float(np.median(np.abs(sample - level))) or 1.0
    around = (ndimage.uniform_filter(data, 3, mode="nearest") * 9.0 - data) / 8.0
    peak = data - level
    hot = (peak > 5.0 * rms) & (around - level < 0.25 * _psf_neighbour_ratio(psf_sigma_px) * peak)
    if not hot.any():
        return data
    out = data.copy()
    out[hot] = around[hot]
    return out


def _sharp(sub: np.ndarray, x_px: np.ndarray, y_px: np.ndarray, psf_sigma_px: float) -> np.ndarray:
    """False for detections whose brightest pixel stands alone (a hot pixel or a cosmic ray).

    A star's brightest pixel has neighbours of a comparable level (for a Gaussian of sigma s the
    mean of the 8 neighbours is ``(e^(-1/2s^2) + e^(-1/s^2)) / 2`` of the peak: 0.86 at 2 px);
    a detection whose neighbours reach less than a quarter of that is refused.
    """
    if x_px.size == 0:
        return np.zeros(0, dtype=bool)
    h, w = sub.shape
    ix = np.clip(np.floor(x_px).astype(np.int64), 1, w - 2)
    iy = np.clip(np.floor(y_px).astype(np.int64), 1, h - 2)
    off = np.array([-1, 0, 1])
    # the brightest pixel of the 3x3 box around each centroid, then its 8 neighbours
    box = sub[iy[:, None, None] + off[None, :, None], ix[:, None, None] + off[None, None, :]].reshape(-1, 9)
    k = box.argmax(axis=1)
    py = np.clip(iy + k // 3 - 1, 1, h - 2)
    px = np.clip(ix + k % 3 - 1, 1, w - 2)
    nb = sub[py[:, None, None] + off[None, :, None], px[:, None, None] + off[None, None, :]].reshape(-1, 9)
    peak = nb[:, 4]
    around = (nb.sum(axis=1) - peak) / 8.0
    return ~((peak > 0) & (around < 0.25 * _psf_neighbour_ratio(psf_sigma_px) * peak))


def extract(image, *, threshold_sigma: float = 3.0, min_area_px: int = 5, psf_sigma_px: float = 2.0,
            zero_point_mag: float = 0.0, windowed: bool = True, aperture_sigmas: float = 3.0,
            max_stars: int = 2000, reject_hot_pixels: bool = True, method: str = "auto"):
    """Detect the stars of ``image`` and measure them.

    Parameters
    ----------
    image : 2-D array (rows = y, columns = x) of pixel values (ADU), any numeric dtype.
    threshold_sigma : detection threshold in units of the background rms (on the image filtered
        with a Gaussian of ``psf_sigma_px``).
    min_area_px : smallest component kept, in pixels above the threshold.
    psf_sigma_px : Gaussian sigma of the stars (px): the detection filter, the windowed centroid
        and the aperture radius follow it.
    zero_point_mag : magnitude of a source of 1 ADU in total (0 = instrumental magnitudes).
    windowed : refine the isophotal centroids with SExtractor's windowed centroid (sep only).
    aperture_sigmas : aperture radius for the flux, in units of ``psf_sigma_px``.
    max_stars : keep at most this many detections (the brightest).
    reject_hot_pixels : replace lone bright pixels (hot pixels, cosmic rays: 5 rms above the
        median, their 8 neighbours below a quarter of what the PSF predicts) by their neighbours'
        mean before detection, and drop detections whose brightest pixel still stands alone.
    method : ``"sep"``, ``"scipy"`` or ``"auto"`` (sep when installed).

    Returns
    -------
    ``(x_px, y_px, mag, flux)``: float64 arrays, brightest first, in starid's pixel convention;
    ``flux`` in ADU above the background. Detections with a non-positive aperture flux are
    dropped (no magnitude).
    """
    check_number("threshold_sigma", threshold_sigma, lo=0, lo_open=True)
    check_whole("min_area_px", min_area_px, 1)
    check_number("psf_sigma_px", psf_sigma_px, lo=0.1, hi=100)
    check_number("zero_point_mag", zero_point_mag)
    check_flag("windowed", windowed)
    check_number("aperture_sigmas", aperture_sigmas, lo=0.5, hi=20)
    check_whole("max_stars", max_stars, 1)
    check_flag("reject_hot_pixels", reject_hot_pixels)
    check_choice("method", method, METHODS)
    data = _as_image(image)
    if method == "auto":
        method = "sep" if sep_available() else "scipy"
    if method == "sep" and not sep_available():
        raise ConfigError("method='sep' needs the sep package: pip install 'starid-bench[images]'")
    run = _extract_sep if method == "sep" else _extract_scipy
    if reject_hot_pixels:
        data = _clean_hot_pixels(data, float(psf_sigma_px))
    x, y, flux, sub = run(data, float(threshold_sigma), int(min_area_px), float(psf_sigma_px), bool(windowed),
                     float(aperture_sigmas * psf_sigma_px), int(max_stars))
    h, w = data.shape
    ok = _sharp(sub, x - 0.5, y - 0.5, psf_sigma_px) if reject_hot_pixels else np.ones(x.size, dtype=bool)
    ok &= (flux > 0) & np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x < w) & (y >= 0) & (y < h)
    x, y, flux = x[ok], y[ok], flux[ok]
    order = np.lexsort((y, x, -flux))
    x, y, flux = x[order], y[order], flux[order]
    mag = zero_point_mag - 2.5 * np.log10(flux)
    return x, y, mag, flux


__all__ = ["METHODS", "extract", "sep_available"]
