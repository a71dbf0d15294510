"""The pre-flight's time estimate is measured, not modelled (issue 31, class 6).

The size model announced the README's 2 000-run GLS study (3-17 s) as "~8 min" on a quiet machine
and "~102 min" on a loaded one: 30-300× off. The estimate now comes from timing the study's own
first runs (``preflight.measured_seconds_per_run``). The property: the announced seconds within a
factor ``FACTOR`` of the time from the pre-flight line to the result.

DECISION: 3× in the default suite (two sub-second measurements on a machine shared by other
processes: the ratio wanders by ±50 % between repeats), 2× in the slow fuzz run over every shipped
study (``tests/project/test_fuzz.py``, which prints the ratios); the old model fails both by > 10×.
"""

from __future__ import annotations

import time

import pytest

from boresight.studies.montecarlo import montecarlo_study

FACTOR = 3.0

#: the README's studies (README.md, "boresight montecarlo …"), at their own sizes
README_STUDIES = {
    "gls": dict(scenario="kiev2012-sensitivity", runs=2000, weighting="gls"),
    "kalman20-all": dict(scenario="kiev2012-kalman20", runs=1000, algorithms="all"),
}


def preflight_ratio(scenario, **kw) -> tuple[float, float]:
    """(announced seconds, measured seconds from the pre-flight line to the result)."""
    got = {}

    def pf(d):
        got["seconds"], got["t"] = d["seconds"], time.perf_counter()

    montecarlo_study(scenario, preflight=pf, **kw)
    return got["seconds"], time.perf_counter() - got["t"]


@pytest.mark.parametrize("name", list(README_STUDIES))
def test_the_preflight_time_is_within_a_factor_of_the_measured_time(name):
    kw = dict(README_STUDIES[name])
    est, took = preflight_ratio(kw.pop("scenario"), **kw)
    # or within the line's resolution: it prints whole seconds (tests/project/test_fuzz.py, PREFLIGHT_RESOLUTION_S)
    assert took / FACTOR <= est <= took * FACTOR or abs(est - took) <= 0.5, (name, est, took)


def test_large_checkpoints_say_how_to_avoid_them():
    from boresight.studies.montecarlo.preflight import format_preflight

    line = format_preflight(dict(runs=10**9, cases=1, workers=2, memory_bytes=1e8, seconds=7200.0, disk_bytes=5 * 2**30))
    assert "5.00 GiB" in line and "--block-runs" in line, line
