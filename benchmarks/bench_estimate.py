"""Whole-process benchmark of ``boresight estimate`` on campaign files against a plain-numpy diagnosis.

    python benchmarks/bench_estimate.py [--pairs 5] [--images 120 1000 10000]

For each size it writes an observation file (120: ``scenarios/campaign-6pass.toml`` simulated with
seed 1, 1 320 observations, star-tracker/GNSS errors per image and per pass, catalogue errors;
larger: ``bench_gls.large`` — 20 site-tracking passes, 10 landmarks every image sees, the same noise
model), then runs, as whole processes interleaved in pairs (A B A B …, so drift of the shared
machine hits both alike):

* A: ``python -m boresight estimate FILE`` (GLS weighting from the file's noise model);
* B: ``python benchmarks/reference_diagnosis.py --file FILE`` — the independent plain-numpy whole
  diagnosis of ``bench_diagnose`` (dense per-image whitening and shared nuisance columns, GN fit,
  χ² and probe tests, every catalogue candidate's LR test, naming rounds) on the same file.

It prints, per command, the median and [min, max] of wall seconds, CPU seconds (user + system of the
child, from ``os.wait4``) and peak RSS (MiB), and the median and spread of the pair-by-pair ratio
A/B. Figures and the command used are in docs/estimators.md ("Speed of estimate").
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from machine import machine_line  # benchmarks/machine.py

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def make_file(images: int, folder: str) -> str:
    path = os.path.join(folder, f"campaign-{images}.ecsv")
    if images == 120:
        subprocess.run(
            [sys.executable, "-m", "boresight", "simulate", "campaign-6pass", "--seed", "1", "--out", folder],
            check=True,
            capture_output=True,
            cwd=ROOT,
        )
        os.replace(os.path.join(folder, "campaign-6pass.ecsv"), path)
        return path
    sys.path.insert(0, HERE)
    sys.path.insert(0, ROOT)
    from bench_gls import large

    from boresight.observations.ecsv import write_ecsv

    obs, _ = large(images)
    write_ecsv(obs, path)
    return path


def run(cmd) -> tuple[float, float, float]:
    """(wall s, CPU s, peak RSS MiB) of one whole process."""
    t = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode not in (0, 3):  # 3: estimate's "fit is suspect" exit still did the whole fit
        raise SystemExit(f"{cmd}: exit {p.returncode}: {p.stderr.read().decode()[-500:]}")
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024


def spread(x) -> str:
    x = np.asarray(x)
    return f"{np.median(x):7.3f} [{x.min():.3f}, {x.max():.3f}]"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--images", type=int, nargs="+", default=[120])
    a = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    with tempfile.TemporaryDirectory() as folder:
        for n in a.images:
            path = make_file(n, folder)
            A = [sys.executable, "-m", "boresight", "estimate", path]
            B = [sys.executable, os.path.join(HERE, "reference_diagnosis.py"), "--file", path]
            run(A), run(B)  # warm-up (file cache), not counted
            ra, rb = [], []
            for _ in range(a.pairs):
                ra.append(run(A))
                rb.append(run(B))
            ra, rb = np.array(ra), np.array(rb)
            print(f"{n} images ({a.pairs} interleaved pairs; median [min, max])")
            for name, r in (("estimate", ra), ("reference diagnosis", rb)):
                print(f"  {name:20s} wall {spread(r[:, 0])} s   CPU {spread(r[:, 1])} s   peak {spread(r[:, 2])} MiB")
            print(
                f"  ratio A/B            wall {spread(ra[:, 0] / rb[:, 0])}     CPU {spread(ra[:, 1] / rb[:, 1])}     "
                f"peak {spread(ra[:, 2] / rb[:, 2])}"
            )


if __name__ == "__main__":
    main()
