"""Benchmark: the CPU cost per detection of a pushbroom strip's fit against a frame campaign's (not part of the test run).

    python benchmarks/bench_line_scan.py [--lines 10000] [--gcps 500] [--loops 3] [--only strip|frame|both] [--profile]

``strip``: one ZY-3-like strip (``scenarios/pushbroom-strip.toml``'s sensor, noise and roll) of ``--lines`` lines
with ``--gcps`` ground-control points, simulated once (seed 0), then θ fitted ``--loops`` times by
``boresight.core.line_scan.estimate_line_scan`` (the GLS on rows, the tracker's errors on the attitude-sample table).
``frame``: ``scenarios/campaign-6pass.toml`` (120 images, ~1 320 observations, per-image and per-pass star-tracker
and GNSS errors, catalogue errors), simulated once (seed 0), fitted ``--loops`` times by
``boresight.estimate(obs, weighting="gls", model=...)``. Each prints its in-process CPU time per fit
(``time.process_time``, the median of the loops) and per detection (observation), and with ``both`` the ratio
strip / frame per detection: issue 29 asks for ≤ 1. For whole-process figures, time ``--only strip --loops N``
against ``--loops 0`` (set-up only) from outside and divide the difference by N (``farm-bench --vs``, docs/pushbroom.md
"Cost"). ``--profile``: the strip's ``--loops`` fits again under ``cProfile``, the 20 largest cumulative entries.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # noqa: E402 - benchmarks/machine.py
from timing import median_time  # noqa: E402 - benchmarks/timing.py

HERE = os.path.dirname(os.path.abspath(__file__))


def strip_case(lines: int, gcps: int, loops: int, profile: bool = False) -> float:
    import dataclasses

    from boresight.core.line_scan import estimate_line_scan
    from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns
    from orbits.strip import GcpLayout, load_strip_scenario, simulate_strip, strip_geometry

    sc = load_strip_scenario(os.path.join(HERE, "..", "scenarios", "pushbroom-strip.toml"))
    cfg = dataclasses.replace(sc.strips[0], n_lines=lines)
    geo = strip_geometry(cfg)
    layout = dataclasses.replace(sc.layout, n_gcps=gcps) if isinstance(sc.layout, GcpLayout) else sc.layout
    obs = strip_observations(simulate_strip(geo, sc.truth(), np.random.default_rng(0), layout, sc.tracker, sc.sigma_pixel_px))
    model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
    fit = estimate_line_scan(obs, unknowns, model)
    cpu = median_time(lambda: estimate_line_scan(obs, unknowns, model), loops, time.process_time)
    k = obs.n_observations
    print(
        f"strip: {lines} lines, {gcps} GCPs, {k} detections, {obs.n_samples} tracker samples; θ σ "
        f"{np.array2string(fit.sigma[:3] * 206264.806, precision=4)}″; CPU per fit {cpu:.3f} s, per detection {cpu / k * 1e3:.3f} ms"
    )
    if profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.enable()
        for _ in range(loops):
            estimate_line_scan(obs, unknowns, model)
        prof.disable()
        pstats.Stats(prof).sort_stats("cumulative").print_stats(20)
    return cpu / k


def frame_case(loops: int) -> float:
    import orbits
    from boresight import estimate, simulate
    from boresight.core.disturbances import DisturbanceModel

    sc = orbits.load_scenario(os.path.join(HERE, "..", "scenarios", "campaign-6pass.toml"))
    obs, model = simulate(sc, np.random.default_rng(0)), DisturbanceModel.from_scenario(sc)
    estimate(obs, weighting="gls", model=model)
    cpu = median_time(lambda: estimate(obs, weighting="gls", model=model), loops, time.process_time)
    k = obs.n_observations
    print(
        f"frame: campaign-6pass, {obs.n_images} images, {k} observations; CPU per fit {cpu:.3f} s, per observation {cpu / k * 1e3:.3f} ms"
    )
    return cpu / k


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--lines", type=int, default=10_000)
    p.add_argument("--gcps", type=int, default=500)
    p.add_argument("--loops", type=int, default=3)
    p.add_argument("--only", choices=("strip", "frame", "both"), default="both")
    p.add_argument("--profile", action="store_true", help="profile the strip's fits (cProfile, 20 largest cumulative)")
    a = p.parse_args(argv)
    print(machine_line())
    s = strip_case(a.lines, a.gcps, a.loops, a.profile) if a.only in ("strip", "both") else None
    f = frame_case(a.loops) if a.only in ("frame", "both") else None
    if s is not None and f is not None:
        print(f"ratio strip / frame CPU per detection: {s / f:.3f}")


if __name__ == "__main__":
    main()
