"""Start-up benchmark (issue 19; not part of the test run): whole processes, interleaved in pairs.

    python benchmarks/bench_startup.py [--pairs 9]

Each case runs as a fresh process against its anchor, A B A B …, and the ratio is taken pair by
pair (pairing keeps it meaningful when the machine's speed drifts); the median ratio over the
pairs is printed with its min and max, for CPU time (user + system of the child, from
``resource.getrusage``) and wall time. Goals: ``boresight --help`` ≤ 2× ``python -c "import
numpy"``; ``import boresight`` ≤ 2× ``import numpy``. The modules these paths may load are pinned
by ``tests/project/test_startup.py``.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time

from machine import machine_line  # benchmarks/machine.py

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

CASES = {
    "boresight --help": [sys.executable, "-m", "boresight", "--help"],
    "boresight --version": [sys.executable, "-m", "boresight", "--version"],
    "boresight estmate (typo)": [sys.executable, "-m", "boresight", "estmate"],
    "boresight estimate --help": [sys.executable, "-m", "boresight", "estimate", "--help"],
    "import boresight": [sys.executable, "-c", "import boresight"],
}
ANCHOR = [sys.executable, "-c", "import numpy"]


def run_once(argv: list[str], env: dict) -> tuple[float, float]:
    """(CPU s, wall s) of one whole process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall


def paired(argv: list[str], anchor: list[str], pairs: int, env: dict) -> dict:
    run_once(argv, env), run_once(anchor, env)  # warm-up (file cache), not counted
    cpu, wall, a_cpu, b_cpu = [], [], [], []
    for _ in range(pairs):
        ca, wa = run_once(argv, env)
        cb, wb = run_once(anchor, env)
        cpu.append(ca / cb)
        wall.append(wa / wb)
        a_cpu.append(ca)
        b_cpu.append(cb)
    return {"cpu": cpu, "wall": wall, "a_cpu": a_cpu, "b_cpu": b_cpu}


def _fmt(v: list[float]) -> str:
    return f"{statistics.median(v):.2f} [{min(v):.2f}..{max(v):.2f}]"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=9, help="interleaved pairs per case (≥ 5; default 9)")
    ap.add_argument("--only", default="", help="run only the cases whose name contains this text")
    args = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    if args.pairs < 5:
        ap.error("--pairs: at least 5")
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    print(f"anchor: {' '.join(ANCHOR[1:])!r}; {args.pairs} interleaved pairs; median [min..max]")
    print(f"{'case':<28} {'CPU ratio':>20} {'wall ratio':>20} {'CPU s (case / anchor)':>24}")
    for name, cmd in CASES.items():
        if args.only not in name:
            continue
        r = paired(cmd, ANCHOR, args.pairs, env)
        print(
            f"{name:<28} {_fmt(r['cpu']):>20} {_fmt(r['wall']):>20} "
            f"{statistics.median(r['a_cpu']):>11.3f} / {statistics.median(r['b_cpu']):.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
