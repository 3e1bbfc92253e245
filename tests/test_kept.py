"""``Algorithm.kept``: a per-run bundle built once per (database, camera) objects, never pickled."""

import pickle
from dataclasses import dataclass, replace
from typing import ClassVar

from starid import Camera
from starid.plugin import Algorithm, Identification


@dataclass(frozen=True)
class _Counting(Algorithm):
    name: ClassVar[str] = "counting"
    scale: float = 1.0

    def build(self, catalog, camera):
        return None

    def identify(self, database, observation):
        return Identification.none(0)


def test_built_once_per_identity_rebuilt_for_another_object():
    alg, calls = _Counting(), []
    cam_a, cam_b = Camera(), Camera()      # equal, but different objects
    db = object()

    def make(tag):
        calls.append(tag)
        return tag

    assert alg.kept("x", (db, cam_a), lambda: make("a")) == "a"
    assert alg.kept("x", (db, cam_a), lambda: make("again")) == "a"     # same objects: kept
    assert alg.kept("x", (db, cam_b), lambda: make("b")) == "b"         # an equal camera is another camera
    assert alg.kept("y", (db, cam_b), lambda: make("y")) == "y"         # names are separate
    assert alg.kept("x", (db, cam_b), lambda: make("again")) == "b"
    assert calls == ["a", "b", "y"]


def test_not_pickled_and_not_carried_by_replace():
    alg = _Counting()
    alg.kept("x", (Camera(),), lambda: 1)
    assert "_kept" in alg.__dict__
    assert "_kept" not in pickle.loads(pickle.dumps(alg)).__dict__
    assert "_kept" not in replace(alg, scale=2.0).__dict__
    assert pickle.loads(pickle.dumps(alg)) == alg
