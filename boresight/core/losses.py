"""The robust losses ``estimate(loss=...)`` offers and their tuning constants, in a module that
imports nothing: the command line lists them in ``--help`` without loading the estimators
(``tests/project/test_startup.py``). The weights themselves are ``boresight.core.robust``.
"""

from __future__ import annotations

__all__ = ["LOSSES"]

#: robust losses: weight w(z) of an observation whose normalised residual vector has length z
#: (z = |e|/σ over its two components, e ~ N(0, σ² E₂) for a clean observation).
# DECISION: constants for the 2-D length z: Huber k = 2.45 = √χ²₂(0.95) (5 % of clean
# observations get a weight < 1); Cauchy c = 3.0 (a clean observation keeps w ≥ 0.64 at the
# 95th percentile); Tukey c = 4.9 (a clean observation is dropped with probability e^{−12}).
LOSSES: dict[str, float] = {"huber": 2.45, "cauchy": 3.0, "tukey": 4.9}
