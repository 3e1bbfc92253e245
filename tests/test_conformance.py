"""The conformance suite over every registered algorithm (``pytest -k <check>`` runs one check)."""

import pytest

from starid.registry import available_algorithms, get_algorithm
from starid.testing import CHECKS, check_algorithm

ALGORITHMS = [info.name for info in available_algorithms()]


def test_builtin_algorithms_are_registered_and_ok():
    infos = {info.name: info for info in available_algorithms()}
    assert "ptp" in infos
    broken = {name: info.error for name, info in infos.items() if info.status != "ok"}
    assert not broken


@pytest.mark.parametrize("check", CHECKS)
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_conformance(algorithm, check):
    check_algorithm(get_algorithm(algorithm), checks=[check])


def test_unknown_check_is_refused():
    with pytest.raises(ValueError, match="unknown check"):
        check_algorithm(get_algorithm("ptp"), checks=["nope"])
