"""Which numba kernels Python code calls: for every ``@njit`` kernel defined in the given files, the
places outside kernel bodies (algorithm wrappers, tests, tools, the harness) that name it. A kernel
named nowhere outside kernels can be compiled with ``no_cpython_wrapper=True, no_cfunc_wrapper=True``
(~40 ms less per kernel on a cold cache; a Python call to it then fails).

    python benchmarks/tools/compilecut_pyrefs.py "algorithms/ptp/kernels.py starid/kernels/verify.py" \
        starid algorithms tests benchmarks

The match is by name (an attribute or a name with the kernel's name), so it over-reports (a method
of the same name elsewhere counts): check the places it lists before adding a wrapper back or not.
"""

from __future__ import annotations

import ast
import collections
import pathlib
import sys


def _is_kernel_decorator(dec: ast.expr) -> bool:
    s = ast.unparse(dec)
    return "njit" in s or s.startswith("_inner")


def _kernels(tree: ast.AST) -> dict[str, ast.FunctionDef]:
    return {node.name: node for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef) and any(_is_kernel_decorator(d) for d in node.decorator_list)}


def main(files: list[str], roots: list[str]) -> None:
    defined = collections.defaultdict(list)
    for f in files:
        for name in _kernels(ast.parse(pathlib.Path(f).read_text())):
            defined[name].append(f)
    refs = collections.defaultdict(set)
    for root in roots:
        for f in pathlib.Path(root).rglob("*.py"):
            if ".venv" in f.parts:
                continue
            tree = ast.parse(f.read_text())
            inside = {id(sub) for node in _kernels(tree).values() for sub in ast.walk(node)}
            for node in ast.walk(tree):
                if id(node) in inside:
                    continue
                name = node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else None
                if name in defined:
                    refs[name].add(f"{f}:{node.lineno}")
    for name in sorted(defined):
        places = sorted(refs.get(name, ()))
        print(f"{name} ({', '.join(defined[name])}): {len(places)} Python references {' '.join(places[:6])}")


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1].split(), sys.argv[2:])
