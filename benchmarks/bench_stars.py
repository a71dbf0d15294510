"""Cost per observation of a star campaign against a landmark campaign (issue 28, "Cost"): one process.

    python benchmarks/bench_stars.py [--frames 1000] [--repeats 5]

Star campaign: ``scenarios/star-calibration.toml`` with its segments replaced by one zenith-pointed
segment of ``--frames`` frames, 10 s apart (Hipparcos, Hp <= 7.5; star tracker 4" per image, centroid
0.1 pixel). Landmark campaign: ``scenarios/campaign-6pass.toml`` (120 images, 1 320 observations;
per-image and per-pass star-tracker and GNSS errors, catalogue errors). Each simulated once (seed 0);
then ``boresight.estimate(obs, "image_plane", weighting="gls")`` — the Gauss-Newton loop on the one
GLS, its warnings and σ — is timed ``--repeats`` times after one warm-up fit of each (imports and
the apparent directions' cache are not counted), and the median fit time per observation of each and
their ratio are printed. The apparent directions of the star rows (computed once per set, cached) are
timed apart.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tomllib

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # noqa: E402 - benchmarks/machine.py
from timing import median_time  # noqa: E402 - benchmarks/timing.py

import orbits  # noqa: E402
from boresight import estimate, simulate  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def _median_fit(obs, repeats: int) -> float:
    estimate(obs, "image_plane", weighting="gls")  # warm-up
    return median_time(lambda: estimate(obs, "image_plane", weighting="gls"), repeats)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    print(machine_line())
    with open(os.path.join(HERE, "..", "scenarios", "star-calibration.toml"), "rb") as f:
        d = tomllib.load(f)
    d["star_frames"] = [{"attitude": "zenith", "t_s": {"start": 0.0, "stop": 10.0 * (a.frames - 1), "step": 10.0}}]
    stars = simulate(orbits.scenario_from_dict(d, "bench_stars"), np.random.default_rng(0))
    t0 = time.perf_counter()
    stars.row_star_directions_i()
    t_dir = time.perf_counter() - t0
    landmarks = simulate(os.path.join(HERE, "..", "scenarios", "campaign-6pass.toml"), np.random.default_rng(0))
    t_s = _median_fit(stars, a.repeats)
    t_l = _median_fit(landmarks, a.repeats)
    us_s, us_l = 1e6 * t_s / stars.n_observations, 1e6 * t_l / landmarks.n_observations
    print(
        f"stars      {a.frames} frames asked, {stars.n_images} with stars, {stars.n_observations} rows, {stars.n_targets} stars: "
        f"fit {t_s:.3f} s = {us_s:.1f} us/observation (apparent directions, once: {t_dir:.3f} s)"
    )
    print(
        f"landmarks  campaign-6pass, {landmarks.n_images} images, {landmarks.n_observations} rows: fit {t_l:.3f} s = {us_l:.1f} us/observation"
    )
    print(f"ratio      stars / landmarks per observation = {us_s / us_l:.2f} (median of {a.repeats} fits each)")


if __name__ == "__main__":
    main()
