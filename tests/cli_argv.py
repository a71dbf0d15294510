"""Command lines the tests share, written once (imported by name, like ``paths``): the two noise models
tests pass as options, and the ``boresight ingest`` command lines of the flight tests.

* ``KIEV2012_NOISE`` — the Kiev 2012 case's noise model (``scenarios/kiev2012-kalman20.toml``,
  ``builders.small_campaign``): σK = 3 µm on the focal plane, σβ = 4″ per star-tracker axis,
  σR = 15 m GNSS, σP = 0.1 m catalogue.
* ``TUTORIAL_NOISE`` — the flight tutorial's (``docs/tutorial-flight-data.md`` step 1;
  ``examples/flight-pass/README.md`` says where each σ comes from): 0.3 px, 4″, 1 m, 0.5 m.
* ``flight_pass_argv`` — the tutorial's step 1 on the shipped data set (``ingest --example flight-pass``).
* ``ingest_argv`` — ``ingest`` on the five files ``boresight.observations.flight.export_flight_files``
  wrote (its dict of paths).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

KIEV2012_NOISE = [
    "--sigma-pixel-m",
    "3e-6",
    "--sigma-star-tracker-arcsec",
    "4",
    "--sigma-gnss-m",
    "15",
    "--sigma-catalogue-m",
    "0.1",
]
TUTORIAL_NOISE = [
    "--sigma-pixel-px",
    "0.3",
    "--sigma-star-tracker-arcsec",
    "4",
    "--sigma-gnss-m",
    "1",
    "--sigma-catalogue-m",
    "0.5",
]


def flight_pass_argv(out: str | Path, *options: str) -> list[str]:
    """argv of ``boresight ingest --example flight-pass`` with the tutorial's noise model, writing ``out``,
    then ``options``."""
    return ["ingest", "--example", "flight-pass", *TUTORIAL_NOISE, "--out", str(out), *options]


def ingest_argv(
    files: Mapping[str, str | Path],
    out: str | Path,
    *options: str,
    orbit_attitude: list[str] | None = None,
    camera: str | Path | None = None,
) -> list[str]:
    """argv of ``boresight ingest`` on the files ``export_flight_files`` wrote (``files``: the paths it returns),
    writing ``out``, then ``options``.

    ``orbit_attitude`` replaces ``--oem ORBIT --aem ATTITUDE`` by other orbit and attitude options (an
    attitude CSV, SPICE kernels); ``camera`` replaces the camera TOML.
    """
    if orbit_attitude is None:
        orbit_attitude = ["--oem", str(files["orbit"]), "--aem", str(files["attitude"])]
    return [
        "ingest",
        *orbit_attitude,
        "--landmarks",
        str(files["landmarks"]),
        "--detections",
        str(files["detections"]),
        "--camera",
        str(files["camera"] if camera is None else camera),
        "--out",
        str(out),
        *options,
    ]
