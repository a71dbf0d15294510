"""docs/tutorial-pushbroom.md: its commands run and print what the doc shows (θ ± σ, χ², the base fit, the
named effects, the files written: compared exactly)."""

import re
import shutil

from cli_run import run_cli
from paths import ROOT
from tutorial_doc import console_blocks

DOC = ROOT / "docs" / "tutorial-pushbroom.md"
EXACT = re.compile(r"^\s*(theta_|line_time_offset_s|focal_scale|chip1_|χ²|base fit|named:|wrote|strip 0 )")


def test_the_pushbroom_tutorial_prints_what_it_shows(tmp_path, monkeypatch):
    shutil.copytree(ROOT / "examples" / "pushbroom", tmp_path / "examples" / "pushbroom")
    monkeypatch.chdir(tmp_path)
    blocks = console_blocks(DOC)
    assert len(blocks) == 5
    for argv, shown in blocks:
        code, out, err = run_cli(argv)
        assert code == 0, (argv, err)
        printed = out.splitlines()
        for line in shown:
            if EXACT.match(line):
                assert line in printed, (argv, line, out)
