"""Every benchmark in ``benchmarks/`` runs, at a tiny size, in the default test suite — so none
can rot between the occasions someone measures with it (one crashed with ``KeyError: 'kalman'``
after a rename, and nobody saw). The smoke run checks that the script still works, not its
numbers: the figures quoted in the docs come from full-size runs, timed as whole processes in
interleaved pairs (docs/montecarlo.md).

A new ``benchmarks/bench_*.py`` must add its tiny command line to ``SMOKE``.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from paths import ROOT

BENCH = ROOT / "benchmarks"

#: script → its arguments at a tiny size (a few seconds each)
SMOKE = {
    "bench_diagnose.py": ["--repeats", "1", "--images", "24"],  # diagnose, estimate and the numpy reference
    "bench_effects.py": ["--repeats", "1", "--loops", "1"],
    "bench_eq28.py": ["--runs", "50"],
    "bench_estimate.py": ["--pairs", "1"],
    "bench_gls.py": ["large", "--images", "30"],
    "bench_montecarlo.py": ["--runs", "200", "--loop-runs", "5", "--skip-million", "--workers", "1"],
    "bench_montecarlo_weighting.py": ["--runs", "40", "--workers", "1"],
    "bench_plan.py": ["--candidates", "20", "--naive", "2"],
    "bench_pushbroom.py": ["--gcps", "20", "--lines", "2000", "--repeats", "1"],
    "bench_line_scan.py": ["--lines", "2000", "--gcps", "30", "--loops", "1", "--only", "strip"],
    "bench_scale.py": ["--tiles", "1", "--formats", "ecsv"],  # read and check, as flown and single-use
    "bench_startup.py": ["--pairs", "5", "--only=--version"],
    "bench_stars.py": ["--frames", "50", "--repeats", "1"],  # a star campaign against campaign-6pass
}


def test_every_benchmark_has_a_smoke_run():
    scripts = {p.name for p in BENCH.glob("bench_*.py")}
    missing = sorted(scripts - set(SMOKE))
    assert not missing, f"add a tiny command line for {missing} to SMOKE in tests/project/test_benchmarks.py"
    assert not sorted(set(SMOKE) - scripts), "SMOKE names a benchmark that no longer exists"


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_benchmark_smoke_run(script, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    r = subprocess.run(
        [sys.executable, str(BENCH / script), *SMOKE[script]], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, f"{script} {' '.join(SMOKE[script])}: exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    assert "Traceback" not in r.stderr
    # where its figures were taken (benchmarks/machine.py): a ratio without its machine is not a figure
    line = next((ln for ln in r.stdout.splitlines() if ln.startswith("machine: CPU ")), "")
    assert "; SIMD " in line and "; BLAS " in line and " kernel " in line, (
        f"{script} does not print machine_line():\n{r.stdout[:500]}"
    )


def test_machine_line_names_every_loaded_blas():
    """numpy's and scipy's wheels each load their own OpenBLAS (here 0.3.31 and 0.3.30), and a study
    runs both: ``machine_line`` names each BLAS threadpoolctl sees, with its package and kernel (it
    named only the first)."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    sys.path.insert(0, str(BENCH))
    try:
        from machine import _owner, machine_line
    finally:
        sys.path.remove(str(BENCH))
    line = machine_line()  # imports numpy and scipy.linalg: every BLAS a study loads
    libs = [i for i in threadpoolctl.threadpool_info() if i.get("user_api") == "blas"]
    assert line.count(" kernel ") == len(libs) >= 1, line
    for b in libs:
        assert f"{_owner(b['filepath'])}'s {b['internal_api']} {b['version']} kernel {b['architecture']}" in line, line


@pytest.mark.slow
def test_bench_montecarlo_default_sections_run(tmp_path):
    """``bench_montecarlo.py --skip-million --workers 2`` — the documented command without its
    million-run section — runs every section to the end (section 4 crashed while the smoke run used
    only ``--runs 200``); ≈ 40 s on 2 cores."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    argv = [sys.executable, str(BENCH / "bench_montecarlo.py"), "--skip-million", "--workers", "2"]
    r = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    assert "Traceback" not in r.stderr
