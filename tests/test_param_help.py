"""Every built-in plugin parameter declares its meaning and unit (``starid.params.param``), for
``starid info`` and the docs' parameter tables (issue #28)."""

import dataclasses

import pytest

from starid.registry import algorithm_info

BUILT_INS = ("geometric_voting", "grid", "lpt", "lpt_improved", "planar_triangle", "ptp", "pvector", "pyramid",
             "tetra", "triangle_voting")
SUFFIX_UNITS = {"_px": "px", "_deg": "deg", "_mag": "mag", "_s": "s", "_pct": "%", "_rad": "rad"}


@pytest.mark.parametrize("name", BUILT_INS)
def test_every_parameter_has_help_and_unit(name):
    cls = algorithm_info(name).cls
    fields = dataclasses.fields(cls)
    assert fields, name
    bad = []
    for f in fields:
        text = f.metadata.get("help", "")
        if not text.strip() or len(text) > 120 or "\n" in text:
            bad.append(f"{f.name}: help {text!r}")
        if "unit" not in f.metadata:
            bad.append(f"{f.name}: no declared unit")
            continue
        want = next((u for suffix, u in SUFFIX_UNITS.items() if f.name.endswith(suffix)), None)
        if want is not None and f.metadata["unit"] != want:
            bad.append(f"{f.name}: unit {f.metadata['unit']!r}, the name says {want!r}")
    assert not bad, f"{name}: " + "; ".join(bad)
