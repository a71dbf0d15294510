"""The documentation builds with no warning: the API reference (autodoc over the public modules,
numpy-style docstrings) and the narrative docs (Markdown), ``sphinx -W`` as in a release.

Skipped only where Sphinx is not installed (the ``test`` extra installs it, so CI builds it)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from paths import ROOT


def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "sphinx",
            "-E",
            "-W",
            "--keep-going",
            "-q",
            "-b",
            "html",
            str(ROOT / "docs"),
            str(tmp_path / "html"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    assert (tmp_path / "html" / "api" / "boresight.html").exists()


def test_the_docs_ship_with_the_package_and_the_command_prints_them(capsys):
    from boresight.cli.docs import shipped_docs
    from boresight.cli.main import main

    docs = shipped_docs()
    assert {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"} == set(docs)
    assert main(["docs"]) == 0
    out = capsys.readouterr().out
    assert "tutorial-flight-data" in out and "Tutorial" in out
    assert main(["docs", "conventions"]) == 0
    assert capsys.readouterr().out == (ROOT / "docs" / "conventions.md").read_text()
    assert main(["docs", "convention"]) == 1
    assert "did you mean 'conventions'" in capsys.readouterr().err
