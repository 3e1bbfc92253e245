"""starid.extract: both back ends find synthetic stars where they are, in starid's pixel convention."""

import math

import numpy as np
import pytest

from starid import ConfigError, ObservationError
from starid.extract import extract, sep_available
from starid.render import RenderConfig, render_image

METHODS = ["scipy", pytest.param("sep", marks=pytest.mark.skipif(not sep_available(), reason="sep not installed"))]


def _field(n=25, w=300, h=200, seed=0, hot=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(15, w - 15, n)
    y = rng.uniform(15, h - 15, n)
    keep = np.ones(n, dtype=bool)
    for i in range(n):   # no blends in this field
        d = np.hypot(x - x[i], y - y[i])
        d[i] = np.inf
        if keep[i] and (d[keep] < 15).any():
            keep[i] = False
    x, y = x[keep], y[keep]
    v_mag = rng.uniform(2.0, 5.0, x.size)
    cfg = RenderConfig(hot_pixels=hot)
    img = render_image(x, y, cfg.signal_e(v_mag), w, h, cfg, np.random.default_rng(seed + 1))
    return img, x, y, v_mag, cfg


@pytest.mark.parametrize("method", METHODS)
def test_finds_every_star_at_its_position(method):
    img, x, y, v_mag, cfg = _field()
    ex, ey, mag, flux = extract(img, method=method, zero_point_mag=cfg.adu_zero_point_mag)
    assert ex.size == x.size
    d = np.hypot(ex[:, None] - x[None, :], ey[:, None] - y[None, :])
    nearest = d.argmin(axis=1)
    assert np.sort(nearest).tolist() == list(range(x.size))             # one detection per star
    err = d[np.arange(ex.size), nearest]
    assert math.sqrt((err ** 2).mean()) < 0.15                            # bright stars: sub-0.15 px
    assert np.all(np.diff(flux) <= 0)                                     # brightest first
    assert np.median(np.abs(mag - v_mag[nearest])) < 0.1                  # calibrated magnitudes


@pytest.mark.parametrize("method", METHODS)
def test_hot_pixels_and_empty_images_give_no_star(method):
    img, x, y, *_ = _field(hot=40)
    assert extract(img, method=method, reject_hot_pixels=False)[0].size > x.size + 20   # the filter spreads them
    ex, ey, *_ = extract(img, method=method)
    # every hot pixel refused; a star whose peak a hot pixel hit may go with it
    assert x.size - 1 <= ex.size <= x.size
    assert np.hypot(ex[:, None] - x[None, :], ey[:, None] - y[None, :]).min(axis=1).max() < 1.0
    cfg = RenderConfig(hot_pixels=30)
    empty = render_image(np.zeros(0), np.zeros(0), np.zeros(0), 256, 192, cfg, np.random.default_rng(3))
    assert extract(empty, method=method)[0].size == 0
    flat = np.full((64, 64), 1000, dtype=np.uint16)
    out = extract(flat, method=method)
    assert all(a.size == 0 and a.dtype == np.float64 for a in out)


def test_sep_and_scipy_agree():
    if not sep_available():
        pytest.skip("sep not installed")
    img, *_ = _field(seed=4)
    a = extract(img, method="sep")
    b = extract(img, method="scipy")
    assert a[0].size == b[0].size
    d = np.hypot(a[0][:, None] - b[0][None, :], a[1][:, None] - b[1][None, :]).min(axis=1)
    assert d.max() < 0.3


def test_bad_input_is_refused():
    with pytest.raises(ObservationError):
        extract(np.zeros((10, 10, 3)))
    with pytest.raises(ObservationError):
        extract(np.zeros((4, 4)))
    with pytest.raises(ObservationError):
        extract(np.full((20, 20), np.nan))
    with pytest.raises(ConfigError):
        extract(np.zeros((20, 20)), threshold_sigma=0)
    with pytest.raises(ConfigError):
        extract(np.zeros((20, 20)), method="magic")
