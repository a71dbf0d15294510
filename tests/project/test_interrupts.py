"""Interrupted commands (issue 14): Ctrl-C or SIGTERM leaves each command's outputs old or
complete and new — never a half-written file, never a mix of old and new files — and exits
130 (Ctrl-C) or 143 (SIGTERM) with one line (``boresight.reporting.outputs.writing_outputs``, the
atomic writers, ``cli.Terminated``). The studies' cases are in ``tests/studies/test_study_resume.py``.
"""

from __future__ import annotations

import os
import random
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import study_processes as sp  # noqa: E402

import boresight
from boresight import files
from boresight.reporting import outputs

ROOT = sp.ROOT
SENS = ROOT / "scenarios" / "kiev2012-sensitivity.toml"
K20 = ROOT / "scenarios" / "kiev2012-kalman20.toml"
CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _files(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _no_temporaries(folder: Path):
    left = [p.name for p in folder.rglob("*") if ".tmp-" in p.name]
    assert not left, f"temporary files left behind: {left}"


def _one_line(err: str, *needles):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], lines[0]


def _signal_after(module, name: str, sig, calls: int = 1):
    """Wrap ``module.name`` so that the process signals itself after ``calls`` calls returned —
    an interruption in the middle of writing a set of files."""
    real = getattr(module, name)
    count = {"n": 0}

    def wrapper(*a, **k):
        out = real(*a, **k)
        count["n"] += 1
        if count["n"] == calls:
            os.kill(os.getpid(), sig)
        return out

    return wrapper


def _signal_before(fn, sig):
    """``fn`` that signals the process first (e.g. ``os.replace``: the temporary file is
    complete, the rename not done)."""

    def wrapper(*a, **k):
        os.kill(os.getpid(), sig)
        return fn(*a, **k)

    return wrapper


@pytest.fixture(scope="module")
def two_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("obs")
    a, b = d / "a.ecsv", d / "b.ecsv"
    boresight.simulate(K20, np.random.default_rng(1), runs=1).write(a)
    boresight.simulate(K20, np.random.default_rng(2), runs=1).write(b)
    return a, b


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_estimate_interrupted_while_writing_leaves_the_complete_new_set(tmp_path, monkeypatch, two_files, sig):
    """A signal after the first of estimate's files is written: the command finishes the set
    (all new, identical to an uninterrupted run), then exits 130 / 143 with one line."""
    from boresight.cli import estimate as cmd

    a, b = two_files
    new, out = tmp_path / "new", tmp_path / "out"
    argv = ["estimate", "--no-check", "--out"]
    assert sp.cli([*argv, new, b])[0] == 0
    assert sp.cli([*argv, out, a])[0] == 0  # the old outputs
    old = _files(out)
    assert old.keys() == _files(new).keys() and old != _files(new)
    monkeypatch.setattr(cmd, "write_table", _signal_after(cmd, "write_table", sig))
    code, stdout, err = sp.cli([*argv, out, b])
    assert code == CODES[sig]
    _one_line(err, "interrupted" if sig == signal.SIGINT else "terminated (SIGTERM)", "no output was half-written")
    assert _files(out) == _files(new), "every file is the new one"
    _no_temporaries(out)


def test_an_exception_inside_the_write_leaves_the_old_file(tmp_path, monkeypatch):
    """atomic writers: a failure part-way through a file leaves the old file and no temporary."""
    p = tmp_path / "x.txt"
    files.atomic_write_text(p, "old")

    class Boom(Exception):
        pass

    real = Path.write_text

    def half(self, text, encoding=None):
        real(self, text[:3])
        raise Boom

    monkeypatch.setattr(Path, "write_text", half)
    with pytest.raises(Boom):
        files.atomic_write_text(p, "a much longer new text")
    monkeypatch.undo()
    assert p.read_text() == "old"
    _no_temporaries(tmp_path)


