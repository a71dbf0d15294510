"""Benchmark of the effects catalogue's estimator side (not part of the test run): prints its figures.

    python benchmarks/bench_effects.py [--repeats 7] [--runs 1]

``boresight.core.effect_model.effect_columns`` (exact prediction, offset, ∂xy/∂θ and ∂xy/∂p) against a
baseline measured in the same run on the same data: the θ-only linearisation of Algorithm 3
(``boresight.core.measurement.linearize``), which every Gauss–Newton iteration computes anyway.

1. The 6-pass campaign (``scenarios/campaign-6pass.toml``: 120 images, ~1 300 observations):
   each effect alone, and all eight together (18 columns), at p = 0 and at p ≠ 0 (the offset
   needs a second prediction).
2. A dense long campaign: the same scenario replicated to ``--runs`` runs.

Figures are medians of ``--repeats`` timings, quoted as ratios to the baseline (the machine is
shared: absolute times are noisy). For a whole-process comparison timed from outside (e.g. with
``/usr/bin/time``), ``--only all --loops 30`` and ``--only baseline --loops 30`` run just that
computation 30 times after the same set-up.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # benchmarks/machine.py
from timing import median_time  # benchmarks/timing.py

from boresight import simulate  # noqa: E402
from boresight.core.effect_model import effect_columns, effect_names  # noqa: E402
from boresight.core.measurement import linearize  # noqa: E402
from orbits.effects import EFFECTS  # noqa: E402

CAMPAIGN = os.path.join(os.path.dirname(__file__), "..", "scenarios", "campaign-6pass.toml")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--only", choices=("all", "baseline"), help="run only this computation --loops times, print nothing")
    ap.add_argument("--loops", type=int, default=30)
    a = ap.parse_args(argv)
    if not a.only:  # a timed child prints only its own result
        print(machine_line())  # where the figures below were taken
    obs = simulate(CAMPAIGN, np.random.default_rng(0), runs=a.runs)
    theta = np.zeros(3)
    if a.only:
        for _ in range(a.loops):
            effect_columns(obs, theta, effect_names()) if a.only == "all" else linearize(obs, theta)
        return
    print(f"6-pass campaign: {a.runs} run(s), {obs.n_images} images, {obs.n_observations} observations per run")
    base = median_time(lambda: linearize(obs, theta), a.repeats)
    print(f"  baseline θ-only linearize             {base * 1e3:8.2f} ms")
    for name in effect_names():
        t = median_time(lambda: effect_columns(obs, theta, [name]), a.repeats)
        print(f"  {name:<22} ({EFFECTS[name].n_params} col)     {t * 1e3:8.2f} ms   {t / base:5.2f} × baseline")
    names = effect_names()
    t0 = median_time(lambda: effect_columns(obs, theta, names), a.repeats)
    params = {n: 0.1 * np.array(EFFECTS[n].scale) for n in names}
    t1 = median_time(lambda: effect_columns(obs, theta, names, params), a.repeats)
    print(f"  all 8 effects (18 columns), p = 0     {t0 * 1e3:8.2f} ms   {t0 / base:5.2f} × baseline")
    print(f"  all 8 effects (18 columns), p ≠ 0     {t1 * 1e3:8.2f} ms   {t1 / base:5.2f} × baseline")


if __name__ == "__main__":
    main()
