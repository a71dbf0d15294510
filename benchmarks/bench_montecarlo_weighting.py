"""Benchmark of ``boresight montecarlo --weighting`` (not part of the test run): a weighted study vs
the unit-weight study on the same runs (same scenario, seed, algorithm and image counts).

    python benchmarks/bench_montecarlo_weighting.py [--scenario kalman20|sensitivity|per-pass]
        [--runs 2000] [--workers 2] [--weighting all|unit|diagonal|gls]

With ``--weighting all`` (default) each weighting runs once in this process, in turn, and the
script prints its wall time, the ratio to the unit study, runs/s, and per axis the sample σθ and
the predicted σ (unit: linear propagation at the nominal geometry; diagonal/GLS: the mean σ the
estimator reports) for the largest image count. With one weighting it runs only that study, so
the whole process can be timed from outside, paired with ``--weighting unit`` for the ratio
(e.g. ``/usr/bin/time -v python benchmarks/bench_montecarlo_weighting.py --weighting gls``).

Scenarios: ``kalman20`` = scenarios/kiev2012-kalman20.toml (20 images × 4 landmarks, per-image
errors; image counts 1, 2, 4, 8, 12, 20); ``sensitivity`` = the one-image eq 28 case;
``per-pass`` = docs/estimators.md's per-pass case (Algorithm 1 geometry, 4 images, per-pass
star-tracker and GNSS biases), where GLS beats unit weighting. Figures: docs/montecarlo.md
("Weighting").
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # benchmarks/machine.py

import orbits  # noqa: E402
from boresight.studies import montecarlo as mc  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCEN = os.path.join(HERE, "..", "scenarios")


def scenario(name: str):
    if name == "kalman20":
        return orbits.load_scenario(os.path.join(SCEN, "kiev2012-kalman20.toml"))
    if name == "sensitivity":
        return orbits.load_scenario(os.path.join(SCEN, "kiev2012-sensitivity.toml"))
    sys.path.insert(0, os.path.join(HERE, "..", "tests"))
    from test_montecarlo_weighting import per_pass_doc  # the test's scenario, one definition

    return orbits.scenario_from_dict(per_pass_doc(), source="per-pass")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", choices=("kalman20", "sensitivity", "per-pass"), default="kalman20")
    ap.add_argument("--runs", type=int, default=2000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--weighting", choices=("all", "unit", "diagonal", "gls"), default="all")
    a = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    sc = scenario(a.scenario)
    ws = ("unit", "diagonal", "gls") if a.weighting == "all" else (a.weighting,)
    base = None
    print(f"{a.scenario}: {a.runs} runs, image_plane, seed {a.seed}, {a.workers} worker(s)")
    for w in ws:
        t0 = time.perf_counter()
        r = mc.montecarlo_study(sc, ["image_plane"], runs=a.runs, seed=a.seed, workers=a.workers, weighting=w)
        dt = time.perf_counter() - t0
        base = dt if w == "unit" else base
        pred = r.predicted.get("image_plane") if w == "unit" else r.reported_sigma_arcsec("image_plane")
        sd = r.sigma_arcsec("image_plane")[-1]
        ratio = f"  {dt / base:6.1f}× unit" if base and w != "unit" else ""
        print(f"{w:<9} {dt:8.2f} s  {a.runs / dt:9.0f} runs/s  (chunks of {r.chunk_runs}, counts {r.image_counts}){ratio}")
        print(
            f"          {r.image_counts[-1]} images: σθ = {np.array2string(sd, precision=3)}″, predicted "
            f"{np.array2string(pred[-1], precision=3) if pred is not None else '-'}″, unconverged "
            f"{int(np.sum(r.unconverged['image_plane']))}"
        )


if __name__ == "__main__":
    main()
