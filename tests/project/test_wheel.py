"""Build the wheel, install it (a real install, dependencies resolved by pip) into a fresh venv,
and run every README command from a directory outside the checkout.

Every ``boresight …`` line of the README's ```bash blocks runs, and the Python block: scenario,
plan and report-template names resolve as package data, nothing is read from the checkout. Each
bash block is a sequence (a later line may read what an earlier one wrote); the blocks and the
Python block are independent, so they run two at a time (the machine's two cores).

Not run: ``python -m pytest`` (this is it). In the default run the three long jobs run with
fewer Monte Carlo runs / candidates (``SHORTER``: the same code paths, a smaller sample); the
``slow`` test runs every command exactly as the README prints it (.ci/run also runs the 45 000-run
main job right after ``pip install .``).
"""

import os
import re
import shlex
import subprocess
import sys
import venv
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from paths import ROOT

#: the default run's options appended to the README's long jobs (prefix of argv → extra options)
SHORTER = {
    ("boresight", "montecarlo", "kiev2012-sensitivity"): ["--runs", "2000"],  # 45 000 runs in the README
    ("boresight", "reproduce", "kiev2012"): ["--runs", "1000", "--kalman-runs", "50"],  # 45 000 / 2 000
    ("boresight", "plan", "kiev680"): ["--max-candidates", "2000"],  # 74 612 campaigns scored
}


def _readme_commands():
    """([[command, …] per ```bash block], [python blocks]) of the README."""
    text = (ROOT / "README.md").read_text()
    lanes = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        cmds = []
        for line in block.splitlines():
            for part in line.split("&&"):
                part = part.split("  #")[0].strip()
                if part.startswith("boresight "):
                    cmds.append(part)
        if cmds:
            lanes.append(cmds)
    python = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    return lanes, python


def test_readme_commands_are_found():
    lanes, python = _readme_commands()
    cmds = [c for lane in lanes for c in lane]
    assert "boresight montecarlo kiev2012-sensitivity" in cmds and len(python) == 1
    # the use section, the diagnosis / planning / report block: every command of the README
    for sub in ("simulate", "check", "estimate", "montecarlo", "sensitivity", "pointing", "diagnose", "plan", "reproduce"):
        assert any(c.split()[1] == sub for c in cmds), sub
    assert len(cmds) >= 14
    # a README command reads no file of the checkout: its inputs are names (package data) or
    # files an earlier README line wrote under out/
    for c in cmds:
        for tok in shlex.split(c)[2:]:
            if "/" in tok and not tok.startswith("-"):
                assert tok.startswith("out/"), c
    for prefix in SHORTER:
        assert any(tuple(shlex.split(c)[: len(prefix)]) == prefix for c in cmds), prefix


def _install(tmp_path):
    dist = tmp_path / "dist"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-w", str(dist), "-q"], capture_output=True, text=True
    )
    assert build.returncode == 0, build.stderr[-3000:]
    wheel = next(dist.glob("boresight-*.whl"))
    venv.EnvBuilder(with_pip=True, clear=True).create(tmp_path / "venv")
    bindir = tmp_path / "venv" / ("Scripts" if os.name == "nt" else "bin")
    py = bindir / "python"
    # without PYTHONPATH: a checkout on it (the usual PYTHONPATH=$PWD) with a boresight.egg-info from an
    # earlier build makes pip think boresight is already installed, and it skips the wheel
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    # DECISION: with the plot extra, as the tutorial installs it: its console blocks show the figures
    # written; the plain install (no matplotlib: figures skipped with a note) is covered in-process by
    # the tests that hide matplotlib (tests/cli/test_wrong_answers.py)
    inst = subprocess.run([str(py), "-m", "pip", "install", "-q", f"{wheel}[plot]"], capture_output=True, text=True, env=env)
    assert inst.returncode == 0, inst.stderr[-3000:]
    env["PATH"] = str(bindir) + os.pathsep + env.get("PATH", "")
    env["MPLBACKEND"] = "Agg"
    return py, env


