"""The documentation builds with no warning: the API reference (autodoc over the public modules,
numpy-style docstrings) and the narrative docs (Markdown), ``sphinx -W`` as in a release.

Skipped only where Sphinx is not installed (the ``test`` extra installs it, so CI builds it)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from paths import ROOT


@pytest.fixture(scope="module")
def html(tmp_path_factory):
    """The site, built once: ``sphinx -E -W`` (every warning an error), the gallery's scripts run."""
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("sphinx_gallery")
    pytest.importorskip("matplotlib")
    out = tmp_path_factory.mktemp("docs") / "html"
    env = dict(os.environ, BORESIGHT_GALLERY_WORKDIR=str(out.parent), BORESIGHT_GALLERY_SMALL="1")
    r = subprocess.run(
        [sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html", str(ROOT / "docs"), str(out)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
        env=env,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    return out


def test_docs_build_without_warnings(html):
    assert (html / "api" / "boresight.html").exists()


#: figures each gallery script writes (the PNG files of its commands, or its own pyplot figure)
GALLERY_FIGURES = {
    "estimate_a_pass": 1,  # the histogram of residual_z
    "flight_pass": 2,  # estimate --out: residuals on the focal plane and against time
    "diagnose_hidden_effects": 2,  # one residual plot per named effect (time_tag, radial_distortion)
    "plan_a_campaign": 1,  # plan.png, the Pareto front
    "reproduce_kiev2012": 2,  # the eq 28 and Kalman figures of the report
}


def test_the_gallery_renders_every_example_with_its_figures(html):
    """Every script of ``examples/gallery/`` has its page with code, printed output and its figures,
    and the gallery's index shows one thumbnail per script."""
    scripts = sorted(p.stem for p in (ROOT / "examples" / "gallery").glob("*.py") if not p.name.startswith("_"))
    assert sorted(GALLERY_FIGURES) == scripts
    index = (html / "examples" / "index.html").read_text()
    assert sorted(set(re.findall(r"sphx_glr_([a-z_0-9]+)_thumb\.png", index))) == scripts
    for name, n in GALLERY_FIGURES.items():
        page = (html / "examples" / f"{name}.html").read_text()
        images = set(re.findall(rf'<img[^>]+src="[^"]*(sphx_glr_{name}_\d+\.png)"', page))
        assert len(images) == n, f"{name}: {len(images)} figure(s) on its page, expected {n}"
        assert all((html / "_images" / i).stat().st_size > 5000 for i in images), name  # real figures, not blanks
        assert "sphx-glr-script-out" in page, f"{name}: no printed output on its page"
        assert "highlight-Python" in page or "highlight-python" in page, f"{name}: no code on its page"
        # the pages show what a reader's run prints: paths relative to the working folder, not the builder's
        for path in (str(html.parent), str(ROOT), "/tmp/"):  # its working folder, its checkout, any temporary one
            assert path not in page, f"{name}: the builder's absolute path {path} on its page"


def test_the_docs_ship_with_the_package_and_the_command_prints_them(capsys):
    from boresight.cli.docs import shipped_docs
    from boresight.cli.main import main

    docs = shipped_docs()
    assert {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"} == set(docs)
    assert main(["docs"]) == 0
    out = capsys.readouterr().out
    assert "tutorial-flight-data" in out and "Tutorial" in out
    assert "run one from a working folder of yours, not from that folder" in out  # not inside site-packages
    assert main(["docs", "conventions"]) == 0
    assert capsys.readouterr().out == (ROOT / "docs" / "conventions.md").read_text()
    assert main(["docs", "convention"]) == 1
    assert "did you mean 'conventions'" in capsys.readouterr().err
