"""``starid new-plugin NAME``: a new, installable algorithm package that already works.

:func:`new_plugin` writes a package folder (``pyproject.toml`` with the ``starid.algorithms`` entry
point, the algorithm class with declared parameters and a ``published`` dict, a numba kernel, an
``explain``, a tests file running the conformance suite through :func:`starid.testing.check_algorithm`,
a documentation page with the sections of a built-in page, a README). The algorithm is pair
voting (Kolomenkin et al., IEEE TAES 44(2), 2008: every observed pair votes for the catalog pairs
of the same angular separation), the docs/plugins.md example with its loop moved into one
kernel (``starid.kernels.jit.kernel``: ``@njit(cache=True, no_cfunc_wrapper=True)``, the flags every
built-in kernel uses); the author replaces the method and keeps the scaffolding.
"""

from __future__ import annotations

import keyword
import re
from pathlib import Path
from string import Template

from ..errors import ConfigError

NAME_RULE = re.compile(r"^[a-z][a-z0-9_]*$")


def class_name(name: str) -> str:
    """``pair_votes`` -> ``PairVotes``."""
    return "".join(part.capitalize() for part in name.split("_") if part)


def dist_name(name: str) -> str:
    """The distribution name: ``pair_votes`` -> ``starid-pair-votes``."""
    return "starid-" + name.replace("_", "-")


PYPROJECT = """\
[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "$dist"
version = "0.1.0"
description = "$cls: a star-identification plugin for starid (pair voting, Kolomenkin et al. 2008)"
readme = "README.md"
requires-python = ">=3.11"
dependencies = ["starid-bench", "numpy", "scipy", "numba"]

[project.optional-dependencies]
test = ["pytest"]

# starid finds the algorithm through this entry point: its name must equal the class's `name`
[project.entry-points."starid.algorithms"]
$name = "$name:$cls"

[tool.setuptools]
packages = ["$name"]

[tool.pytest.ini_options]
testpaths = ["tests"]
"""

INIT = '''\
"""$cls: a starid algorithm plugin (see algorithm.py)."""

from .algorithm import $cls, ${cls}Database

__all__ = ["$cls", "${cls}Database"]
'''

KERNELS = '''\
"""The numba kernel of $cls: pair voting over a k-vector of catalog chords."""

import numpy as np

from starid.kernels import chord, kvector_query
from starid.kernels.jit import kernel


@kernel
def vote(v_cam, kv, pair, n_guide, tol_chord, min_votes):
    """Per observed star the catalog row with most votes (-1 below ``min_votes``).

    Every observed pair (i, j) with chord c (``2 sin(theta / 2)``) looks up the catalog pairs with
    chord in [c - tol, c + tol] (Mortari's k-vector, O(1) per query); each such catalog pair
    (a, b) gives one vote to a and b for both i and j (Kolomenkin et al. 2008, section III).
    """
    n = v_cam.shape[0]
    votes = np.zeros((n, n_guide), dtype=np.int32)
    for i in range(n):
        for j in range(i + 1, n):
            c = chord(v_cam[i], v_cam[j])
            lo, hi = kvector_query(kv, c - tol_chord, c + tol_chord)
            for r in range(lo, hi):
                a = pair[r, 0]
                b = pair[r, 1]
                votes[i, a] += 1
                votes[i, b] += 1
                votes[j, a] += 1
                votes[j, b] += 1
    best = np.full(n, -1, dtype=np.int64)
    if n_guide == 0:
        return best
    for i in range(n):
        k = np.argmax(votes[i])
        if votes[i, k] >= min_votes:
            best[i] = k
    return best
'''

