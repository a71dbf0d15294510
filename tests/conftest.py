"""Test configuration: property-based tests are seeded too (CONVENTIONS: "no unseeded test").

Hypothesis draws its examples from a fresh random seed on every run unless told otherwise, so a
failure could appear on one run and vanish on the next. ``derandomize=True`` makes the examples a
fixed function of each test, like a fixed ``SeedSequence``; ``print_blob`` shows how to reproduce
any failure. Run ``pytest --hypothesis-profile=explore`` to search with random seeds on purpose.

Shared fixtures (built by ``tests/builders.py``, one instance per test module, so no module sees
another's changes): ``wgs84_kalman20`` (the kalman20 scenario on WGS-84) and ``flight_obs`` (one
run of it, seed 5: the set the flight-file tests export and read back).
"""

import builders
import pytest
from hypothesis import settings

settings.register_profile("seeded", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile("seeded")


@pytest.fixture(scope="module")
def wgs84_kalman20():
    return builders.wgs84_kalman20()


@pytest.fixture(scope="module")
def flight_obs(wgs84_kalman20):
    return builders.simulate_with_model(wgs84_kalman20, seed=5)[0]
