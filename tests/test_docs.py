"""The documentation builds with no warning: the API reference (autodoc over the public modules,
numpy-style docstrings) and the narrative docs (Markdown), ``sphinx -W`` as in a release.

Skipped only where Sphinx is not installed (the ``test`` extra installs it, so CI builds it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html", str(ROOT / "docs"),
                        str(tmp_path / "html")], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    assert (tmp_path / "html" / "api" / "boresight.html").exists()
