"""Everything about the Kiev 2012 seminar itself rather than the method: its reproduction.

The estimators (``boresight.core.algorithms``), the accuracy tools (``crlb``, ``sensitivity``) and the
Monte Carlo engine are general; this package holds what only makes sense for the seminar
(``docs/references.md`` [Kiev2012]):

* ``published`` — the seminar's published numbers (eq 28 table and σθ, the Algorithm 1 table,
  the eq 32 Kalman table), defined once;
* ``scenarios`` — its scenarios' variants (``kalman_scenario``, ``sensitivity_case``);
* ``algorithm1`` — our Algorithm 1 table and its modelling variants;
* ``eq28`` — our eq 28 sensitivities beside the seminar's (``eq28_comparison``);
* ``kalman_table`` — our eq 32 table (the library's filter on the seminar's scenario);
* ``report`` — the report sections and ``generate`` behind ``boresight reproduce kiev2012``.

Nothing in the library proper imports this package (``tests/project/test_layering.py``).
"""

from boresight.reproductions.kiev2012.algorithm1 import algorithm1_table, algorithm1_variants
from boresight.reproductions.kiev2012.eq28 import eq28_comparison, seminar_table
from boresight.reproductions.kiev2012.kalman_table import kalman_table
from boresight.reproductions.kiev2012.published import (
    SEMINAR_ALGORITHM1_TABLE,
    SEMINAR_EQ28,
    SEMINAR_EQ28_SIGMA_ARCSEC,
    SEMINAR_EQ28_UNITS,
    SEMINAR_KALMAN_ROWS,
    seminar_kalman_table,
)
from boresight.reproductions.kiev2012.scenarios import SCENARIOS, kalman_scenario, sensitivity_case

__all__ = [
    "SEMINAR_ALGORITHM1_TABLE",
    "SEMINAR_EQ28",
    "SEMINAR_EQ28_SIGMA_ARCSEC",
    "SEMINAR_EQ28_UNITS",
    "SEMINAR_KALMAN_ROWS",
    "seminar_kalman_table",
    "SCENARIOS",
    "kalman_scenario",
    "sensitivity_case",
    "algorithm1_table",
    "algorithm1_variants",
    "kalman_table",
    "eq28_comparison",
    "seminar_table",
]
