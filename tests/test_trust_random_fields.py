"""Random fields: no algorithm may name a star in a field of uniformly random points (issue #26)."""

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from starid import Camera
from starid.plugin import Algorithm, Database, Identification
from starid.registry import get_algorithm
from starid.testing import RANDOM_FIELDS, RANDOM_POINTS, ConformanceError, check_algorithm, random_fields


@dataclass(frozen=True, eq=False)
class _HipDatabase(Database):
    hip: np.ndarray


@dataclass(frozen=True)
class NamesInOddFields(Algorithm):
    """Names its brightest detection as the first catalog star in every field of an odd number of points
    (a test double)."""

    name: ClassVar[str] = "names_in_odd_fields"

    def build(self, catalog, camera):
        return _HipDatabase(hip=catalog.hip[:1].copy())

    def identify(self, database, observation):
        out = np.full(len(observation), -1, dtype=np.int64)
        if len(observation) % 2:
            out[int(np.argmin(observation.mag))] = database.hip[0]
        return Identification(out)


def test_the_fields_are_200_of_10_to_40_points():
    sizes = [len(obs) for obs in random_fields(Camera())]
    assert RANDOM_FIELDS == 200 and RANDOM_POINTS == (10, 40)
    assert len(sizes) == 200 and min(sizes) == 10 and max(sizes) == 40
    assert len(set(sizes)) > 25


def test_one_id_in_a_field_of_noise_is_refused():
    pattern = r"identified stars in \d+ of 200 fields of 10 to 40 .*none may be named"
    with pytest.raises(ConformanceError, match=pattern):
        check_algorithm(NamesInOddFields, checks=["random_fields"])


def test_triangle_voting_names_nothing_in_the_fields_it_used_to(catalog, camera):
    """Fields 112 and 151 got a 4-star 'identification' (photometry 1.45 and 2.45 V off) before the check."""
    cls = get_algorithm("triangle_voting")
    algorithm = cls()
    db = algorithm.build(catalog, camera)
    fields = list(random_fields(camera))
    for k in (112, 151):
        assert (algorithm.identify(db, fields[k].for_plugin()).hip == -1).all(), k
