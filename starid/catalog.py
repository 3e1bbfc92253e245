"""Star catalogs as structs of numpy arrays.

The embedded catalog (``starid/data/hipparcos_v8.npz``) holds every Hipparcos star with
V <= 8.0 (41,225 stars), built by :mod:`starid.catalog_build` from ESA's Hipparcos new
reduction (I/311, ``hip2.dat``): positions propagated from J1991.25 to J2000.0 (ICRS) with the
proper motions, and Johnson V derived from Hp and B-V (see :mod:`starid.catalog_build`).
The HIP number is the catalog id everywhere in starid.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import CatalogError, StarIDWarning
from .io import read_numeric_csv

EMBEDDED_CATALOG = "hipparcos_v8.npz"


def radec_to_unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    """ICRS unit vectors ``(n, 3)``: ``(cos d cos a, cos d sin a, sin d)``."""
    ra = np.radians(np.asarray(ra_deg, dtype=np.float64))
    dec = np.radians(np.asarray(dec_deg, dtype=np.float64))
    cos_dec = np.cos(dec)
    return np.ascontiguousarray(np.stack([cos_dec * np.cos(ra), cos_dec * np.sin(ra), np.sin(dec)], axis=-1))


@dataclass(frozen=True, eq=False)
class Catalog:
    """A star catalog: one entry per star, sorted by id.

    Attributes
    ----------
    hip : int64 (n,) catalog ids (HIP numbers for the embedded catalog), unique, positive.
    ra_deg, dec_deg : float64 (n,) J2000.0 ICRS right ascension and declination in degrees.
    v_mag : float64 (n,) visual magnitude.
    unit_icrs : float64 (n, 3) unit vectors in the ICRS frame.
    name : a label saying where the catalog came from.
    """

    hip: np.ndarray
    ra_deg: np.ndarray
    dec_deg: np.ndarray
    v_mag: np.ndarray
    unit_icrs: np.ndarray
    name: str = "custom"

    @classmethod
    def from_arrays(cls, hip, ra_deg, dec_deg, v_mag, name: str = "custom") -> Catalog:
        """Validate and build a catalog; rows are sorted by id."""
        hip_in = np.asarray(hip).ravel()
        try:
            hip_f = np.asarray(hip, dtype=np.float64).ravel()
            ra = np.asarray(ra_deg, dtype=np.float64).ravel()
            dec = np.asarray(dec_deg, dtype=np.float64).ravel()
            mag = np.asarray(v_mag, dtype=np.float64).ravel()
        except (TypeError, ValueError) as exc:
            raise CatalogError(f"catalog columns must be numeric: {exc}") from None
        n = hip_f.size
        if not (ra.size == dec.size == mag.size == n):
            raise CatalogError(f"catalog columns differ in length: hip {n}, ra_deg {ra.size}, "
                               f"dec_deg {dec.size}, v_mag {mag.size}")
        if n < 3:
            raise CatalogError(f"a catalog needs at least 3 stars, got {n}")
        for label, col in (("hip", hip_f), ("ra_deg", ra), ("dec_deg", dec), ("v_mag", mag)):
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                raise CatalogError(f"catalog column {label} has non-finite values (first at row {bad[0]})")
        if np.any(hip_f != np.round(hip_f)) or np.any(hip_f <= 0):
            bad = np.flatnonzero((hip_f != np.round(hip_f)) | (hip_f <= 0))[0]
            raise CatalogError(f"catalog ids must be positive integers (row {bad}: {hip_f[bad]!r})")
        bad = np.flatnonzero((dec < -90) | (dec > 90))
        if bad.size:
            raise CatalogError(f"dec_deg must lie in [-90, 90] (row {bad[0]}: {dec[bad[0]]!r})")
        bad = np.flatnonzero((ra < 0) | (ra >= 360))
        if bad.size:
            raise CatalogError(f"ra_deg must lie in [0, 360) (row {bad[0]}: {ra[bad[0]]!r})")
        ids = hip_in.astype(np.int64) if np.issubdtype(hip_in.dtype, np.integer) else hip_f.astype(np.int64)
        order = np.argsort(ids, kind="stable")
        ids = ids[order]
        dup = np.flatnonzero(np.diff(ids) == 0)
        if dup.size:
            raise CatalogError(f"catalog id {ids[dup[0]]} appears more than once")
        ra, dec, mag = ra[order], dec[order], mag[order]
        return cls(hip=ids, ra_deg=ra, dec_deg=dec, v_mag=mag, unit_icrs=radec_to_unit(ra, dec), name=name)

    @classmethod
    def embedded(cls, max_v_mag: float = 8.0) -> Catalog:
        """The embedded Hipparcos catalog (see :func:`load_hipparcos`)."""
        return load_hipparcos(max_v_mag)

    def to_frame(self):
        """The catalog as a pandas DataFrame (``hip, ra_deg, dec_deg, v_mag``)."""
        import pandas as pd

        return pd.DataFrame({"hip": self.hip, "ra_deg": self.ra_deg, "dec_deg": self.dec_deg, "v_mag": self.v_mag})

    def __len__(self) -> int:
        return int(self.hip.size)

    def subset(self, mask_or_index: np.ndarray, name: str | None = None) -> Catalog:
        """The stars selected by a boolean mask or an index array (kept in id order)."""
        sel = np.asarray(mask_or_index)
        if sel.dtype == bool:
            sel = np.flatnonzero(sel)
        sel = np.sort(sel)
        return Catalog(hip=self.hip[sel], ra_deg=self.ra_deg[sel], dec_deg=self.dec_deg[sel],
                       v_mag=self.v_mag[sel], unit_icrs=self.unit_icrs[sel],
                       name=name or self.name)

    def brighter_than(self, limit_mag: float) -> Catalog:
        """Stars with ``v_mag <= limit_mag``."""
        return self.subset(self.v_mag <= limit_mag, name=f"{self.name}[V<={limit_mag:g}]")

    def index_of(self, hip: np.ndarray) -> np.ndarray:
        """Row index of each id, or -1 where the id is not in the catalog."""
        hip = np.asarray(hip, dtype=np.int64)
        pos = np.searchsorted(self.hip, hip)
        pos_clipped = np.minimum(pos, len(self) - 1)
        found = (pos < len(self)) & (self.hip[pos_clipped] == hip)
        return np.where(found, pos_clipped, -1)

    @property
    def nbytes(self) -> int:
        return int(self.hip.nbytes + self.ra_deg.nbytes + self.dec_deg.nbytes + self.v_mag.nbytes
                   + self.unit_icrs.nbytes)


@lru_cache(maxsize=4)
def load_hipparcos(max_v_mag: float = 8.0) -> Catalog:
    """The embedded Hipparcos catalog (V <= 8.0), optionally cut to ``v_mag <= max_v_mag``."""
    with resources.files("starid.data").joinpath(EMBEDDED_CATALOG).open("rb") as fh:
        with np.load(fh, allow_pickle=False) as data:
            cat = Catalog.from_arrays(data["hip"], data["ra_deg"], data["dec_deg"], data["v_mag"],
                                      name="hipparcos")
    if max_v_mag < 8.0:
        cat = cat.brighter_than(max_v_mag)
    return cat


def load_csv(path: str | Path) -> Catalog:
    """Load a user catalog from CSV with columns ``hip`` (or ``id``), ``ra_deg``, ``dec_deg``, ``vmag``.

    Positions are J2000.0 ICRS degrees. Malformed rows raise :class:`CatalogError` naming the
    line number.
    """
    path = Path(path)
    cols, lines = read_numeric_csv(path, [("hip", "id"), "ra_deg", "dec_deg", "vmag"], error=CatalogError,
                                   lower=True, integer=("hip", "id"))
    if not lines.size:
        raise CatalogError(f"{path}: no stars")
    ids = cols["hip"] if "hip" in cols else cols["id"]
    if len(ids) >= 20 and np.abs(cols["ra_deg"]).max() <= 2 * np.pi + 1e-9 \
            and np.abs(cols["dec_deg"]).max() <= np.pi / 2 + 1e-9:
        warnings.warn(f"{path}: every ra_deg is <= 2 pi and every dec_deg <= pi/2: are these radians? "
                      f"starid reads degrees", StarIDWarning, stacklevel=2)
    try:
        return Catalog.from_arrays(ids, cols["ra_deg"], cols["dec_deg"], cols["vmag"], name=path.name)
    except CatalogError as exc:
        raise CatalogError(f"{path}: {exc}") from None
