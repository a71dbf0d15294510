"""Benchmark of the whole diagnosis of a 120-image campaign (issue 9: ≤ 10 s); not part of the test run.

    python benchmarks/bench_diagnose.py [--repeats 3]

Simulates ``scenarios/campaign-6pass.toml`` (120 images, ~1 300 observations, Kiev noise with
per-image *and* per-pass star-tracker/GNSS errors and catalogue errors: ~420 nuisance columns)
with a hidden 20 ms time tag, and times ``boresight.diagnose`` with the whole catalogue (base fit,
residual tests, identifiability of 8 effects, naming rounds, the refit after each name) against a
baseline measured in the same run on the same data: one GLS estimate of θ
(``boresight.estimate(weighting="gls")``). Figures are medians of ``--repeats``.

For a whole-process comparison timed from outside (``farm-bench``), ``--only diagnose`` and
``--only estimate`` run just that computation after the same set-up.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import orbits  # noqa: E402
from boresight import diagnose, estimate, simulate  # noqa: E402
from boresight.core.disturbances import DisturbanceModel  # noqa: E402

CAMPAIGN = os.path.join(os.path.dirname(__file__), "..", "scenarios", "campaign-6pass.toml")


def setup():
    import dataclasses

    sc = orbits.load_scenario(CAMPAIGN)
    sc = dataclasses.replace(sc, effects=orbits.effects.effect_sizes({"time_tag": {"dt_s": 0.02}}))
    obs = simulate(sc, np.random.default_rng(0))
    return obs, DisturbanceModel.from_scenario(sc)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", choices=("diagnose", "estimate"))
    a = ap.parse_args(argv)
    obs, model = setup()
    if a.only == "diagnose":
        diagnose(obs, model)
        return
    if a.only == "estimate":
        estimate(obs, weighting="gls", model=model)
        return
    td, te = [], []
    for _ in range(a.repeats):
        t = time.perf_counter()
        d = diagnose(obs, model)
        td.append(time.perf_counter() - t)
        t = time.perf_counter()
        estimate(obs, weighting="gls", model=model)
        te.append(time.perf_counter() - t)
    print(f"campaign: {obs.n_images} images, {obs.n_observations} observations; named {d.named}")
    print(f"diagnosis  median {np.median(td):.2f} s   one GLS estimate median {np.median(te):.2f} s   ratio {np.median(np.array(td) / np.array(te)):.1f}")


if __name__ == "__main__":
    main()
