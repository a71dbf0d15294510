"""Interrupted and concurrent studies beyond ``montecarlo`` (issue 14, build item 5):

* ``sensitivity`` through the same checkpoint machinery: SIGKILL part-way at a random block,
  no process survives, ``--resume`` gives files byte-identical to an uninterrupted run; a
  resume with another scenario, seed or ``--rel-step`` is refused naming what changed; Ctrl-C
  keeps the finished blocks; a locked ``--out`` is refused; no NaN/inf in the products;
* the dask engine's workers die with their parent (PR_SET_PDEATHSIG armed; SIGKILL, SIGTERM);

The montecarlo cases are in ``tests/project/test_reliability.py``.
"""

from __future__ import annotations

import os
import random
import re
import signal
import sys
import tomllib
from pathlib import Path

import pytest
import study_processes as sp  # noqa: E402
from study_argv import killable_study
from toml_writer import dumps as toml_dumps  # noqa: E402

from boresight.cli.exit_codes import EXIT_INPUT_ERROR, EXIT_INTERRUPTED
from boresight.studies import montecarlo as mc
from boresight.studies.montecarlo.checkpoint import CHECKPOINT_DIR, StudyLock

ROOT = sp.ROOT
SENS = ROOT / "scenarios" / "kiev2012-sensitivity.toml"
LINUX = sys.platform.startswith("linux")
SENS_PRODUCTS = ("sensitivity_fd.ecsv", "sensitivity_linear.ecsv", "error_budget.ecsv")


_cli = sp.cli  # the CLI in-process: (exit code, stdout, stderr)


def _same_products(a: Path, b: Path, execution=()):
    """The products equal byte for byte (JSON: all but wall time, argv, versions and the
    ``execution`` settings — chunk size, workers — that the two runs chose differently)."""
    for name in SENS_PRODUCTS:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    drop = ("elapsed_s", "argv", "versions", *execution)
    assert sp.normalised_json(a / "sensitivity.json", drop) == sp.normalised_json(b / "sensitivity.json", drop)


class _CtrlCAfter:
    """A stand-in for ``montecarlo.ProgressBar`` that presses Ctrl-C once ``runs`` are done."""

    runs = 0

    def __init__(self, *a, **k):
        pass

    def __call__(self, done, total):
        if done >= self.runs:
            raise KeyboardInterrupt


# ---------------------------------------------------------------------------- sensitivity: resume, refusals, lock