ALGORITHM = '''\
"""$cls: geometric voting on star pairs (Kolomenkin M., Pollak S., Shimshoni I., Lindenbaum M.,
"Geometric voting algorithm for star trackers", IEEE TAES 44(2), 2008), made by ``starid new-plugin``.

Replace the method (``build``, ``identify``, ``kernels.vote``) with yours; keep the contract:
parameters as dataclass fields with defaults (declared with ``starid.params.param``), a frozen
database of numpy arrays, ``identify`` returning one id or -1 per star in input order.
"""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

import starid
from starid.kernels import kvector_make, verify_pairwise
from starid.params import check_number, check_whole, param

from .kernels import vote


@dataclass(frozen=True, eq=False)
class ${cls}Database(starid.Database):
    """What ``identify`` reads: the k-vector over sorted catalog chords and the guide stars."""

    kv: object             # starid.kernels.KVector over the sorted chords of every guide-star pair
    pair: np.ndarray       # int64 (m, 2): guide rows of each pair, in chord order
    unit_icrs: np.ndarray  # float64 (g, 3): guide-star unit vectors, ICRS
    hip: np.ndarray        # int64 (g,): guide-star catalog ids


@dataclass(frozen=True)
class $cls(starid.Algorithm):
    """Pair voting (Kolomenkin et al., IEEE TAES 44(2), 2008), a starid plugin made by ``starid new-plugin``.

    Every observed pair votes for the catalog pairs of the same separation; each star takes the
    catalog star with most votes, and the proposals are kept when they agree pairwise
    (``starid.kernels.verify_pairwise``).
    """

    name: ClassVar[str] = "$name"
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}
    #: only identify reads sigma_px (build does not): one database serves every noise level
    query_only: ClassVar[tuple] = ("sigma_px",)
    #: the paper's plain vote: every star takes its best-voted catalog star, however few votes
    published: ClassVar[dict] = {"min_votes": 1}

    mag_limit: float = param(6.0, help="guide stars: catalog stars brighter than this", unit="mag")
    sigma_px: float | None = param(None, help="centroid noise the tolerances assume (None: the simulator's, "
                                              "at least 0.5 px)", unit="px")
    min_votes: int = param(2, help="fewest votes a star's best catalog star needs to be proposed")
    min_support: int = param(3, help="fewest agreeing partners a kept proposal needs (verification)")

    def __post_init__(self):
        check_number("mag_limit", self.mag_limit, 0.0, 12.0)
        if self.sigma_px is not None:
            check_number("sigma_px", self.sigma_px, 0.0, 10.0)
        check_whole("min_votes", self.min_votes, 1)
        check_whole("min_support", self.min_support, 2)

    def build(self, catalog, camera):
        guide = catalog.brighter_than(self.mag_limit)
        pair = cKDTree(guide.unit_icrs).query_pairs(2 * np.sin(camera.half_diagonal_rad), output_type="ndarray")
        pair = pair.astype(np.int64).reshape(-1, 2)
        chord = np.linalg.norm(guide.unit_icrs[pair[:, 0]] - guide.unit_icrs[pair[:, 1]], axis=1)
        order = np.argsort(chord, kind="stable")
        return ${cls}Database(kvector_make(chord[order]), np.ascontiguousarray(pair[order]),
                              np.ascontiguousarray(guide.unit_icrs), guide.hip.astype(np.int64))

    def _tolerance(self, camera) -> float:
        """Chord tolerance: 2 sigma, sigma at least 0.5 px, in radians (~ chord at small angles)."""
        return 2 * max(self.sigma_px or 0.0, 0.5) / camera.f_px

    def _proposals(self, db, observation):
        v = np.ascontiguousarray(observation.unit_cam())
        tol = self._tolerance(observation.camera)
        best = vote(v, db.kv, db.pair, len(db.hip), tol, self.min_votes)
        keep = verify_pairwise(v, best, db.unit_icrs, tol, self.min_support, 0.5)
        return np.where(keep, best, -1)

    def identify(self, db, observation):
        rows = self._proposals(db, observation)
        return starid.Identification(np.where(rows >= 0, db.hip[np.maximum(rows, 0)], -1).astype(np.int64))

    def explain(self, db, observation):
        """The kept stars joined in a closed outline (brightest order), each labelled with its HIP."""
        rows = self._proposals(db, observation)
        kept = np.flatnonzero(rows >= 0)
        xy = np.column_stack([observation.x_px, observation.y_px])[kept]
        seg = np.array([[xy[i], xy[j]] for i in range(len(kept)) for j in range(i + 1, len(kept))]).reshape(-1, 2, 2)
        caption = (f"{len(kept)} of {len(observation)} stars kept after voting and pairwise verification; "
                   f"every segment is a pair whose observed and catalog separations agree.")
        return starid.Explanation(segments=seg, points=xy, labels=tuple(str(h) for h in db.hip[rows[kept]]),
                                  caption=caption, highlight=np.arange(min(len(seg), 3)))
'''

TESTS = '''\
"""$cls: the starid conformance suite (one pytest case per check) and a noisy-image id rate."""

import pytest

import starid
from starid.testing import CHECKS, check_algorithm

from $name import $cls


@pytest.mark.parametrize("check", CHECKS)
def test_conformance(check):
    check_algorithm($cls, checks=[check])


def test_identifies_noisy_images():
    catalog = starid.Catalog.embedded()
    sim = starid.Simulator(catalog, starid.Camera(), starid.SimConfig(sigma_px=0.5, sigma_mag=0.3), seed=1)
    summary = starid.summarize(starid.run([$cls()], sim.generate(30), catalog, sim))
    # measured when generated: 60 % of these 30 images, none misidentified (a floor, not a target)
    assert summary["id_rate"].iloc[0] >= 0.4 and summary["misid_rate"].iloc[0] <= 0.05
'''

