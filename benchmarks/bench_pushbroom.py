"""Benchmark of pushbroom location (not part of the test run): prints its figures.

    python benchmarks/bench_pushbroom.py [--gcps 500] [--lines 10000 100000] [--repeats 5]

On the ZY-3-like three-chip line (``orbits.strip.zy3_like_sensor``), a 30° roll strip at 40° N and every
forward-model effect on (θ, line-time offset and period error, chip offsets, focal scale, 0.65 Hz jitter), for each
strip length in ``--lines``: the median time of ``inverse_location`` of ``--gcps`` ground points (on 300-2700 m hills,
placed by ``direct_location``), per call and per point, and of ``direct_location`` of the same points. The strip's
length should not matter (location holds no per-line array: ``docs/pushbroom.md``, "Memory"); the cost should be
linear in the points.

For a whole-process comparison timed from outside (e.g. with ``/usr/bin/time``), ``--only inverse --loops 10`` and
``--only setup`` run just the set-up and then that many inverse locations.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # noqa: E402 - benchmarks/machine.py
from timing import median_time  # noqa: E402 - benchmarks/timing.py

from orbits.pushbroom import direct_location, inverse_location  # noqa: E402
from orbits.strip import StripConfig, hills_height_m, strip_geometry, zy3_like_effects, zy3_like_sensor  # noqa: E402

EFFECTS = zy3_like_effects()  # every forward-model effect on
terrain = hills_height_m  # hills of 300-2700 m


def setup(n_lines, n_gcps):
    sensor = zy3_like_sensor()
    geo = strip_geometry(StripConfig(sensor, roll_deg=30.0, n_lines=n_lines))
    rng = np.random.default_rng(3)
    line = rng.uniform(0, n_lines - 1, n_gcps)
    pixel = rng.uniform(0, sensor.n_pixels - 1, n_gcps)
    return sensor, geo, line, pixel


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gcps", type=int, default=500)
    ap.add_argument("--lines", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--only", choices=("setup", "inverse"), help="set-up (and --loops inverse locations), print nothing")
    ap.add_argument("--loops", type=int, default=10)
    a = ap.parse_args(argv)
    if not a.only:  # a timed child prints nothing
        print(machine_line())  # where the figures below were taken
    if a.only:
        sensor, geo, line, pixel = setup(a.lines[0], a.gcps)
        g = direct_location(sensor, geo.datation, geo.trajectory, line, pixel, EFFECTS, terrain)
        for _ in range(a.loops if a.only == "inverse" else 0):
            inverse_location(sensor, geo.datation, geo.trajectory, g, geo.line_range, EFFECTS)
        return
    print(f"{'lines':>8} {'GCPs':>6} {'direct s':>9} {'inverse s':>10} {'inverse µs/GCP':>15} {'seen':>6}")
    for n_lines in a.lines:
        sensor, geo, line, pixel = setup(n_lines, a.gcps)
        g = direct_location(sensor, geo.datation, geo.trajectory, line, pixel, EFFECTS, terrain)
        t_dir = median_time(
            lambda: direct_location(sensor, geo.datation, geo.trajectory, line, pixel, EFFECTS, terrain),  # noqa: B023
            a.repeats,
        )
        t_inv = median_time(
            lambda: inverse_location(sensor, geo.datation, geo.trajectory, g, geo.line_range, EFFECTS),  # noqa: B023
            a.repeats,
        )
        seen = int(inverse_location(sensor, geo.datation, geo.trajectory, g, geo.line_range, EFFECTS).seen.sum())
        print(f"{n_lines:>8} {a.gcps:>6} {t_dir:>9.3f} {t_inv:>10.3f} {1e6 * t_inv / a.gcps:>15.0f} {seen:>6}")


if __name__ == "__main__":
    main()