def test_sensitivity_ctrl_c_then_resume_is_identical_and_changed_inputs_are_refused(tmp_path, monkeypatch):
    """Ctrl-C part-way (exit 130, one line, the finished blocks kept); a new study there, and a
    resume with another --seed, --rel-step or scenario value, are refused naming what changed;
    the resume with the same inputs writes the uninterrupted study's files byte for byte."""
    base = [
        "sensitivity",
        SENS,
        "--runs",
        "1200",
        "--block-runs",
        "100",
        "--chunk-runs",
        "100",
        "--workers",
        "1",
        "--seed",
        "5",
        "--no-plots",
    ]
    whole = tmp_path / "whole"
    code, _, err = _cli([*base, "--quiet", "--out", whole])
    assert code == 0, err

    out = tmp_path / "cut"
    monkeypatch.setattr(_CtrlCAfter, "runs", 500)
    monkeypatch.setattr(mc, "ProgressBar", _CtrlCAfter)
    code, stdout, err = _cli([*base, "--out", out])
    monkeypatch.undo()
    assert code == EXIT_INTERRUPTED == 130
    assert len(err.strip().splitlines()) == 1 and "interrupted" in err and "--resume" in err, err
    blocks = sorted((out / CHECKPOINT_DIR).glob("block-*.npz"))
    assert 5 <= len(blocks) < 12
    assert not any((out / n).exists() for n in (*SENS_PRODUCTS, "sensitivity.json")), "no product before the study finished"

    code, _, err = _cli([*base, "--quiet", "--out", out])
    assert code == EXIT_INPUT_ERROR and "holds an interrupted study" in err and "--resume" in err
    code, _, err = _cli([*base, "--quiet", "--out", out, "--resume", "--seed", "6"])
    assert code == EXIT_INPUT_ERROR and "(--seed 5 → 6)" in err, err
    code, _, err = _cli([*base, "--quiet", "--out", out, "--resume", "--rel-step", "0.5"])
    assert code == EXIT_INPUT_ERROR and "(--rel-step 1.0 → 0.5)" in err, err
    with open(SENS, "rb") as fh:
        d = tomllib.load(fh)
    d["gnss"]["sigma_m"] = 20.0
    other = tmp_path / "other.toml"
    other.write_text(toml_dumps(d))
    code, _, err = _cli([*base[:1], other, *base[2:], "--quiet", "--out", out, "--resume"])
    assert code == EXIT_INPUT_ERROR and "scenario sigma_gnss_m 15.0 → 20.0" in err, err
    code, _, err = _cli([*base, "--quiet", "--out", out, "--resume", "--algorithm", "unit_vector"])
    assert code == EXIT_INPUT_ERROR and "--algorithm" in err, err
    code, _, err = _cli(["montecarlo", *base[1:], "--quiet", "--out", out, "--resume"])
    assert code == EXIT_INPUT_ERROR and "(the command sensitivity → montecarlo)" in err, err
    assert sorted((out / CHECKPOINT_DIR).glob("block-*.npz")) == blocks, "a refused resume changes nothing"

    # the same study resumes (another chunk size and worker count change nothing)
    code, stdout, err = _cli([*base, "--quiet", "--out", out, "--resume", "--chunk-runs", "70", "--workers", "2"])
    assert code == 0, err
    assert f"resumed: {len(blocks)} finished block(s) of 100 runs" in stdout
    _same_products(out, whole, execution=("chunk_runs", "workers"))
    assert not (out / CHECKPOINT_DIR).exists()


def test_sensitivity_refuses_a_locked_output_folder(tmp_path):
    with StudyLock(tmp_path):
        code, _, err = _cli(["sensitivity", SENS, "--runs", "10", "--workers", "1", "--out", tmp_path, "--quiet", "--no-plots"])
    assert code == EXIT_INPUT_ERROR and len(err.strip().splitlines()) == 1
    assert f"pid {os.getpid()}" in err and "another boresight study is writing this folder" in err
    assert not list(tmp_path.glob("sensitivity*")), "the refused study wrote nothing"


@pytest.mark.parametrize("change", ["zero_gnss_sigma", "no_catalogue", "zero_star_tracker_axis"])
def test_sensitivity_products_never_hold_nan_or_inf(tmp_path, change):
    """Issue 14: "sensitivity with a zero GNSS σ or no [catalogue] table writes NaN/inf into its
    products". Each case alone: the undefined values are empty cells / null, with a note."""
    with open(SENS, "rb") as fh:
        d = tomllib.load(fh)
    if change == "zero_gnss_sigma":
        d["gnss"]["sigma_m"] = 0.0
    elif change == "no_catalogue":
        del d["catalogue"]
    else:
        d["star_tracker"]["sigma_arcsec"] = [4.0, 0.0, 4.0]
    p = tmp_path / "s.toml"
    p.write_text(toml_dumps(d))
    code, out, err = _cli(["sensitivity", p, "--runs", "300", "--workers", "1", "--quiet", "--out", tmp_path / "o"])
    assert code == 0, err
    assert "undefined value(s) left empty" in out
    bad = re.compile(r"(?<![\w/-])(nan|inf|infinity)(?![\w/-])", re.I)
    for f in (tmp_path / "o").iterdir():
        if f.suffix in (".ecsv", ".json"):
            assert not bad.search(f.read_text()), f
    # and the terminal table says "undefined", not nan
    assert not bad.search(out), out


