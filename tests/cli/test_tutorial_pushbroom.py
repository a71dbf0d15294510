"""docs/tutorial-pushbroom.md: its commands run and print what the doc shows (θ ± σ, χ², the base fit, the
named effects, the files written, the unknowns and the plan tables' headers, the planned campaign and its Monte Carlo
verdict: compared exactly)."""

import re

from paths import ROOT
from tutorial_doc import check_console_blocks

DOC = ROOT / "docs" / "tutorial-pushbroom.md"
EXACT = re.compile(
    r"^\s*(theta_|line_time_offset +(σ|predicted|[\d-])|focal_scale|chip1_|χ²|chi2 / dof|largest z|base fit|named:|wrote|strip 0 |\[|chosen|verdict"
    r"|unknowns|strips \(rolls\)|best of each size)"
)


def test_the_pushbroom_tutorial_prints_what_it_shows(tmp_path, monkeypatch):
    check_console_blocks(DOC, EXACT, "pushbroom", tmp_path, monkeypatch, 13)
