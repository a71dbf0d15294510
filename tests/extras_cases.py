"""What each optional library is needed for, as command lines, listed once.

The cases of ``tests/project/test_optional_extras.py`` (every plotting command without matplotlib;
every request refused without the extra it needs) and of the missing-library fuzz family of
``tests/project/test_fuzz.py`` (all of them, and other libraries a request may import). In an argv, ``OUT``
stands for a fresh output folder, ``OBS`` for a simulated ``kiev2012-kalman20`` observation file and
``TLE`` for a file holding ``TLE``.
"""

from __future__ import annotations

#: (name, argv, outputs that must exist under OUT) — the cheapest run of each plotting command
PLOTTING_COMMANDS = [
    ("estimate", ["estimate", "OBS", "--out", "OUT/est"], ["est/estimate.json"]),
    (
        "montecarlo",
        ["montecarlo", "kiev2012-kalman20", "--runs", "40", "--workers", "1", "--out", "OUT/mc"],
        ["mc/montecarlo.ecsv"],
    ),
    (
        "sensitivity",
        [
            "sensitivity",
            "scenarios/kiev2012-sensitivity.toml",
            "--runs",
            "200",
            "--algorithm",
            "image_plane",
            "--workers",
            "1",
            "--out",
            "OUT/sens",
        ],
        [],
    ),
    ("diagnose", ["diagnose", "OBS", "--out", "OUT/diag"], ["diag/diagnosis.md", "diag/diagnosis.json"]),
    ("pointing", ["pointing", "sea-sky", "--out", "OUT/sea"], ["sea/sea_sky.json"]),
    ("plan", ["plan", "kiev680", "--out", "OUT/plan", "--quiet"], ["plan/summary.md", "plan/plan.json"]),
]

#: (missing module, the extra the refusal must name, argv)
EXTRA_REQUESTS = [
    ("dask", "dask", ["montecarlo", "kiev2012-kalman20", "--runs", "20", "--engine", "dask", "--out", "OUT/mc"]),
    ("sgp4", "flight", ["ingest", "--example", "flight-pass", "--tle", "TLE", "--out", "OUT/pass.ecsv"]),
    (
        "spiceypy",
        "spice",
        [
            "ingest",
            "--example",
            "flight-pass",
            "--spk",
            "TLE",
            "--spice-target",
            "X",
            "--spice-kernel",
            "TLE",
            "--out",
            "OUT/p.ecsv",
        ],
    ),
]

#: (missing module, argv): other libraries these requests may import (the fuzz family asks exit 0, or a
#: one-line refusal that writes nothing)
OTHER_LIBRARIES = [
    ("filterpy", ["estimate", "OBS", "--algorithm", "kalman"]),
    ("lxml", ["ingest", "--example", "flight-pass", "--out", "OUT/r.ecsv"]),
    ("threadpoolctl", ["estimate", "OBS"]),
]

#: a two-line element set (the ISS, 2024-01-01), with its name line
TLE = (
    "ISS\n"
    "1 25544U 98067A   24001.50000000  .00016717  00000-0  10270-3 0  9005\n"
    "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.49815318432241\n"
)
