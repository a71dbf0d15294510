"""docs/discrepancy-example is what the documented command writes (issue 20 item 7): the whole
diagnosis.json, not only the headline numbers, and the printed block of docs/discrepancy.md.
Regenerate with ``python examples/make_discrepancy_example.py``."""

import importlib.util
import json
import math

import pytest
from paths import ROOT

pytest.importorskip("boresight.core.effect_model")

#: numbers to a relative 1e-6 (BLAS differences across CPUs are ~1e-12 on θ; p-values as small as
#: 1e-88 move by Δχ²/2 times the relative change of Δχ²), or 1e-9 absolute near zero
RTOL, ATOL = 1e-6, 1e-9


def _script():
    spec = importlib.util.spec_from_file_location("make_discrepancy_example", ROOT / "examples/make_discrepancy_example.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def compare(a, b, where="diagnosis.json"):
    """Recursively equal: same keys in the same order, same strings and booleans, numbers within
    RTOL/ATOL. Returns a list of differences, each naming its path."""
    if isinstance(a, dict) and isinstance(b, dict):
        if list(a) != list(b):
            return [f"{where}: keys {list(a)} != {list(b)}"]
        return [d for k in a for d in compare(a[k], b[k], f"{where}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: length {len(a)} != {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in compare(x, y, f"{where}[{i}]")]
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)) or not isinstance(b, (int, float)):
        return [] if a == b else [f"{where}: {a!r} != {b!r}"]
    if isinstance(a, float) and isinstance(b, float) and math.isinf(a) and math.isinf(b) and (a > 0) == (b > 0):
        return []
    return [] if math.isclose(a, b, rel_tol=RTOL, abs_tol=ATOL) else [f"{where}: {a!r} != {b!r}"]


def test_compare_names_the_difference():
    assert compare({"a": [1.0, {"b": "x"}]}, {"a": [1.0 + 1e-9, {"b": "x"}]}) == []
    assert compare({"a": [1.0, {"b": "x"}]}, {"a": [1.1, {"b": "y"}]}) == [
        "diagnosis.json.a[0]: 1.0 != 1.1",
        "diagnosis.json.a[1].b: 'x' != 'y'",
    ]


def test_docs_example_is_what_the_command_writes(tmp_path):
    mod = _script()
    printed = mod.run(["diagnose", "scenarios/diagnose-example.toml", "--seed", "1", "--out", str(tmp_path), "--no-plots"])
    committed = json.loads((ROOT / mod.OUT / "diagnosis.json").read_text())
    fresh = json.loads((tmp_path / "diagnosis.json").read_text())
    diffs = compare(fresh, committed)
    assert not diffs, "docs/discrepancy-example is stale (python examples/make_discrepancy_example.py):\n" + "\n".join(diffs[:20])
    block = mod._BLOCK.search(mod.DOC.read_text(encoding="utf-8")).group(2)
    assert block == mod.summary_block(printed)
    # the figures the page shows exist
    for name in ("step1_radial_distortion.png", "step2_time_tag.png"):
        assert (ROOT / mod.OUT / name).stat().st_size > 1000
