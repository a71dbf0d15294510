"""Test configuration: property-based tests are seeded too (CONVENTIONS: "no unseeded test").

Hypothesis draws its examples from a fresh random seed on every run unless told otherwise, so a
failure could appear on one run and vanish on the next. ``derandomize=True`` makes the examples a
fixed function of each test, like a fixed ``SeedSequence``; ``print_blob`` shows how to reproduce
any failure. Run ``pytest --hypothesis-profile=explore`` to search with random seeds on purpose.
"""

from hypothesis import settings

settings.register_profile("seeded", derandomize=True, print_blob=True)
settings.register_profile("explore", derandomize=False, print_blob=True)
settings.load_profile("seeded")
