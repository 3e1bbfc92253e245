import numpy as np
import pytest

from starid import Catalog, CatalogError, load_csv, load_hipparcos
from starid.catalog_build import build, hp_to_v, propagate_to_j2000


def test_embedded_catalog_counts(catalog):
    assert 40_000 <= len(catalog) <= 43_000
    assert catalog.v_mag.max() <= 8.0
    assert 4_900 <= len(catalog.brighter_than(6.0)) <= 5_200
    assert np.all(np.diff(catalog.hip) > 0)
    assert np.allclose(np.linalg.norm(catalog.unit_icrs, axis=1), 1.0)


@pytest.mark.parametrize("hip, ra_deg, dec_deg", [
    (32349, 101.2871553, -16.7161158),   # Sirius
    (91262, 279.2347348, 38.7836890),    # Vega
    (11767, 37.9545610, 89.2641090),     # Polaris
])
def test_j2000_positions_within_0p1_arcsec(catalog, hip, ra_deg, dec_deg):
    i = catalog.index_of([hip])[0]
    assert i >= 0
    expected = Catalog.from_arrays([1, 2, 3], [ra_deg, 0, 0], [dec_deg, 0, 1], [0, 0, 0]).unit_icrs[0]
    sep_arcsec = np.degrees(2 * np.arcsin(np.linalg.norm(catalog.unit_icrs[i] - expected) / 2)) * 3600
    assert sep_arcsec < 0.1


def test_bright_star_magnitudes(catalog):
    sirius, vega = catalog.index_of([32349, 91262])
    assert catalog.v_mag[vega] == pytest.approx(0.03, abs=0.1)
    # Hp saturates for the very brightest stars: Sirius comes out at -1.10 (V = -1.46), still the brightest.
    assert catalog.v_mag[sirius] == catalog.v_mag.min() < -1.0


def test_index_of_missing_is_minus_one(catalog):
    assert catalog.index_of([1, 10**9]).tolist()[1] == -1


def test_hp_to_v_transformation():
    assert hp_to_v(np.array([5.0]), np.array([0.0]))[0] == pytest.approx(5.0 - 0.00509)
    b_v = 1.0
    assert hp_to_v(np.array([5.0]), np.array([b_v]))[0] == pytest.approx(5.0 + 0.02994 + 0.08731 - 0.27173 - 0.00509)


def test_propagation_moves_along_proper_motion():
    ra, dec = propagate_to_j2000(np.array([0.0]), np.array([0.0]), np.array([1000.0]), np.array([0.0]), dt_yr=3600.0)
    # 1000 mas/yr * 3600 yr = 1 deg along the tangent plane, i.e. atan(1 deg in rad) on the sky
    assert ra[0] == pytest.approx(np.degrees(np.arctan(np.radians(1.0))), abs=1e-12)
    assert dec[0] == pytest.approx(0.0, abs=1e-12)
    ra, dec = propagate_to_j2000(np.array([1.0]), np.array([0.5]), np.array([0.0]), np.array([0.0]))
    assert ra[0] == pytest.approx(np.degrees(1.0)) and dec[0] == pytest.approx(np.degrees(0.5))


def test_build_from_hip2_format(tmp_path):
    line = ("{hip:6d}   5 0 1  {ra:.10f}  {dec:.10f}    4.55    -4.55    -1.19   1.29   0.66   1.33   1.25   0.75  90"
            "  0.91  0    0.0    0  {hp:.4f} 0.0020 0.017 0  {bv:.3f} {ebv:.3f}  0.550" + "   1.00" * 15)
    rows = [line.format(hip=1, ra=0.1, dec=0.2, hp=5.0, bv=0.5, ebv=0.01),
            line.format(hip=2, ra=0.3, dec=-0.2, hp=9.0, bv=0.5, ebv=0.01),     # too faint
            line.format(hip=3, ra=0.5, dec=0.4, hp=7.0, bv=0.0, ebv=0.0)]       # missing colour
    path = tmp_path / "hip2.dat"
    path.write_text("\n".join(rows) + "\n")
    out = build(path)
    assert out["hip"].tolist() == [1, 3]
    assert out["v_mag"][1] == pytest.approx(7.0 - 0.00509)


def _write(tmp_path, text):
    path = tmp_path / "cat.csv"
    path.write_text(text)
    return path


def test_load_csv_roundtrip(tmp_path):
    cat = load_csv(_write(tmp_path, "hip,ra_deg,dec_deg,vmag\n3,10,20,1.5\n1,30,-40,2.5\n2,50,60,3.5\n"))
    assert cat.hip.tolist() == [1, 2, 3]
    assert cat.v_mag.tolist() == [2.5, 3.5, 1.5]


def test_load_csv_accepts_id_column(tmp_path):
    assert len(load_csv(_write(tmp_path, "id,ra_deg,dec_deg,vmag\n1,0,0,1\n2,1,1,1\n3,2,2,2\n"))) == 3


@pytest.mark.parametrize("text, message", [
    ("ra_deg,dec_deg,vmag\n1,2,3\n", "missing column"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,3,4\n2,x,3,4\n", "line 3: non-numeric"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,3,4\n2,nan,3,4\n", "line 3: NaN"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,3,4\n2,3,4\n", "line 3: expected 4 fields"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,3,4\n1,3,4,5\n2,3,4,5\n", "appears more than once"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,95,4\n2,3,4,5\n3,3,4,5\n", "dec_deg must lie"),
    ("hip,ra_deg,dec_deg,vmag\n1,2,3,4\n", "at least 3 stars"),
    ("", "empty file"),
])
def test_load_csv_rejects_malformed(tmp_path, text, message):
    with pytest.raises(CatalogError, match=message):
        load_csv(_write(tmp_path, text))


def test_from_arrays_rejects_mismatched_lengths():
    with pytest.raises(CatalogError, match="differ in length"):
        Catalog.from_arrays([1, 2, 3], [0, 1], [0, 1, 2], [1, 1, 1])


def test_load_hipparcos_cut():
    assert load_hipparcos(6.0).v_mag.max() <= 6.0
