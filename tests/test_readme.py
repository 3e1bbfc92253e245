"""The README tells the truth: its set-up commands, the CI hook and its code examples."""

import re
import subprocess
from pathlib import Path

import starid
from starid.registry import unregister
from starid.testing import check_algorithm

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _blocks(lang):
    return re.findall(rf"^```{lang}\n(.*?)^```", README, flags=re.S | re.M)


def test_readme_starts_with_two_setup_commands():
    first = README.split("```sh\n", 1)[1].split("```", 1)[0].strip().splitlines()
    assert len(first) == 2
    assert first[0].startswith("pip install -e .") and "starid table6" in first[0]
    assert "'.[test]'" in first[1] and "pytest" in first[1]
    assert README.index("```sh") < README.index("\n## ")


def test_ci_runs_the_readme_test_command():
    script = (ROOT / ".ci" / "run").read_text()
    extract = re.search(r"test_command=\$\((.*)\)\n", script).group(1)
    out = subprocess.run(["bash", "-c", extract], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    assert out.strip() == _blocks("sh")[0].strip().splitlines()[1]


def test_plugin_guide_example_runs():
    text = (ROOT / "docs" / "plugins.md").read_text()
    plugin, harness = re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)[:2]
    namespace = {}
    exec(compile(plugin, "README-plugin", "exec"), namespace)
    try:
        cls = namespace["PairVoting"]
        assert starid.get_algorithm("pair_voting") is cls
        assert check_algorithm(cls) == list(starid.testing.CHECKS)
        exec(compile(harness.replace("generate(50)", "generate(5)"), "README-harness", "exec"), namespace)
    finally:
        unregister("pair_voting")


def test_readme_and_docs_cover_every_builtin_algorithm():
    builtins = [i for i in starid.available_algorithms() if i.dist == "starid-bench"]
    assert len(builtins) >= 4
    for info in builtins:
        assert f"`{info.name}`" in README
        doc = ROOT / "docs" / "algorithms" / f"{info.name}.md"
        assert doc.is_file() and len(doc.read_text()) > 1000, f"{doc} missing or a stub"
        assert f"docs/algorithms/{info.name}.md" in (info.cls.__doc__ or ""), \
            f"{info.name}'s docstring must point to its doc"
