"""Image files end to end: ``starid render`` -> TIFF (8/16-bit), FITS, PNG, JPEG -> ``starid identify``
(square and non-square, field of view 3 % off, star-less and unreadable images)."""

import math

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("tifffile")
pytest.importorskip("astropy")
pytest.importorskip("PIL")

from starid import Camera, ObservationError, SimConfig, Simulator  # noqa: E402
from starid.attitude import random_attitude, rotation_angle_rad  # noqa: E402
from starid.cli import main  # noqa: E402
from starid.cli.images import ATTITUDE_COLUMNS, attitude_from_ra_dec_roll, ra_dec_roll_deg  # noqa: E402
from starid.imagefile import read_image, to_8bit, write_image  # noqa: E402
from starid.scoring import RAD_TO_ARCSEC  # noqa: E402


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Trial 3 (seed 11) as TIFF 16/8-bit, FITS, PNG; trial 4 at 1024x768 as PNG."""
    d = tmp_path_factory.mktemp("img")
    files = {}
    for name, extra in (("t16.tiff", []), ("t8.tiff", ["--bits", "8"]), ("t.fits", []), ("t.png", [])):
        assert main(["render", "--trial", "3", "--seed", "11", "--out", str(d / name), *extra]) == 0
        files[name] = d / name
    assert main(["render", "--trial", "4", "--seed", "11", "--size", "1024x768", "--fov-deg", "10",
                 "--out", str(d / "wide.png")]) == 0
    files["wide.png"] = d / "wide.png"
    return d, files


def _truth(trial, camera=None):
    from starid import load_hipparcos

    return Simulator(load_hipparcos(), camera or Camera(), SimConfig(), seed=11).draw(trial)[0]


def _attitude_error_arcsec(row):
    """(boresight error, whole-rotation error) in arcsec; roll about the boresight is the weak axis."""
    est = attitude_from_ra_dec_roll(row.ra_deg, row.dec_deg, row.roll_deg)
    boresight = math.acos(min(1.0, float(est[2] @ row.true[2]))) * RAD_TO_ARCSEC
    return boresight, rotation_angle_rad(est, row.true) * RAD_TO_ARCSEC


def test_every_format_and_shape_solves(rendered, tmp_path, capsys):
    d, files = rendered
    out = tmp_path / "ids"
    names = ["t16.tiff", "t8.tiff", "t.fits", "t.png", "wide.png"]
    assert main(["identify", "ptp", *[str(files[n]) for n in names], "--fov-deg", "10", "--out", str(out)]) == 0
    att = pd.read_csv(out / "attitudes.csv")
    assert list(att.columns) == ATTITUDE_COLUMNS and len(att) == len(names)
    assert (att["status"] == "solved").all(), att
    wide = Camera.from_fov(10.0)
    wide = Camera(1024, 768, wide.pixel_um, wide.focal_mm)
    att["true"] = [_truth(3)] * 4 + [_truth(4, wide)]
    err = np.array([_attitude_error_arcsec(r) for r in att.itertuples()])
    assert (err[:, 0] < 30).all() and (err[:, 1] < 300).all(), err    # a 35 arcsec pixel
    assert (att["residual_arcsec"] < 30).all() and (att["n_identified"] >= 6).all()
    ids = pd.read_csv(out / "identifications.csv")
    assert {"image", "algorithm", "star", "x_px", "y_px", "mag", "hip"} <= set(ids.columns)
    pngs = sorted(p.name for p in out.glob("*.annotated.png"))
    assert pngs == ["t16.annotated.png", "t8.annotated.png", "t_fits.annotated.png", "t_png.annotated.png",
                    "wide.annotated.png"], pngs
    assert "solved" in capsys.readouterr().out


@pytest.mark.parametrize("fov", [9.7, 10.3])
def test_field_of_view_three_percent_off_still_solves(rendered, tmp_path, fov):
    d, files = rendered
    out = tmp_path / "ids"
    assert main(["identify", "pvector", str(files["t16.tiff"]), "--fov-deg", str(fov), "--out", str(out)]) == 0
    att = pd.read_csv(out / "attitudes.csv")
    assert att["status"].tolist() == ["solved"]
    att["true"] = [_truth(3)]
    assert _attitude_error_arcsec(next(att.itertuples()))[0] < 60
    # without the focal-length search the wrong scale is not solved (or solved badly)
    assert main(["identify", "pvector", str(files["t16.tiff"]), "--fov-deg", str(fov), "--fov-search-pct", "0",
                 "--out", str(out)]) == 0
    att = pd.read_csv(out / "attitudes.csv")
    assert att["status"].iloc[0] == "not solved" or att["residual_arcsec"].iloc[0] > 100


def test_starless_image_is_not_solved(tmp_path, capsys):
    rng = np.random.default_rng(0)
    noise = np.clip(rng.normal(300, 14, (600, 800)), 0, 65535).astype(np.uint16)
    write_image(tmp_path / "dark.tiff", noise)
    out = tmp_path / "ids"
    assert main(["identify", "ptp", "pvector", str(tmp_path / "dark.tiff"), "--fov-deg", "10", "--out", str(out)]) == 0
    att = pd.read_csv(out / "attitudes.csv")
    assert att["status"].tolist() == ["not solved", "not solved"] and (att["n_identified"] == 0).all()
    assert (out / "dark.annotated.png").exists()


def test_unreadable_and_unsupported_files_are_refused(tmp_path, capsys):
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png at all")
    out = tmp_path / "ids"
    assert main(["identify", "ptp", str(bad), "--fov-deg", "10", "--out", str(out)]) == 2
    assert "bad.png" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ObservationError, match="unsupported"):
        read_image(tmp_path / "x.bmp")
    with pytest.raises(ObservationError, match="no such file"):
        read_image(tmp_path / "missing.fits")
    good = tmp_path / "g.tiff"
    write_image(good, np.zeros((20, 20), dtype=np.uint16))
    assert main(["identify", "ptp", str(good), "--fov-range", "12:9", "--out", str(out)]) == 2   # a bad range
    assert "--fov-range" in capsys.readouterr().err and not out.exists()


def test_readers_round_trip_and_colour(tmp_path):
    img = (np.arange(48 * 64, dtype=np.uint32).reshape(48, 64) * 17 % 65536).astype(np.uint16)
    for name in ("a.tiff", "a.fits", "a.png"):
        write_image(tmp_path / name, img)
        back = read_image(tmp_path / name)
        assert back.shape == (48, 64) and np.array_equal(back, img.astype(float)), name
    from PIL import Image

    rgb = np.zeros((30, 40, 3), dtype=np.uint8)
    rgb[..., 1] = 100
    Image.fromarray(rgb).save(tmp_path / "c.jpg", quality=100)
    Image.fromarray(rgb).save(tmp_path / "c.png")
    assert np.allclose(read_image(tmp_path / "c.png"), 71.52)
    assert np.allclose(read_image(tmp_path / "c.jpg"), 71.52, atol=1.5)
    eight = to_8bit(np.random.default_rng(0).normal(300, 14, (64, 64)))
    assert eight.dtype == np.uint8 and 3 < eight.mean() < 12 and 2.0 < eight.std() < 4.0


def test_ra_dec_roll_convention():
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = random_attitude(rng)
        ra, dec, roll = ra_dec_roll_deg(a)
        assert np.allclose(attitude_from_ra_dec_roll(ra, dec, roll), a, atol=1e-9)
        b = a[2]
        assert math.isclose(math.degrees(math.asin(b[2])), dec, abs_tol=1e-9)


def test_roll_zero_puts_north_down_and_east_right():
    def unit(ra, dec):
        ra, dec = math.radians(ra), math.radians(dec)
        return np.array([math.cos(dec) * math.cos(ra), math.cos(dec) * math.sin(ra), math.sin(dec)])

    a = attitude_from_ra_dec_roll(30.0, 20.0, 0.0)
    north, east = a @ unit(30.0, 20.5), a @ unit(30.5, 20.0)
    assert north[1] > 0 and abs(north[0]) < 1e-9 and east[0] > 0
    assert np.allclose(ra_dec_roll_deg(a), (30.0, 20.0, 0.0), atol=1e-9)
