"""Test plugins that misbehave on purpose, one way each (issue: a plugin cannot cheat, corrupt or hide).

They register in process (``register_all``); forked worker processes inherit the registrations.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from starid.plugin import Algorithm, Database, Explanation, Identification
from starid.registry import register, unregister


@dataclass(frozen=True, eq=False)
class Empty(Database):
    ids: np.ndarray


#: what ``mode=leave`` builds keep alive in the process, as a worker keeps earlier chunks' databases
_LEFT: list = []


@dataclass(frozen=True)
class Misbehaving(Algorithm):
    """Identifies nothing, then misbehaves as ``mode`` says (test double)."""

    name: ClassVar[str] = "misbehaving"
    mode: str = "none"
    every: int = 3
    gb: float = 0.0         # modes leave / need / leak: GB of address space (reserved, never written to)

    def build(self, catalog, camera):
        if self.mode == "build_raises":
            raise RuntimeError("cannot build")
        if self.mode == "build_hang":
            time.sleep(3600)
        if self.mode == "leave":    # what an earlier chunk leaves in its worker (a database, compiled code)
            _LEFT.append(np.empty(int(self.gb * 1e9), dtype=np.uint8))
        return Empty(catalog.hip[:10].copy())

    def _hit(self, observation) -> bool:
        return len(observation) % self.every == 0

    def identify(self, database, observation):
        n = len(observation)
        if self.mode == "hang" and self._hit(observation):
            time.sleep(3600)
        if self.mode == "exit" and self._hit(observation):
            sys.exit(3)
        if self.mode == "crash" and self._hit(observation):
            os._exit(9)
        if self.mode == "alloc" and self._hit(observation):     # without bound: 64 GB, written to
            np.ones(8 * 10**9)
        if self.mode == "need" and self._hit(observation):      # a bounded need, freed after the image
            np.empty(int(self.gb * 1e9), dtype=np.uint8)
        if self.mode == "leak":     # numba's way: a kernel that runs out of memory does not free what it had
            if self._hit(observation):
                _LEFT.append(np.empty(int(self.gb / 2 * 1e9), dtype=np.uint8))
                np.empty(int(4 * self.gb * 1e9), dtype=np.uint8)
            np.empty(int(self.gb * 1e9), dtype=np.uint8)
            return Identification(np.full(n, -1, dtype=np.int64), counters={"pid": os.getpid()})
        if self.mode == "mutate":
            observation.x_px[:] = 0.0
        if self.mode == "cheat":
            return Identification(observation.truth_hip.copy())
        return Identification.none(n)

    def explain(self, database, observation):
        if self.mode == "explain_hang":
            time.sleep(3600)
        if self.mode == "explain_alloc":
            np.ones(8 * 10**9)
        return Explanation(caption="nothing identified")


NAMES = ("misbehaving",)


def register_all():
    register(Misbehaving)


def unregister_all():
    for name in NAMES:
        unregister(name)
