"""Who compiles what in a cold preparation of one plugin: every numba compilation with its exclusive and
inclusive CPU s and the dispatcher that triggered it (its caller), as a tree. Run on an empty cache:

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/tools/plnspeed2_compile_tree.py planar_triangle [MIN_S]

Prints the preparation's CPU s, then the tree (children indented under the kernel whose typing compiled
them; entries under MIN_S inclusive, default 0.05 s, folded into their parent's line as a count).
"""

from __future__ import annotations

import sys
import time

from compile_profile import prepare_listening, warmup_trials  # benchmarks/tools
from numba.core import event


def _name(dispatcher) -> str:
    f = dispatcher.py_func
    mod = f.__module__.rsplit(".", 2)[-2] if f.__module__.count(".") > 1 else f.__module__
    return f"{mod}.{f.__name__}"


class _Node:
    def __init__(self, name):
        self.name, self.children, self.incl, self.t0 = name, [], 0.0, 0.0

    @property
    def excl(self):
        return self.incl - sum(c.incl for c in self.children)


class _Recorder(event.Listener):
    def __init__(self):
        self.root = _Node("<root>")
        self.stack = [self.root]

    def on_start(self, ev):
        node = _Node(_name(ev.data["dispatcher"]))
        node.t0 = time.process_time()
        self.stack[-1].children.append(node)
        self.stack.append(node)

    def on_end(self, ev):
        node = self.stack.pop()
        node.incl = time.process_time() - node.t0


def _show(node, depth, min_s):
    small = [c for c in node.children if c.incl < min_s]
    extra = f"  (+{len(small)} small: {sum(c.incl for c in small):.2f} s)" if small else ""
    print(f"{'  ' * depth}{node.incl:6.2f} incl {node.excl:6.2f} excl  {node.name}{extra}")
    for c in node.children:
        if c.incl >= min_s:
            _show(c, depth + 1, min_s)


def main(name: str, min_s: float) -> None:
    catalog, trials = warmup_trials()
    rec = _Recorder()
    p, cpu_s = prepare_listening(name, catalog, trials, rec)
    print(f"{name}: cpu_s {cpu_s:.2f} build_s {p.build_s:.2f} error {p.error!r}")
    for c in rec.root.children:
        _show(c, 0, min_s)


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 0.05)
