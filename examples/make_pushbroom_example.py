"""Make the pushbroom flight-style example data set in ``examples/pushbroom-pass/`` (see its README.md).

One strip of ``scenarios/pushbroom-strip.toml`` (a ZY-3-like line of three staggered 8 192-pixel chips, 10 000 lines of
0.31 ms rolled 10° toward a site near Beijing, 300 ground-control points on hills, 0.3 px of matching noise, the star
tracker's attitude at 4 Hz with 0.3″ of white error per sample, θ = (20, −35, 50)″ hidden), simulated with seed 2026
and exported as the files a pushbroom product comes as (``boresight.observations.flight.pushbroom.export_strip_files``):

* ``orbit.oem``            CCSDS OEM v2 (KVN, GCRF), the orbit's samples every second, Lagrange degree 7 (``oem``)
* ``attitude.aem``         CCSDS AEM (KVN, ICRF → STAR_TRACKER, scalar last), the tracker's measured samples at 4 Hz
                           (``ccsds-ndm``)
* ``landmarks.csv``        the ground-control points seen, ITRS metres
* ``line-detections.csv``  landmark, chip, line, pixel of every detection (fractional line and column)
* ``line-sensor.toml``     the focal length, the pitch, each chip's look-angle polynomials, the linear datation and
                           the tracker mount

Run from the repository root: ``python examples/make_pushbroom_example.py`` (needs the extra ``flight-export``; seeded:
the files are reproduced bit for bit on one machine; the committed ones were made this way).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from boresight.observations.flight.pushbroom import export_strip_files
from boresight.observations.strip import simulate_strip_scenario
from orbits.strip import load_strip_scenario

OUT = Path(__file__).resolve().parent / "pushbroom-pass"
SEED = 2026


def main() -> dict:
    sc = load_strip_scenario("pushbroom-strip")
    (obs,) = simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(SEED)))
    return export_strip_files(obs, OUT)


if __name__ == "__main__":
    for name, path in main().items():
        print(f"{name:16s} {path}")
