"""Every gallery script (``examples/gallery/``, listed in ``docs/gallery.md``) runs as it is, with
small sizes, in a fresh process from an empty folder."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from paths import ROOT

GALLERY = ROOT / "examples" / "gallery"
SCRIPTS = sorted(p for p in GALLERY.glob("*.py") if not p.name.startswith("_"))


def test_the_gallery_page_lists_every_script():
    listed = set(re.findall(r"`examples/gallery/([a-z_0-9]+\.py)`", (ROOT / "docs" / "gallery.md").read_text()))
    assert listed == {p.name for p in SCRIPTS}


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_gallery_script_runs(script, tmp_path):
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(ROOT), str(GALLERY)]),
        MPLBACKEND="Agg",
        BORESIGHT_GALLERY_SMALL="1",
        BORESIGHT_GALLERY_OUT=str(tmp_path / "out"),
    )
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"{script.name}: exit {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    assert "Traceback" not in r.stderr
