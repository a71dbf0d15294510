"""Build the wheel, install it (a real install, dependencies resolved by pip) into a fresh venv,
and run every README command from a directory outside the checkout.

Not run here: ``python -m pytest`` (this is it), the developers' checkout-only
``boresight reproduce kiev2012 --out docs/`` (it regenerates the checkout's own report), and the
45 000-run main job ``boresight montecarlo kiev2012-sensitivity``: .ci/run runs that exact
command right after ``pip install .``; here the same command runs with ``--runs 500`` to keep this
test in the default run (pip's cache makes the install ~20 s on an idle machine).
"""

import os
import re
import shlex
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _readme_commands():
    text = (ROOT / "README.md").read_text()
    cmds = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            for part in line.split("&&"):
                part = part.split("  #")[0].strip()
                if part.startswith("boresight "):
                    cmds.append(part)
    python = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    return cmds, python


def test_readme_commands_are_found():
    cmds, python = _readme_commands()
    assert "boresight montecarlo kiev2012-sensitivity" in cmds and len(cmds) >= 7 and len(python) == 1


def test_wheel_in_a_fresh_venv_runs_the_readme(tmp_path):
    if os.environ.get("BORESIGHT_SKIP_WHEEL_TEST"):
        pytest.skip("BORESIGHT_SKIP_WHEEL_TEST is set")
    dist = tmp_path / "dist"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-w", str(dist), "-q"], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr[-3000:]
    wheel = next(dist.glob("boresight-*.whl"))
    venv.EnvBuilder(with_pip=True, clear=True).create(tmp_path / "venv")
    bindir = tmp_path / "venv" / ("Scripts" if os.name == "nt" else "bin")
    py = bindir / "python"
    inst = subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheel)], capture_output=True, text=True)
    assert inst.returncode == 0, inst.stderr[-3000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = str(bindir) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"
    cmds, python = _readme_commands()
    for cmd in cmds:
        argv = shlex.split(cmd)
        if argv[:3] == ["boresight", "montecarlo", "kiev2012-sensitivity"] and len(argv) == 3:
            argv += ["--runs", "500"]
        if "--workers" not in argv and argv[1] in ("montecarlo", "sensitivity"):
            argv += ["--workers", "1"]
        r = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, f"{cmd}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
    # the package really is the installed wheel, not the checkout
    where = subprocess.run([str(py), "-c", "import boresight, orbits; print(boresight.__file__); print(orbits.scenario_path('kiev2012-sensitivity'))"],
                           cwd=work, env=env, capture_output=True, text=True)
    assert str(ROOT) not in where.stdout and "site-packages" in where.stdout, where.stdout + where.stderr
    r = subprocess.run([str(py), "-c", python[0]], cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