def test_signals_are_delivered_once_after_the_outputs_and_handlers_restored():
    seen = []
    previous = signal.signal(signal.SIGUSR1, signal.SIG_DFL)
    before = {s: signal.getsignal(s) for s in outputs.HELD_SIGNALS}
    try:
        with pytest.raises(KeyboardInterrupt):
            with outputs.writing_outputs():
                os.kill(os.getpid(), signal.SIGINT)
                os.kill(os.getpid(), signal.SIGINT)
                seen.append("wrote")
        assert seen == ["wrote"]
        assert {s: signal.getsignal(s) for s in outputs.HELD_SIGNALS} == before
    finally:
        signal.signal(signal.SIGUSR1, previous)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_simulate_signalled_mid_write_keeps_old_or_new_and_no_temporary(tmp_path, monkeypatch, sig):
    """simulate's single file: a signal while the file is being written (the temporary file
    complete, before the rename) — the file is the complete new one, no temporary."""
    out = tmp_path / "o"
    argv = ["simulate", SENS, "--out", out]
    assert sp.cli([*argv, "--seed", "1"])[0] == 0
    name = next(out.glob("*.ecsv")).name
    old = (out / name).read_bytes()
    assert sp.cli([*argv, "--seed", "2", "--out", tmp_path / "new"])[0] == 0
    new = (tmp_path / "new" / name).read_bytes()
    assert old != new
    monkeypatch.setattr(os, "replace", _signal_before(os.replace, sig))
    code, _, err = sp.cli([*argv, "--seed", "2"])
    assert code == CODES[sig]
    _one_line(err, "no output was half-written")
    assert (out / name).read_bytes() == new
    _no_temporaries(out)


def _reference_files(tmp_path, args):
    out = tmp_path / "o"
    assert sp.run([*args, "--out", out, "--seed", "1"]).returncode == 0
    name = next(out.glob("*.ecsv")).name
    assert sp.run([*args, "--seed", "2", "--out", tmp_path / "new"]).returncode == 0
    return out, name, (out / name).read_bytes(), (tmp_path / "new" / name).read_bytes()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals")
def test_a_real_sigterm_while_simulate_writes_its_file(tmp_path):
    """SIGTERM sent while ``simulate``'s temporary file is being written: the write completes
    and is renamed (the new file), then the command exits 143 with one line; no temporary."""
    args = ["simulate", K20, "--runs", "300", "--seed", "2"]
    assert sp.cli([*args, "--out", tmp_path / "new"])[0] == 0  # the reference, in-process
    name = next((tmp_path / "new").glob("*.ecsv")).name
    new = (tmp_path / "new" / name).read_bytes()
    out = tmp_path / "o"
    out.mkdir()
    proc = sp.start([*args, "--out", out])
    seen = False
    deadline = time.time() + 120
    while proc.poll() is None and time.time() < deadline:
        if any(".tmp-" in q.name for q in out.iterdir()):
            os.kill(proc.pid, signal.SIGTERM)
            seen = True
            break
        time.sleep(0.002)
    _, err = proc.communicate(timeout=120)
    assert seen, "the write was not caught in progress"
    assert proc.returncode == 143, err.decode()
    _one_line(err.decode(), "terminated (SIGTERM)", "no output was half-written")
    assert (out / name).read_bytes() == new
    _no_temporaries(out)


@pytest.mark.slow  # five process start-ups of a 400-run simulation
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals")
def test_sigterm_at_a_random_moment_leaves_old_or_new_simulate_output(tmp_path):
    """A real SIGTERM to a running ``simulate`` at a random moment (computing or writing): exit
    143 with one line (or 0 if it had finished), the file old or the complete new one, no
    temporary file."""
    args = ["simulate", K20, "--runs", "400"]
    out, name, old, new = _reference_files(tmp_path, args)
    args += ["--out", out]
    rng = random.Random(14)
    outcomes = []
    for delay in (rng.uniform(1.0, 4.0) for _ in range(3)):
        (out / name).write_bytes(old)
        proc = sp.start([*args, "--seed", "2"])
        time.sleep(delay)
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        err = err.decode()
        # -15: the signal came before the command started (SIGTERM's default action; nothing written)
        assert proc.returncode in (0, 143, -15), err
        if proc.returncode == 143:
            _one_line(err, "terminated (SIGTERM)")
        got = (out / name).read_bytes()
        assert got in (old, new), "a half-written or foreign file"
        assert proc.returncode != -15 or got == old
        assert proc.returncode != 0 or got == new
        _no_temporaries(out)
        outcomes.append((proc.returncode, "new" if got == new else "old"))
    print(outcomes)


def test_the_one_json_writer_is_atomic_and_keeps_numbers(tmp_path, monkeypatch):
    """boresight.files.write_json: numpy values as JSON numbers; a failed write leaves the old file."""
    import json

    import numpy as np

    p = files.write_json(tmp_path / "a.json", {"n": np.int64(3), "x": np.array([1.5, 2.0])})
    assert json.loads(p.read_text()) == {"n": 3, "x": [1.5, 2.0]} and p.read_text().endswith("}\n")
    monkeypatch.setattr(json, "dumps", lambda *a, **k: (_ for _ in ()).throw(ValueError("boom")))
    with pytest.raises(ValueError):
        files.write_json(p, {"n": 4})
    monkeypatch.undo()
    assert json.loads(p.read_text())["n"] == 3
    _no_temporaries(tmp_path)
