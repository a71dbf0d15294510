"""The pre-flight sees every command (the row model, "The memory budget sees every command"): each
command that reads an observation file asks the memory budget before it allocates anything, and a
file it cannot hold is refused with the estimate in the message — the reader first (its working set
from the file's size, ``observations.ecsv.read_bytes``), then the consumer's own estimate where
what it builds is larger than the file (the Kalman filter's state history, the dense Cramér–Rao
oracle, the per-image covariance layout, the GLS on rows: their tests in ``tests/core``).

The budget is monkeypatched small (``BORESIGHT_MEMORY_BUDGET_GB``) so each test is fast; a traced
peak far below the estimate shows the refusal came before the allocation."""

import tracemalloc

import numpy as np
import pytest
from builders import campaign_as_flown, single_use

from boresight.cli.main import main
from boresight.observations.ecsv import read_bytes

COMMANDS = {
    "check": ["check", "{file}"],
    "estimate": ["estimate", "{file}", "--out", "{out}"],
    "estimate-kalman": ["estimate", "{file}", "--algorithm", "kalman", "--out", "{out}"],
    "estimate-homography": ["estimate", "{file}", "--algorithm", "homography", "--out", "{out}"],
    "diagnose": ["diagnose", "{file}", "--out", "{out}", "--no-plots"],
    "montecarlo-file": ["montecarlo", "{file}", "--runs", "10", "--out", "{out}", "--no-plots"],
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The as-flown campaign (120 images, ~1 300 observations) as ECSV and Parquet, and its
    single-use form (every observation its own target) as ECSV."""
    flown, _ = campaign_as_flown()
    d = tmp_path_factory.mktemp("budget")
    out = {"ecsv": flown.write(d / "flown.ecsv"), "single": single_use(flown).write(d / "single.ecsv")}
    try:
        import pyarrow  # noqa: F401

        out["parquet"] = flown.write(d / "flown.parquet")
    except ImportError:
        pass
    return out


def _run(argv, capsys):
    tracemalloc.start()
    try:
        rc = main(argv)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return rc, capsys.readouterr().err, peak


@pytest.mark.parametrize("name", list(COMMANDS))
def test_every_file_command_refuses_a_file_it_cannot_hold_with_the_estimate(name, files, tmp_path, capsys, monkeypatch):
    """A budget of half the reader's estimate for the file: the command exits non-zero with one line
    naming the file, the estimate (``read_bytes``, in GiB to 3 digits) and the budget, writes no
    output, and its traced peak (a second call: the imports done) stays below a tenth of the
    estimate — the read alone traces ≈ 0.8 of it, so nothing was read first."""
    path = files["ecsv"]
    need = read_bytes(path)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(0.5 * need / 2**30))
    out = tmp_path / "o"
    argv = [a.format(file=path, out=out) for a in COMMANDS[name]]
    _run(argv, capsys)  # the command's imports, outside the measurement
    rc, err, peak = _run(argv, capsys)
    assert rc != 0, err
    assert f"reading {path}" in err and f"would need about {need / 2**30:.3g} GiB" in err, err
    assert "over the memory budget" in err and "BORESIGHT_MEMORY_BUDGET_GB" in err
    assert peak < 0.1 * need, peak
    assert not out.exists() or not any(out.rglob("*.*"))


def test_parquet_is_estimated_from_its_decoded_columns(files, monkeypatch):
    """A Parquet file is compressed on disk: its estimate counts the decoded columns (rows × columns),
    so it is refused like the same ECSV file although it is far smaller on disk."""
    if "parquet" not in files:
        pytest.skip("pyarrow (the parquet extra) is not installed")
    from boresight import ObservationSet
    from orbits.limits import MemoryBudgetError

    pq = files["parquet"]
    assert pq.stat().st_size < files["ecsv"].stat().st_size / 3
    need = read_bytes(pq)
    assert need > 20 * pq.stat().st_size
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(0.5 * need / 2**30))
    with pytest.raises(MemoryBudgetError, match=rf"reading .*flown\.parquet .* would need about {need / 2**30:.3g} GiB"):
        ObservationSet.read(pq)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(2 * need / 2**30))
    assert ObservationSet.read(pq).n_observations > 1000


def test_the_read_estimate_covers_the_reader(files):
    """``read_bytes`` is an upper bound of the reader's traced peak (measured, not assumed): on the
    as-flown and the single-use files, ECSV (and Parquet when installed), within a factor 4 for ECSV."""
    from boresight import ObservationSet

    for path in files.values():
        ObservationSet.read(path)  # imports and caches outside the measurement
        tracemalloc.start()
        ObservationSet.read(path)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak <= read_bytes(path), (path.name, peak, read_bytes(path))
        if path.suffix == ".ecsv":  # (pyarrow's own allocations are not traced)
            assert read_bytes(path) <= 4 * peak, (path.name, peak, read_bytes(path))


def test_the_kalman_command_refuses_a_state_history_it_cannot_hold(files, tmp_path, capsys, monkeypatch):
    """Past the reader: the single-use campaign read fine under a budget of twice the reader's
    estimate, but the Kalman filter would carry a catalogue state per target (3 + 3 × 1 300 states,
    P_history N × n_x² ≈ 15 GB): refused with that estimate, before the filter allocates it."""
    path = files["single"]
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(2 * read_bytes(path) / 2**30))
    rc, err, peak = _run(["estimate", str(path), "--algorithm", "kalman", "--out", str(tmp_path / "o")], capsys)
    assert rc != 0
    assert "Kalman filter's state history of 1 run(s) × 120 images ×" in err and "would need about" in err, err
    est_gib = float(err.split("would need about ")[1].split(" GiB")[0])
    assert np.isfinite(est_gib) and est_gib > 10
    assert peak < 0.05 * est_gib * 2**30  # (what the command builds before the filter is its own)
