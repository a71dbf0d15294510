"""Benchmark of the whole diagnosis of a 120-image campaign (issue 9: ≤ 10 s; issue 19: ≤ 1.5× an
independent numpy reference diagnosis, linear in images); not part of the test run.

    python benchmarks/bench_diagnose.py [--repeats 3] [--images N]

Simulates ``scenarios/campaign-6pass.toml`` (120 images, ~1 300 observations, Kiev noise with
per-image *and* per-pass star-tracker/GNSS errors and catalogue errors: ~420 nuisance columns)
with a hidden 20 ms time tag, and times ``boresight.diagnose`` with the whole catalogue (base fit,
residual tests, identifiability of 8 effects, naming rounds, the refit after each name) against a
baseline measured in the same run on the same data: one GLS estimate of θ
(``boresight.estimate(weighting="gls")``), and the independent reference diagnosis (below).
Figures are medians of ``--repeats``. ``--images N``
spreads N images over the same six passes (same landmarks, shorter steps) for the scaling runs.

For a whole-process comparison timed from outside, ``--only diagnose``, ``--only estimate`` and
``--only reference`` run just that computation after the same set-up (``--only setup``: the set-up
alone, the floor to subtract); ``reference`` is the
independent plain-numpy diagnosis of ``benchmarks/reference_diagnosis.py`` (the yardstick of
issue 19), e.g. (both pinned to one BLAS thread, pairs interleaved)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose.py --only diagnose
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_diagnose.py --only reference

Figures and commands: docs/discrepancy.md ("Speed").
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from machine import machine_line  # benchmarks/machine.py

import orbits  # noqa: E402
from boresight import diagnose, estimate, simulate  # noqa: E402
from boresight.core.disturbances import DisturbanceModel  # noqa: E402

CAMPAIGN = os.path.join(os.path.dirname(__file__), "..", "scenarios", "campaign-6pass.toml")


def setup(images: int | None = None):
    import dataclasses

    sc = orbits.load_scenario(CAMPAIGN)
    sc = dataclasses.replace(sc, effects=orbits.effects.effect_sizes({"time_tag": {"dt_s": 0.02}}))
    if images is not None:
        per = max(images // len(sc.passes), 2)
        passes = []
        for p in sc.passes:
            t = np.asarray(p.t_s, float)
            passes.append(dataclasses.replace(p, t_s=np.linspace(t.min(), t.max(), per)))
        sc = dataclasses.replace(sc, passes=passes)
    obs = simulate(sc, np.random.default_rng(0))
    return obs, DisturbanceModel.from_scenario(sc)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--only",
        choices=("diagnose", "estimate", "reference", "setup"),
        help="run one computation after the set-up (setup: nothing — the start-up and simulation floor)",
    )
    ap.add_argument("--images", type=int, default=None, help="spread this many images over the six passes")
    a = ap.parse_args(argv)
    if not a.only:  # a timed child prints only its own result
        print(machine_line())  # where the figures below were taken
    obs, model = setup(a.images)
    if a.only == "setup":
        print(f"setup: {obs.n_images} images, {obs.n_observations} observations")
        return
    if a.only == "diagnose":
        d = diagnose(obs, model)
        print(f"diagnose: named {d.named}; θ = {np.round(d.theta_arcsec, 3).tolist()} arcsec")
        return
    if a.only == "reference":
        from reference_diagnosis import reference_diagnosis

        theta, names, _ = reference_diagnosis(obs, model)
        print(f"reference: named {names}; θ = {np.round(theta / 4.84813681109536e-06, 3).tolist()} arcsec")
        return
    if a.only == "estimate":
        estimate(obs, weighting="gls", model=model)
        return
    from reference_diagnosis import reference_diagnosis

    td, te, tr = [], [], []
    for _ in range(a.repeats):
        t = time.perf_counter()
        d = diagnose(obs, model)
        td.append(time.perf_counter() - t)
        t = time.perf_counter()
        estimate(obs, weighting="gls", model=model)
        te.append(time.perf_counter() - t)
        t = time.perf_counter()
        _, ref_named, _ = reference_diagnosis(obs, model)
        tr.append(time.perf_counter() - t)
    td, te, tr = map(np.array, (td, te, tr))
    print(f"campaign: {obs.n_images} images, {obs.n_observations} observations; named {d.named} (reference: {ref_named})")
    print(
        f"diagnosis  median {np.median(td):.2f} s   one GLS estimate median {np.median(te):.2f} s   ratio {np.median(td / te):.1f}"
    )
    print(f"diagnosis / independent numpy reference diagnosis (in-process, pairwise median): {np.median(td / tr):.2f}")


if __name__ == "__main__":
    main()
