"""The README's first contact reads sensibly: the θ ± σ demo is noisy and realistic, its truth lies
inside the printed σ (the numbers quoted in the README's prose are the ones the commands print),
and neither the demo commands nor the Python snippet print a warning on a shipped scenario.

(``tests/project/test_wheel.py`` runs every README command from a wheel install; this test checks what
the demo *says*, in a few seconds.)
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

from paths import ROOT

README = (ROOT / "README.md").read_text()
_FLOAT = r"[-+−]?\d+\.\d+"


def _run(argv, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg", PYTHONWARNINGS="default")
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def _demo_lines():
    block = re.findall(r"```bash\n(.*?)```", README, flags=re.S)[1]
    cmds = [ln.split("  #")[0].strip() for ln in block.splitlines()]
    return [c for c in cmds if c.split()[1:2] and c.split()[1] in ("simulate", "check", "estimate")]


def _quoted_sigmas():
    m = re.search(rf"error ({_FLOAT}), ({_FLOAT}), ({_FLOAT}) σ", README)
    assert m, "the README quotes the demo's error in σ"
    return [float(x.replace("−", "-")) for x in m.groups()]


def test_the_cli_demo_is_noisy_and_its_truth_is_inside_sigma(tmp_path):
    cmds = _demo_lines()
    assert [c.split()[1] for c in cmds] == ["simulate", "check", "estimate"]
    out = ""
    for c in cmds:
        r = _run([sys.executable, "-m", "boresight", *c.split()[1:]], tmp_path)
        assert r.returncode == 0, f"{c}: exit {r.returncode}\n{r.stdout}\n{r.stderr}"
        assert "warning" not in (r.stdout + r.stderr).lower(), f"{c} printed a warning:\n{r.stdout}\n{r.stderr}"
        out = r.stdout
    sig = re.search(r"^sigma\s", out, flags=re.M)
    assert sig, out
    theta = [float(x) for x in re.findall(rf"^theta_[xyz]\s+{_FLOAT} ± ({_FLOAT}) arcsec", out, flags=re.M)]
    assert len(theta) == 3 and min(theta) > 0.1, f"a noisy demo has a visible σ:\n{out}"
    truth = re.search(rf"= ({_FLOAT})\s+({_FLOAT})\s+({_FLOAT}) σ", out)
    assert truth, out
    printed = [float(x) for x in truth.groups()]
    assert all(abs(e) <= 1.0 for e in printed), f"truth outside 1σ: {printed}"
    assert printed == _quoted_sigmas(), "the README quotes what estimate prints"


def test_the_python_snippet_prints_a_clean_summary(tmp_path):
    code = re.findall(r"```python\n(.*?)```", README, flags=re.S)[0]
    r = _run([sys.executable, "-W", "error", "-c", code], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "warning" not in r.stdout.lower() and r.stderr == "", r.stdout + r.stderr
    truth = re.search(rf"^truth .*error ({_FLOAT}), ({_FLOAT}), ({_FLOAT}) σ", r.stdout, flags=re.M)
    assert truth, r.stdout
    assert all(abs(float(e)) <= 1.0 for e in truth.groups()), r.stdout


def test_data_format_lists_every_shipped_scenario():
    import orbits

    text = (ROOT / "docs" / "data-format.md").read_text()
    section = text[text.index("## Scenario file (TOML)") :]
    table = section[: section.index("| key |")]
    listed = set(re.findall(r"^\| `([a-z0-9-]+)` \|", table, flags=re.M))
    assert listed == set(orbits.scenario_names())
