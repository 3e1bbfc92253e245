"""Two questions about a cold compile that the other compile tools do not answer (issue #25, stop 45).

Run it on an empty cache, every plugin in one process (as ``symcall_census.py``):

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compile_census.py callers NAMES...
    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/compile_census.py signatures NAMES...

* ``callers``: for every compiled kernel (numpy's and CPython's overload implementations left out),
  how many libraries link it directly (``callers``) and in their closure (``linkers``), its own LLVM
  CPU seconds and its exclusive compile CPU seconds; then the sums over the kernels that exactly one
  library links. Those are the kernels numba could inline into their one caller (``inline="always"``,
  so that their library, and its own optimisation and machine code, would not exist): the sum of
  their ``llvm_s`` is an upper bound of what that saves, before the caller's extra work on the inlined
  code is paid. (At stop 45 the bound was 13 of 37 LLVM s for the fourteen plugins; triangle voting's
  thirteen single-call-site kernels inlined saved nothing measurable: 18.1 / 18.2 -> 18.0 / 18.5 CPU s.)
* ``signatures``: the kernels compiled for more than one argument type signature in this process,
  and the exclusive CPU seconds of all but the costliest signature of each: the most that one
  signature per kernel could save (the issue's "no kernel compiled for two type signatures where one
  serves"), kernels and numpy / CPython implementations apart.

Exclusive CPU seconds and the LLVM share come from numba's ``numba:compile`` and ``numba:llvm_lock``
events (``symcall_census.census_of``); the first plugin carries the core's kernels.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict

from symcall_census import _closure, census_of  # benchmarks/tools

_OVERLOADS = ("np.", "cpython.", "numba.")


def callers(names: list[str], top: int = 40) -> None:
    census, cpu_s = census_of(names)
    direct: dict = defaultdict(set)
    for lib in census.libs:
        for sub in getattr(lib, "_linking_libraries", ()):
            direct[id(sub)].add(id(lib))
    memo: dict = {}
    linkers: dict = defaultdict(int)
    for lib in census.libs:
        for sub in _closure(lib, memo):
            linkers[id(sub)] += 1
    rows = [(info["llvm_s"], len(direct[id(lib)]), linkers[id(lib)], info["excl_s"], info["name"])
            for lib, info in census.libs.items() if not info["name"].startswith(_OVERLOADS)]
    single = [r for r in rows if r[1] == 1]
    print(json.dumps({"plugins": names, "cpu_s": round(cpu_s, 1), "llvm_cpu_s": round(census.llvm_total, 1),
                      "libraries": len(census.libs), "kernels": len(rows),
                      "kernels_llvm_s": round(sum(r[0] for r in rows), 1), "single_caller": len(single),
                      "single_caller_llvm_s": round(sum(r[0] for r in single), 1),
                      "single_caller_excl_s": round(sum(r[3] for r in single), 1)}), flush=True)
    print(f"{'llvm_s':>7} {'excl_s':>7} {'callers':>7} {'linkers':>7}  kernel")
    for llvm_s, n_direct, n_link, excl_s, name in sorted(rows, key=lambda r: -r[0])[:top]:
        print(f"{llvm_s:7.3f} {excl_s:7.3f} {n_direct:7d} {n_link:7d}  {name}")


def signatures(names: list[str], top: int = 25) -> None:
    census, cpu_s = census_of(names)
    by_name: dict = defaultdict(list)
    for info in census.libs.values():
        by_name[info["name"]].append(info)
    extra = {"kernels": 0.0, "overloads": 0.0}
    rows = []
    for name, infos in by_name.items():
        if len(infos) < 2:
            continue
        cost = sorted(i["excl_s"] for i in infos)
        more = sum(cost[:-1])
        kind = "overloads" if name.startswith(_OVERLOADS) else "kernels"
        extra[kind] += more
        if kind == "kernels":
            rows.append((more, name, [i["sig"] for i in infos]))
    print(json.dumps({"plugins": names, "cpu_s": round(cpu_s, 1),
                      "extra_signatures_s": {k: round(v, 1) for k, v in extra.items()}}), flush=True)
    for more, name, sigs in sorted(rows, reverse=True)[:top]:
        print(f"{more:6.2f} s  x{len(sigs)}  {name}")
        for sig in sigs:
            print(f"            ({sig[:100]})")


if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[1] not in ("callers", "signatures"):
        sys.exit(__doc__)
    {"callers": callers, "signatures": signatures}[sys.argv[1]](sys.argv[2:])
