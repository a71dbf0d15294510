"""Public outputs are byte-identical to the committed references (``tests/reference_outputs/``).

The three study commands — ``reproduce kiev2012``, ``montecarlo`` and ``sensitivity`` — are run
in-process with fixed seeds and small run counts, and every file they write (ECSV, JSON,
``reproduction.md``) and everything they print is compared byte for byte with the references.
A refactoring (moving code between modules, renaming internals) must leave them unchanged.

Normalised before the comparison, because they are genuinely volatile (nothing else is):

* ``elapsed_s``, ``versions`` and ``argv`` in the JSON files (wall time; python/numpy/... versions;
  the process's command line, which is pytest's when run here);
* the wall time printed at the end of the summary line (``…; 0.04 s`` → ``…; <elapsed> s``);
* the temporary output folder, wherever it appears (printed paths, ``argv``) → ``<OUT>``.

Not compared: the PNG figures (their bytes depend on the matplotlib and FreeType versions).

When a change of a public output is INTENDED, regenerate the references and say so in the commit::

    python tests/test_public_outputs.py          # rewrites tests/reference_outputs/

and review ``git diff tests/reference_outputs`` — it must show exactly the intended change.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "tests" / "reference_outputs"

# name -> argv (OUT is replaced by the output folder). Seeds fixed, runs small, one worker.
CASES = {
    "montecarlo-sensitivity": ["montecarlo", "scenarios/kiev2012-sensitivity.toml", "--runs", "2000", "--seed", "3",
                               "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "montecarlo-kalman20": ["montecarlo", "scenarios/kiev2012-kalman20.toml", "--runs", "1000", "--seed", "5",
                            "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "sensitivity": ["sensitivity", "scenarios/kiev2012-sensitivity.toml", "--runs", "2000", "--seed", "3",
                    "--algorithm", "image_plane", "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "reproduce-kiev2012": ["reproduce", "kiev2012", "--runs", "1000", "--kalman-runs", "200", "--workers", "1",
                           "--template", "docs/reproduction.md", "--out", "OUT"],
}
VOLATILE_JSON_KEYS = ("elapsed_s", "versions", "argv")
COMPARED_SUFFIXES = (".ecsv", ".json", ".md")


def _normalise(text: str, out: Path) -> str:
    text = text.replace(str(out), "<OUT>")
    return re.sub(r"(\d+ runs per case, seed \d+, |; )\d+\.\d+ s$", r"\1<elapsed> s", text, flags=re.M)


def _normalise_json(text: str, out: Path) -> str:
    d = json.loads(text)
    for k in VOLATILE_JSON_KEYS:
        if k in d:
            d[k] = "<volatile>"
    return _normalise(json.dumps(d, indent=2, ensure_ascii=False) + "\n", out)


def run_case(name: str, out: Path) -> dict[str, str]:
    """Run one case with its output in ``out``; return {file name: normalised text}, stdout included."""
    from boresight.cli import main

    argv = [str(out) if a == "OUT" else a for a in CASES[name]]
    buf = io.StringIO()
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        with contextlib.redirect_stdout(buf):
            code = main(argv)
    finally:
        os.chdir(cwd)
    assert code == 0, f"boresight {' '.join(argv)} exited with {code}"
    files = {"stdout.txt": _normalise(buf.getvalue(), out)}
    for p in sorted(out.iterdir()):
        if p.suffix not in COMPARED_SUFFIXES:
            continue
        text = p.read_text()
        files[p.name] = _normalise_json(text, out) if p.suffix == ".json" else _normalise(text, out)
    return files


@pytest.mark.parametrize("name", sorted(CASES))
def test_public_output_is_byte_identical(name, tmp_path):
    ref_dir = REFERENCE / name
    expected = {p.name: p.read_bytes() for p in sorted(ref_dir.iterdir())}
    got = run_case(name, tmp_path / "out")
    assert sorted(got) == sorted(expected), f"{name}: files written differ from {ref_dir}"
    for fname, text in got.items():
        assert text.encode() == expected[fname], (
            f"{name}/{fname} differs from the committed reference {ref_dir / fname}; if the change is intended, "
            "regenerate with `python tests/test_public_outputs.py` and review the diff"
        )


def regenerate() -> None:
    for name in sorted(CASES):
        with tempfile.TemporaryDirectory() as tmp:
            files = run_case(name, Path(tmp) / "out")
        ref_dir = REFERENCE / name
        ref_dir.mkdir(parents=True, exist_ok=True)
        for old in ref_dir.iterdir():
            old.unlink()
        for fname, text in files.items():
            (ref_dir / fname).write_bytes(text.encode())
        print(f"wrote {ref_dir} ({len(files)} files)", file=sys.stderr)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    regenerate()
