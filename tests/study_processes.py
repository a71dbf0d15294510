"""Test helpers for interrupted studies: a study's processes (from /proc), killing a study part-way
and checking that none of its processes survives, then resuming it, normalised JSON products.

Used by ``tests/project/test_reliability.py`` (montecarlo) and ``tests/studies/test_study_resume.py``
(sensitivity, the dask engine, the other commands). Linux only (``/proc``).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from paths import ROOT


def _ppids() -> dict[int, int]:
    out = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            out[int(d.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def children(pid: int) -> list[int]:
    """The direct children of ``pid``."""
    return [p for p, pp in _ppids().items() if pp == pid]


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (children, grandchildren, …: dask's nannies and their workers)."""
    ppids = _ppids()
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in ppids.items() if pp in frontier} - found
        found |= frontier
    return found


def alive(pid: int) -> bool:
    """``pid`` exists and has not finished (a zombie has finished)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] not in ("Z", "X")


def start(argv: list, **kw) -> subprocess.Popen:
    """``python -m boresight ARGV`` from the repository root (this work tree's code)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-m", "boresight", *map(str, argv)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kw,
    )


def run(argv: list, timeout: float = 300) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, "-m", "boresight", *map(str, argv)], cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout
    )


def watch_until(proc: subprocess.Popen, ready, timeout: float = 120, poll: float = 0.05) -> set[int]:
    """Poll until ``ready()`` or the process ends; returns every descendant seen meanwhile."""
    seen: set[int] = set()
    deadline = time.time() + timeout
    while time.time() < deadline and proc.poll() is None:
        seen |= descendants(proc.pid)
        if ready():
            break
        time.sleep(poll)
    if proc.poll() is None:
        seen |= descendants(proc.pid)
    return seen


def kill_and_check_none_survive(proc: subprocess.Popen, seen: set[int], sig=signal.SIGKILL, grace: float = 10) -> None:
    """Send ``sig`` to the study (not its workers), wait for it, and assert that none of the
    processes seen below it is alive ``grace`` seconds later."""
    assert proc.poll() is None, "the study finished before it could be killed: " + proc.stderr.read().decode()
    os.kill(proc.pid, sig)
    proc.wait(timeout=60)
    t0 = time.time()
    while any(alive(w) for w in seen) and time.time() - t0 < grace:
        time.sleep(0.05)
    survivors = sorted(w for w in seen if alive(w))
    assert not survivors, f"processes {survivors} survived their parent ({signal.Signals(sig).name})"


def killed_resumed_and_whole(argv: list, tmp: Path, blocks: int, products: tuple[str, ...]) -> tuple[int, Path, Path]:
    """Run the study ARGV twice, for a comparison of its products: into ``tmp/killed`` in a child
    process SIGKILLed once ``blocks`` checkpoint blocks are written — none of its processes may
    survive, nothing matching ``products`` (glob patterns) may be written yet — then ``--resume``d to
    the end (exit 0, the finished blocks reported, the checkpoint removed); and uninterrupted, in-process,
    into ``tmp/whole``. Returns (the blocks finished before the kill, the killed folder, the whole one)."""
    from boresight.studies.montecarlo.checkpoint import CHECKPOINT_DIR

    killed, whole = tmp / "killed", tmp / "whole"
    ck = killed / CHECKPOINT_DIR
    proc = start([*argv, "--out", killed])
    seen = watch_until(proc, lambda: len(list(ck.glob("block-*.npz"))) >= blocks)
    assert seen, "no worker processes seen"
    kill_and_check_none_survive(proc, seen, signal.SIGKILL)
    done = len(list(ck.glob("block-*.npz")))
    written = [p.name for pattern in products for p in killed.glob(pattern)]
    assert not written, f"{written} written before the study finished"
    resumed = run([*argv, "--out", killed, "--resume"])
    assert resumed.returncode == 0, resumed.stderr
    assert f"resumed: {done} finished block(s)" in resumed.stdout
    assert not ck.exists()
    code, _, err = cli([*argv, "--out", whole])
    assert code == 0, err
    return done, killed, whole


def normalised_json(p: Path, drop=("elapsed_s", "argv", "versions")) -> dict:
    """A JSON product without the fields that differ between two runs of the same study."""
    d = json.loads(p.read_text())
    for k in drop:
        d.pop(k, None)
    return d


def signal_name(code: int) -> str:
    return signal.Signals(-code).name if code < 0 else str(code)


def cli(argv, cwd=ROOT):
    """Run the CLI in-process: (exit code, stdout, stderr)."""
    from boresight.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    old = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([str(a) for a in argv])
    finally:
        os.chdir(old)
    return code, out.getvalue(), err.getvalue()
