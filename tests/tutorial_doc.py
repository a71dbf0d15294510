"""docs/tutorial-flight-data.md as the tests read it, defined once: its path, the console blocks that run
``boresight …`` with the lines they show, and which printed lines are compared exactly (used by
``cli/test_tutorial.py`` in the checkout and ``project/test_wheel.py`` from a wheel)."""

import re
import shlex

from paths import ROOT

DOC = ROOT / "docs" / "tutorial-flight-data.md"
# lines compared exactly with the doc (θ, σ, χ², the doctor's verdict, counts)
EXACT = re.compile(
    r"^(theta_|chi2 / dof|check |observations|result |declared|algorithm |pixel noise |noise model |note |estimate )"
)


def console_blocks(doc=DOC):
    """[(argv, expected output lines)] of the ```console blocks whose command is `boresight …` (of ``doc``: the flight
    tutorial by default)."""
    out = []
    for block in re.findall(r"```console\n(.*?)```", doc.read_text(), flags=re.S):
        lines = block.splitlines()
        if not lines[0].startswith("$ boresight"):
            continue
        cmd, k = lines[0][2:], 1
        while cmd.endswith("\\"):
            cmd = cmd[:-1] + " " + lines[k].strip()
            k += 1
        out.append((shlex.split(cmd)[1:], lines[k:]))
    return out


def check_console_blocks(doc, exact, examples, tmp_path, monkeypatch, count):
    """Run the ``count`` console blocks of ``doc`` in ``tmp_path`` (with a copy of ``examples/<examples>``):
    each exits 0 and prints every shown line that ``exact`` matches (the pushbroom and star tutorials)."""
    import shutil

    from cli_run import run_cli

    shutil.copytree(ROOT / "examples" / examples, tmp_path / "examples" / examples)
    monkeypatch.chdir(tmp_path)
    blocks = console_blocks(doc)
    assert len(blocks) == count
    for argv, shown in blocks:
        code, out, err = run_cli(argv)
        assert code == 0, (argv, err)
        printed = out.splitlines()
        for line in shown:
            if exact.match(line):
                assert line in printed, (argv, line, out)