DOCS = '''\
# $cls — pair voting (`$name`)

Kolomenkin M., Pollak S., Shimshoni I., Lindenbaum M., "Geometric voting algorithm for star
trackers", *IEEE Transactions on Aerospace and Electronic Systems* 44(2), 2008. Code: `$name/`
(class `$cls`, kernel in `kernels.py`). Made by `starid new-plugin $name`: replace the method and
this page's text with yours, keep the headings.

| parameter | default | unit | meaning | paper or ours |
|---|---|---|---|---|
| `mag_limit` | 6.0 | mag | guide stars: catalog stars brighter than this | paper |
| `sigma_px` | None (the simulator's, at least 0.5 px) | px | centroid noise the tolerances assume | ours |
| `min_votes` | 2 (paper: 1) | | fewest votes a star's best catalog star needs | ours |
| `min_support` | 3 | | fewest agreeing partners a kept proposal needs | ours |

Measured: run the commands under "Measurements" and write the id rate, misidentification rate and
median time here.

## Method as implemented

Database: every pair of guide stars (V <= `mag_limit`) closer than the field's diagonal, stored by
its chord `2 sin(theta / 2)`, sorted, with a k-vector (`starid.kernels.kvector_make`).

Identification, one numba call (`kernels.vote`) per image: every observed pair looks up the
catalog pairs within `2 max(sigma_px, 0.5) / f_px` of its chord and votes for both of their stars;
each star proposes its best-voted catalog star (at least `min_votes` votes); the proposals are
kept when they agree pairwise (`starid.kernels.verify_pairwise`, at least `min_support` partners
and half the others).

## Paper versus reconstruction

The paper accepts each star's best vote (`published = {"min_votes": 1}`, the variant
`$name:paper`); the vote threshold is ours.

## Measurements

```sh
starid check $name
starid run $name ptp --trials 500 --pos-noise-px 1 --mag-noise 0.5
```
'''

README = '''\
# $dist

`$name`: a star-identification algorithm for [starid](https://pypi.org/project/starid-bench/),
made by `starid new-plugin $name`.

```sh
pip install -e .            # registers the entry point "$name" in the group starid.algorithms
starid list                 # $name  ok  Pair voting ...
starid check $name          # the conformance suite, one check at a time
python -m pytest            # the same suite, one pytest case per check, and an id-rate test
starid run $name ptp --trials 500 --pos-noise-px 1 --mag-noise 0.5
starid show $name ptp --trial 3 --out trial3.png
```

Files: `$name/algorithm.py` (the class: parameters, `build`, `identify`, `explain`),
`$name/kernels.py` (the numba kernel), `tests/test_$name.py`, `docs/$name.md` (the method page).
'''

FILES = {"pyproject.toml": PYPROJECT, "README.md": README, "$name/__init__.py": INIT,
         "$name/algorithm.py": ALGORITHM, "$name/kernels.py": KERNELS, "tests/test_$name.py": TESTS,
         "docs/$name.md": DOCS}


def new_plugin(name: str, out: str | Path | None = None) -> list[Path]:
    """Write the package of plugin ``name`` into ``out`` (default ``./NAME``); the files written.

    ``name`` is the algorithm's registered name and the import package (lower case letters, digits,
    ``_``); the distribution is ``starid-NAME`` (``_`` as ``-``). Refuses an existing non-empty
    folder and a name a built-in or Python already uses.
    """
    if not isinstance(name, str) or not NAME_RULE.match(name) or keyword.iskeyword(name):
        raise ConfigError(f"plugin name {name!r}: lower-case letters, digits and _, starting with a letter "
                          f"(it is the registered name and the Python package), e.g. my_voting")
    if name in ("starid", "starid_algorithms", "test", "tests", "numpy", "numba", "scipy"):
        raise ConfigError(f"plugin name {name!r} would shadow a package of that name; choose another")
    out = Path(out) if out is not None else Path(name)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"{out} exists and is not an empty folder; give --out a new folder")
    values = {"name": name, "cls": class_name(name), "dist": dist_name(name)}
    written = []
    for rel, text in FILES.items():
        path = out / Template(rel).substitute(values)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(Template(text).substitute(values))
        written.append(path)
    return written


__all__ = ["class_name", "dist_name", "new_plugin"]
