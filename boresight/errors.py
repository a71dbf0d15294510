"""Typed errors of the estimators.

``ObservabilityError`` is raised instead of returning a θ that the data cannot determine
(too few landmarks, all landmarks along one line of sight, all landmarks at the boresight, …).
It subclasses ``ValueError`` so the CLI reports it as a user error.

Example
-------
>>> import numpy as np
>>> err = ObservabilityError("θz is unobservable", weak_axis=np.array([0.0, 0.0, 1.0]), condition_number=np.inf)
>>> isinstance(err, ValueError), err.weak_axis_name
(True, 'θz (about the boresight)')
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbits.errors import BoresightError
from orbits.limits import MemoryBudgetError

__all__ = [
    "BoresightError",
    "ObservabilityError",
    "MemoryBudgetError",
    "StudyLockedError",
    "ResumeError",
    "OutputPathError",
    "StudyError",
    "NoiseModelError",
    "MissingExtraError",
    "UnsupportedComputationError",
    "axis_name",
    "EXIT_OK",
    "EXIT_INPUT_ERROR",
    "EXIT_USAGE",
    "EXIT_NOT_CONVERGED",
    "EXIT_CONVENTION",
    "EXIT_NO_CAMPAIGN",
    "EXIT_INTERNAL_ERROR",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
]

# ---------------------------------------------------------------------------- exit codes
# The ``boresight`` command's exit status (docs/reliability.md). Shared by every command.

#: success (an estimate may still carry warnings, printed in the summary and JSON)
EXIT_OK = 0
#: the input was refused: a ``BoresightError`` (bad file, scenario, option, geometry, memory
#: budget, locked or mismatched study) or an ``OSError`` on a path the user gave
EXIT_INPUT_ERROR = 1
#: the command line itself is malformed (argparse's own status)
EXIT_USAGE = 2
#: an estimate was computed but did not converge (printed as such; results written)
EXIT_NOT_CONVERGED = 3
#: ``estimate``/``check`` found a convention slip in the data (mirrored axes, quaternion order, …)
EXIT_CONVENTION = 4
#: ``plan``: no candidate campaign in the search space meets every requirement (the outputs are
#: still written: the front shows the trade-offs)
EXIT_NO_CAMPAIGN = 5
#: a bug in boresight: a traceback is printed (please report it)
EXIT_INTERNAL_ERROR = 70
#: interrupted by the user (Ctrl-C); a study's finished blocks are kept for ``--resume``
EXIT_INTERRUPTED = 130
#: stopped by SIGTERM (``kill PID``; 128 + 15, what a shell reports for it): temporary files
#: removed, workers stopped, a study's finished blocks kept for ``--resume``
EXIT_TERMINATED = 143

_AXIS_NAMES = ("θx", "θy", "θz (about the boresight)")


def axis_name(v: Any) -> str:
    """Name a unit direction in θ space: ``'θz (about the boresight)'`` if one component
    carries ≥ 90 % of it (|v_i| ≥ 0.95), else the rounded vector, e.g. ``'[0.71, 0.00, 0.71]'``.

    >>> axis_name([0.0, -1.0, 0.0])
    'θy'
    >>> axis_name([0.6, 0.0, 0.8])
    'direction [0.60, 0.00, 0.80] in θ'
    """
    v = np.asarray(v, float)
    v = v / (np.linalg.norm(v) or 1.0)
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) >= 0.95 and i < len(_AXIS_NAMES):
        return _AXIS_NAMES[i]
    if abs(v[i]) >= 0.95:  # a floated effect's parameter (θ first, then the effects: estimate(effects=…))
        return f"floated parameter {i - len(_AXIS_NAMES) + 1} (after θx, θy, θz)"
    if v[i] < 0:
        v = -v
    where = "θ" if v.size <= len(_AXIS_NAMES) else "(θ, floated parameters)"
    return "direction [" + ", ".join(f"{c:.2f}" for c in v) + f"] in {where}"


class ObservabilityError(BoresightError, ValueError):
    """θ (or one of its axes) is not determined by the data.

    Attributes: ``weak_axis`` (3,) unit vector of the least-determined direction in θ (or
    None), ``weak_axis_name`` (str), ``condition_number`` (float, ``inf`` if singular),
    ``run`` (int or None) the first failing run of a batch.
    """

    def __init__(self, message: str, *, weak_axis: Any = None, condition_number: float | None = None, run: int | None = None):
        super().__init__(message)
        self.weak_axis = None if weak_axis is None else np.asarray(weak_axis, float)
        self.weak_axis_name = None if weak_axis is None else axis_name(weak_axis)
        self.condition_number = condition_number
        self.run = run


class StudyLockedError(BoresightError):
    """Another running study holds the output folder's lock. Attribute ``pid`` (int or None)."""

    def __init__(self, message: str, *, pid: int | None = None):
        super().__init__(message)
        self.pid = pid


class ResumeError(BoresightError, ValueError):
    """``--resume`` cannot continue: no interrupted study, or one with other inputs (scenario,
    seed, runs, …), or an output folder holding an interrupted study without ``--resume``."""


class OutputPathError(BoresightError, ValueError):
    """An output path is unusable (an existing file where a folder is needed, a name that would
    leave the output folder, …)."""


class StudyError(BoresightError, ValueError):
    """A Monte Carlo or sensitivity study cannot give a trustworthy number (a non-finite
    estimate, a singular noise model for the Kalman filter, …); the message says which
    algorithm, run and number of images, and what to change."""


class NoiseModelError(BoresightError, ValueError):
    """A noise (disturbance) model value is invalid: negative, non-finite, or beyond the bound
    that keeps its square and the weights finite (``docs/reliability.md``).

    ``field`` (the ``DisturbanceModel`` field) and ``reason`` are set where the model refuses a
    value, so a caller can name it as its user wrote it; None otherwise."""

    field: str | None = None
    reason: str | None = None


class MissingExtraError(BoresightError, ImportError):
    """An optional extra the request needs is not installed (``dask`` for ``engine="dask"``, …):
    the message names the extra and the ``pip install`` line. Raised before any output is
    written, so a command leaves no half-made folder (issue 31); the command line exits 1."""


class UnsupportedComputationError(BoresightError, NotImplementedError):
    """A quantity the library computes exactly only on some routes, asked for on another (e.g. the
    exact leverage of a campaign whose reduced system is factorised sparsely). The message names
    the route, the size that chose it and what is available instead; never approximated silently."""
