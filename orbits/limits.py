"""The memory budget: every size that would allocate more than it is refused up front.

A scenario with ``t_s = {start = 0, stop = 1000, step = 1e-9}``, a grid of 10⁶ × 10⁶ landmarks or
``--runs 1000000000000`` would otherwise grow for seconds and die with ``MemoryError`` (or take
the machine down). Instead the size is estimated *before* anything is allocated and compared
with ``memory_budget_bytes()``; above it, ``MemoryBudgetError`` names what was asked for, the
estimate and the budget.

DECISION: the budget is 4 GiB by default (a laptop runs it; a study that needs more is
chunked anyway), overridden by the environment variable ``BORESIGHT_MEMORY_BUDGET_GB``
(a positive number of GiB). Estimates are deliberately generous (they count the working set of
the simulation and the estimators, ``BYTES_PER_OBSERVATION`` per landmark observation per run,
not only the output array), so a refused size is at most a small factor below what would fit.

>>> check_memory("a test array", 1e3)
>>> try:
...     check_memory("10¹⁵ numbers", 8e15, hint="use fewer")
... except MemoryBudgetError as exc:
...     print(str(exc)[:62])
10¹⁵ numbers would need about 7.45e+06 GiB, over the memory bu
"""

from __future__ import annotations

import os

from .errors import BoresightError, MemoryBudgetError

__all__ = [
    "MemoryBudgetError",
    "memory_budget_bytes",
    "check_memory",
    "BYTES_PER_OBSERVATION",
    "BYTES_PER_IMAGE",
    "DEFAULT_MEMORY_BUDGET_GB",
]

#: default budget, GiB (``BORESIGHT_MEMORY_BUDGET_GB`` overrides it)
DEFAULT_MEMORY_BUDGET_GB = 4.0
#: working-set estimate per landmark observation per run: the simulation's arrays (truth,
#: errors, xy, camera vectors: ~25 float64) and the estimators' temporaries (Jacobians,
#: residuals, weights: ~25 more) — 400 bytes, measured within 2× on the Kiev scenarios
BYTES_PER_OBSERVATION = 400
#: per image per run: attitudes, positions, their errors (~60 float64)
BYTES_PER_IMAGE = 500


def memory_budget_bytes() -> float:
    """The memory budget in bytes (``BORESIGHT_MEMORY_BUDGET_GB`` or 4 GiB)."""
    raw = os.environ.get("BORESIGHT_MEMORY_BUDGET_GB")
    if raw is None or raw.strip() == "":
        return DEFAULT_MEMORY_BUDGET_GB * 2**30
    try:
        gb = float(raw)
    except ValueError:
        gb = float("nan")
    if not (gb > 0 and gb < 1e9):
        raise BoresightError(f"environment variable BORESIGHT_MEMORY_BUDGET_GB must be a positive number of GiB, got {raw!r}")
    return gb * 2**30


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


def check_memory(what: str, nbytes: float, hint: str = "") -> None:
    """Raise ``MemoryBudgetError`` if ``nbytes`` (an estimate; may be a huge float) exceeds the
    budget; ``what`` says what was asked for, as the user wrote it; ``hint`` how to shrink it."""
    budget = memory_budget_bytes()
    n = float(nbytes)
    if not n <= budget:  # also catches nan / inf from overflowing size arithmetic
        msg = f"{what} would need about {_gib(n)}, over the memory budget of {_gib(budget)}"
        msg += f" ({hint}; or raise BORESIGHT_MEMORY_BUDGET_GB)" if hint else " (raise BORESIGHT_MEMORY_BUDGET_GB to allow it)"
        raise MemoryBudgetError(msg, estimate_bytes=n, budget_bytes=budget)
