"""docs/tutorial-pushbroom.md: its commands run and print what the doc shows (θ ± σ, χ², the base fit, the
named effects, the files written: compared exactly)."""

import re
import shlex
import shutil

from cli_run import run_cli
from paths import ROOT

DOC = ROOT / "docs" / "tutorial-pushbroom.md"
EXACT = re.compile(r"^\s*(theta_|line_time_offset_s|focal_scale|chip1_|χ²|base fit|named:|wrote|strip 0 )")


def _blocks():
    out = []
    for block in re.findall(r"```console\n(.*?)```", DOC.read_text(), flags=re.S):
        lines = block.splitlines()
        out.append((shlex.split(lines[0][2:])[1:], lines[1:]))
    return out


def test_the_pushbroom_tutorial_prints_what_it_shows(tmp_path, monkeypatch):
    shutil.copytree(ROOT / "examples" / "pushbroom", tmp_path / "examples" / "pushbroom")
    monkeypatch.chdir(tmp_path)
    blocks = _blocks()
    assert len(blocks) == 5
    for argv, shown in blocks:
        code, out, err = run_cli(argv)
        assert code == 0, (argv, err)
        printed = out.splitlines()
        for line in shown:
            if EXACT.match(line):
                assert line in printed, (argv, line, out)
