"""Generic statistics, below every layer that tests, weights or summarises.

Nothing here knows about cameras, landmarks or units: plain floats and arrays in. Three modules:

* :mod:`boresight.stats.intervals` — the χ² band at the one level :data:`CHI2_LEVEL` (library
  warnings and the command line), σ and rate intervals, the minimum detectable non-centrality;
* :mod:`boresight.stats.robust` — IRLS weights of the Huber, Cauchy and Tukey losses;
* :mod:`boresight.stats.residuals` — the MAD scale, robust z, binned / harmonic / serial
  structure of residuals, HAC covariance, nested F-test (used by ``pointing`` and ``studies``).

``scipy`` is imported inside the functions that need it, so importing this package is cheap.
"""

from boresight.stats import intervals as _intervals
from boresight.stats import residuals as _residuals
from boresight.stats.intervals import *  # noqa: F403 (the intervals, listed once in their module's __all__)
from boresight.stats.residuals import *  # noqa: F403 (the generic residual statistics, listed in their module's __all__)
from boresight.stats.robust import IRLS_LOSSES, irls_weight_slope, irls_weights

__all__ = [*_intervals.__all__, "IRLS_LOSSES", "irls_weights", "irls_weight_slope", *_residuals.__all__]