def _run_readme(tmp_path, shorter: bool):
    py, env = _install(tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    lanes, python = _readme_commands()
    # the gallery's scripts ship with the package and run from there, as `boresight docs gallery` says
    listed = subprocess.run(["boresight", "docs"], cwd=work, env=env, capture_output=True, text=True)
    gallery = Path(re.search(r"gallery scripts .*, in (\S+):", listed.stdout).group(1))
    assert "site-packages" in str(gallery) and (gallery / "flight_pass.py").is_file(), listed.stdout
    r = subprocess.run(
        [str(py), "flight_pass.py"],
        cwd=gallery,
        env=dict(env, BORESIGHT_GALLERY_SMALL="1", BORESIGHT_GALLERY_OUT=str(work / "gallery")),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0 and (work / "gallery" / "pass.ecsv").exists(), r.stdout[-2000:] + r.stderr[-2000:]

    def run_lane(lane):
        for cmd in lane:
            argv = shlex.split(cmd)
            for prefix, extra in SHORTER.items() if shorter else ():
                if tuple(argv[: len(prefix)]) == prefix and extra[0] not in argv:  # a line that sets it keeps it
                    argv += extra
            if "--workers" not in argv and argv[1] in ("montecarlo", "sensitivity", "reproduce"):
                argv += ["--workers", "1"]  # two lanes already share the two cores
            r = subprocess.run(argv, cwd=work, env=env, capture_output=True, text=True, timeout=900)
            if r.returncode != 0:
                return f"{' '.join(argv)} → exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
        return None

    def run_python(code):
        r = subprocess.run([str(py), "-c", code], cwd=work, env=env, capture_output=True, text=True, timeout=900)
        return None if r.returncode == 0 else f"README python block → exit {r.returncode}\n{r.stderr[-2000:]}"

    def run_tutorial(_):
        """docs/tutorial-flight-data.md from an empty folder: the commands print what the doc shows."""
        from tutorial_doc import EXACT
        from tutorial_doc import console_blocks as _blocks

        folder = work / "tutorial"
        folder.mkdir()
        for argv, expected in _blocks():
            r = subprocess.run(["boresight", *argv], cwd=folder, env=env, capture_output=True, text=True, timeout=900)
            got = [ln for ln in r.stdout.splitlines() if EXACT.match(ln)]
            want = [ln for ln in expected if EXACT.match(ln)]
            if r.returncode != 0 or got != want:
                return f"tutorial: boresight {' '.join(argv)} → exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"
        return None

    # the longest lanes first, so the two workers finish together
    jobs = sorted(lanes, key=len, reverse=True)
    with ThreadPoolExecutor(max_workers=2) as pool:
        failures = (
            [f for f in pool.map(run_lane, jobs) if f]
            + [f for f in pool.map(run_python, python) if f]
            + [f for f in pool.map(run_tutorial, [None]) if f]
        )
    assert not failures, "\n\n".join(failures)
    # what the README promises was written, outside the checkout
    for path in (
        "tutorial/pass.ecsv",
        "tutorial/results/estimate.ecsv",
        "out/kiev2012-sensitivity/montecarlo.ecsv",
        "out/estimate",
        "out/diagnosis/diagnosis.md",
        "out/diagnosis-file/diagnosis.md",
        "out/plan/summary.md",
        "out/report/reproduction.md",
    ):
        assert (work / path).exists(), path
    # the package really is the installed wheel, not the checkout
    where = subprocess.run(
        [
            str(py),
            "-c",
            "import boresight, orbits; from boresight.studies.planning.spec import plan_path; "
            "from boresight.reproductions.kiev2012.report import SHIPPED_TEMPLATE; print(boresight.__file__); "
            "print(orbits.scenario_path('kiev2012-sensitivity')); print(plan_path('kiev680')); print(SHIPPED_TEMPLATE)",
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
    )
    lines = where.stdout.splitlines()
    assert len(lines) == 4 and all(str(ROOT) not in ln and "site-packages" in ln for ln in lines), where.stdout + where.stderr


def test_wheel_in_a_fresh_venv_runs_the_readme(tmp_path):
    if os.environ.get("BORESIGHT_SKIP_WHEEL_TEST"):
        pytest.skip("BORESIGHT_SKIP_WHEEL_TEST is set")
    _run_readme(tmp_path, shorter=True)


@pytest.mark.slow
def test_wheel_runs_the_readme_commands_verbatim(tmp_path):
    """Every README command exactly as printed (the 45 000-run jobs and the full plan search)."""
    _run_readme(tmp_path, shorter=False)
