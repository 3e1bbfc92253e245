"""mkdocs hooks for starid's site (mkdocs.yml ``hooks:``).

* ``<!-- starid:params NAME -->`` in a page becomes the registered algorithm's parameter table
  (name, default, unit, meaning, value as published), generated from the plugin itself, so the
  table cannot drift from the code (the same rows ``starid info NAME`` prints).
* The teaching gallery's pictures are made by the scripts in ``examples/``. Each script's pictures
  live in ``docs/gallery/<script>/`` beside ``<script>.sha256``, the hash of the script that made
  them (and of the registered algorithms' names); when it no longer matches (the example changed,
  or a plugin was added), the build runs the script again
  (``STARID_EXAMPLE_OUT`` set to that folder) before reading any page. An unchanged example costs
  the build nothing, so ``mkdocs build --strict`` stays fast in CI.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import subprocess
import sys
from pathlib import Path

log = logging.getLogger("mkdocs.hooks.starid")

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
GALLERY = ROOT / "docs" / "gallery"
#: The example scripts whose pictures the gallery shows, in the gallery's order.
GALLERY_SCRIPTS = ("teaching.py", "every_algorithm.py")
PARAMS = re.compile(r"<!--\s*starid:params\s+([a-z0-9_]+)\s*-->")
REASONING = re.compile(r"<!--\s*starid:reasoning\s*-->")


def _digest(path: Path) -> str:
    """The script's hash and the registered algorithms' names: a new plugin gets its pictures too."""
    import starid

    return hashlib.sha256(path.read_bytes() + "\n".join(starid.available()).encode()).hexdigest()


def make_gallery(force: bool = False) -> list[str]:
    """Run every gallery script whose pictures are missing or older than the script (by hash).
    Returns the scripts that ran. A script that fails fails the build with its output."""
    ran = []
    for name in GALLERY_SCRIPTS:
        script = EXAMPLES / name
        out = GALLERY / script.stem
        stamp = GALLERY / f"{script.stem}.sha256"
        digest = _digest(script)
        if not force and stamp.is_file() and stamp.read_text().strip() == digest and any(out.glob("*.png")):
            continue
        log.info("gallery: running examples/%s (the script changed since its pictures were made)", name)
        out.mkdir(parents=True, exist_ok=True)
        env = {**os.environ, "STARID_EXAMPLE_OUT": str(out), "MPLBACKEND": "Agg"}
        done = subprocess.run([sys.executable, str(script)], cwd=ROOT, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"examples/{name} failed:\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}")
        stamp.write_text(digest + "\n")
        ran.append(name)
    return ran


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    return "None" if value is None else str(value)


def params_table(name: str) -> str:
    """The Markdown parameter table of a registered algorithm."""
    from starid.cli.plugins import parameter_table
    from starid.registry import get_algorithm

    cls = get_algorithm(name)
    published = getattr(cls, "published", {}) or {}
    lines = ["| parameter | default | unit | meaning | as published |", "|---|---|---|---|---|"]
    for row in parameter_table(cls):
        default = _cell(row["default"])
        if row["follows"]:
            default += f" (follows the {row['follows']})"
        elif row["derived"] is not None:
            default += f" (from the camera: {_cell(row['derived'])} on Table 4's)"
        meaning = " ".join(str(row["meaning"]).split()).replace("|", "\\|")
        if len(meaning) > 220:
            meaning = meaning[:217].rsplit(" ", 1)[0] + " ..."
        paper = f"`{_cell(published[row['name']])}`" if row["name"] in published else "same"
        lines.append(f"| `{row['name']}` | {default} | {row['unit']} | {meaning} | {paper} |")
    return "\n".join(lines)


def reasoning_table() -> str:
    """Each registered algorithm's reasoning picture (examples/every_algorithm.py), two per row."""
    import starid

    cells = [f"![{n}: its reasoning on trial 3 of seed 11](gallery/every_algorithm/reasoning_{n}.png)<br>"
             f"[`{n}`](algorithms/{n}.md)" for n in starid.available()
             if (GALLERY / "every_algorithm" / f"reasoning_{n}.png").is_file()]
    rows = ["| | |", "|---|---|"] + [f"| {' | '.join(cells[i:i + 2])} |" for i in range(0, len(cells), 2)]
    return "\n".join(rows)


def on_pre_build(config, **kwargs):
    make_gallery()


def on_page_markdown(markdown, page, config, files, **kwargs):
    markdown = REASONING.sub(lambda m: reasoning_table(), markdown)
    return PARAMS.sub(lambda m: params_table(m.group(1)), markdown)


if __name__ == "__main__":   # python docs/hooks/starid_docs.py [--force]: remake the gallery's pictures
    logging.basicConfig(level=logging.INFO)
    print("ran:", make_gallery(force="--force" in sys.argv) or "nothing (every picture is current)")
