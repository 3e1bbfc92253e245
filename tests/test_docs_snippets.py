"""The Python blocks in README.md and docs/ parse, and every name they import from starid exists.

Running the blocks would take minutes (most simulate thousands of images); what goes stale when code
moves is the imports, so each block's ``from starid... import name`` is resolved here.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```python\n(.*?)^```", re.DOTALL | re.MULTILINE)
OURS = ("starid", "starid_algorithms")


def python_blocks():
    for path in sorted([ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]):
        for k, m in enumerate(FENCE.finditer(path.read_text(encoding="utf-8"))):
            yield pytest.param(m.group(1), id=f"{path.relative_to(ROOT)}#{k}")


BLOCKS = list(python_blocks())


def test_the_docs_have_python_blocks():
    assert len(BLOCKS) >= 5


@pytest.mark.parametrize("source", BLOCKS)
def test_block_parses_and_its_starid_imports_resolve(source):
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] in OURS:
                    importlib.import_module(alias.name)
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in OURS:
            module = importlib.import_module(node.module)
            for alias in node.names:
                submodule = hasattr(module, "__path__") and importlib.util.find_spec(f"{node.module}.{alias.name}")
                assert hasattr(module, alias.name) or submodule, f"{node.module} has no {alias.name}"