@pytest.mark.skipif(not LINUX, reason="uses /proc and PR_SET_PDEATHSIG")
def test_sensitivity_sigkill_part_way_then_resume_is_byte_identical(tmp_path):
    """SIGKILL a 2-worker sensitivity study after a random number of finished blocks: no
    process of it survives, --resume completes it, and its files equal an uninterrupted run's
    byte for byte (JSON: all but wall time, argv and versions)."""
    k = random.Random(20261123).randint(2, 5)
    args = killable_study("sensitivity", runs=1000, seed=11)
    done, killed, whole = sp.killed_resumed_and_whole(args, tmp_path, k, products=(*SENS_PRODUCTS, "sensitivity.json"))
    assert k <= done < 10
    _same_products(killed, whole)


# ---------------------------------------------------------------------------- dask workers die with the study


def _pdeathsig():
    import ctypes

    v = ctypes.c_int(0)
    ctypes.CDLL(None, use_errno=True).prctl(2, ctypes.byref(v), 0, 0, 0)  # PR_GET_PDEATHSIG
    return os.getpid(), os.getppid(), v.value


@pytest.mark.skipif(not LINUX, reason="PR_SET_PDEATHSIG is Linux's")
def test_dask_local_cluster_workers_are_armed_to_die_with_the_study():
    """Each worker process of the LocalCluster a study starts has the kernel's parent-death
    signal (SIGKILL) armed, on top of dask's own parent-pipe watch."""
    pytest.importorskip("dask.distributed")
    eng = mc.make_engine("dask", workers=1)  # one worker process: the start-up is the cost
    try:
        got = eng.client.run(_pdeathsig)
    finally:
        eng.close()
    assert len(got) == 1
    for pid, ppid, sig in got.values():
        assert pid != os.getpid() and ppid == os.getpid() and sig == signal.SIGKILL


@pytest.mark.slow  # ~15-30 s each: a dask cluster's start-up, twice; the armed check above runs by default
@pytest.mark.skipif(not LINUX, reason="uses /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_dask_study_killed_leaves_no_worker_and_resumes(tmp_path, sig):
    """A dask-engine study killed part-way (SIGKILL: nothing runs in the study; SIGTERM): none
    of its processes survives, and --resume (local engine) completes it to the same table as
    an uninterrupted run."""
    pytest.importorskip("dask.distributed")
    args = killable_study("montecarlo", runs=1500, seed=3)
    out = tmp_path / "o"
    ck = out / CHECKPOINT_DIR
    proc = sp.start([*args, "--engine", "dask", "--out", out])
    seen = sp.watch_until(proc, lambda: len(list(ck.glob("block-*.npz"))) >= 2, timeout=180)
    assert len(seen) >= 2, f"the dask workers did not start: {seen}"
    sp.kill_and_check_none_survive(proc, seen, sig)
    resumed = sp.run([*args, "--workers", "1", "--out", out, "--resume"])
    assert resumed.returncode == 0, resumed.stderr
    assert "resumed:" in resumed.stdout
    code, _, err = _cli([*args, "--workers", "1", "--out", tmp_path / "whole"])
    assert code == 0, err
    assert (out / "montecarlo.ecsv").read_bytes() == (tmp_path / "whole" / "montecarlo.ecsv").read_bytes()


def test_a_checkpoint_of_an_older_format_is_refused_not_misread(tmp_path):
    """A study.json written by an older boresight (format 1, no study kind) is refused on
    resume, naming the format, rather than its blocks being merged."""
    import json

    from boresight.errors import ResumeError
    from boresight.studies.montecarlo.checkpoint import Checkpoint, identity_digest

    ck = tmp_path / CHECKPOINT_DIR
    ck.mkdir()
    old = {"format": 1, "seed": 1, "runs": 10}
    (ck / "study.json").write_text(json.dumps({"digest": identity_digest(old), "identity": old}))
    with pytest.raises(ResumeError, match=r"the checkpoint format \(an older boresight wrote it\) 1 → 2"):
        Checkpoint(ck).open({"seed": 1, "runs": 10}, resume=True)
