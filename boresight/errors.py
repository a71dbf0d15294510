"""The typed errors of ``boresight/``, every one a ``BoresightError``, in one file and grouped by the
layer that raises them:

* generic (every layer): ``ObservabilityError``, ``NoiseModelError``, ``MissingExtraError``,
  ``UnsupportedComputationError``; studies and their outputs: ``StudyError``, ``StudyLockedError``,
  ``ResumeError``, ``OutputPathError``;
* the estimation core (``core/``): ``UnknownErrorSourceError``, ``UnknownAlgorithmError``,
  ``UnknownEffectError``, ``HomographyError``;
* the data (``observations/``): ``ObservationError``, ``ObservationFileError`` (the data model and its
  file), ``ConventionError``, ``LargeRotationError``, ``InconclusiveError`` (the convention doctor),
  ``IngestError``, ``InterpolationError`` (flight-data ingestion);
* the studies (``studies/``): ``PlanError``.

Re-exported from ``orbits`` (the lower package, which must not import ``boresight``): the root
``BoresightError``, ``InputTypeError``, ``InputValueError`` and ``MemoryBudgetError`` (``orbits.errors``). The command line's exit codes are the command line's (``boresight.cli.exit_codes``).

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

from orbits.errors import BoresightError, EffectError, InputTypeError, InputValueError, MemoryBudgetError, extra_hint

__all__ = [
    "BoresightError",
    "InputTypeError",
    "InputValueError",
    "ObservabilityError",
    "MemoryBudgetError",
    "StudyLockedError",
    "ResumeError",
    "OutputPathError",
    "StudyError",
    "NoiseModelError",
    "MissingExtraError",
    "UnsupportedComputationError",
    "UnknownErrorSourceError",
    "UnknownAlgorithmError",
    "UnknownEffectError",
    "HomographyError",
    "ObservationError",
    "ObservationFileError",
    "ConventionError",
    "LargeRotationError",
    "InconclusiveError",
    "IngestError",
    "InterpolationError",
    "PlanError",
    "axis_name",
    "extra_hint",
    "OBSERVATION_SET",
]

#: what an ``observations`` argument takes, in ``InputTypeError.expected``'s wording
OBSERVATION_SET = "an ObservationSet (boresight.ObservationSet.read(path) or boresight.simulate(scenario, rng))"

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


# ---- generic: what θ the data determine, noise models, optional extras; studies and their outputs


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
    the message names the extra and how to install it (``extra_hint``). Raised before any output is
    written, so a command leaves no half-made folder; the command line exits 1."""


class UnsupportedComputationError(BoresightError, NotImplementedError):
    """A quantity the library computes exactly only on some routes, asked for on another. The
    message names the route, the size that chose it and what is available instead; never
    approximated silently (e.g. the exact leverage of rows whose per-image errors live on attitude
    samples, ``core/gls/rows.py``)."""


# ---- the estimation core's (core/): names, algorithms, images


class UnknownErrorSourceError(BoresightError, ValueError):
    """A source name that is not in the table (the message lists the valid ones)."""


class UnknownAlgorithmError(BoresightError, ValueError):
    """An algorithm name that is neither a name nor an alias in the table (the message lists them)."""


class UnknownEffectError(EffectError):
    """An effect name that is not in the catalogue; the message lists the valid names
    (a ``BoresightError`` and ``ValueError``, via ``orbits.effects.EffectError``)."""


class HomographyError(ObservabilityError):
    """An image cannot give a homography: fewer than 4 landmarks or a degenerate (collinear) set.

    The message names the run, the image, its time, the number of landmarks and the condition
    number of the (normalised) DLT matrix; ``run``, ``image`` and ``condition_number`` carry
    them too. A ``boresight.errors.ObservabilityError`` (hence a ``ValueError``).
    """

    def __init__(self, message: str, *, image: int | None = None, condition_number: Any = None, run: Any = None) -> None:
        super().__init__(message, condition_number=condition_number, run=run)
        self.image = image


# ---- the data's (observations/): the data model and its file, the convention doctor, flight-data ingestion


class ObservationError(BoresightError, ValueError):
    """An ObservationSet is inconsistent; the message names the field and the value."""


class ObservationFileError(ObservationError):
    """An observation file is malformed; the message names the column and the row."""


class ConventionError(BoresightError, ValueError):
    """The file's declared conventions fit the images far worse than a common slip does.

    ``slip`` is the name (a key of ``SLIPS``), ``report`` the full ``ConventionReport``. Every command
    that runs the doctor (``check``, ``estimate``, ``diagnose``, ``ingest``) lets it reach the CLI,
    which prints ``boresight COMMAND: ConventionError: …`` and exits 4 (``cli.exit_codes.EXIT_CONVENTION``).
    """

    def __init__(self, message: str, *, slip: str | None = None, report: Any = None) -> None:
        super().__init__(message)
        self.slip = slip
        self.report = report


class LargeRotationError(ConventionError):
    """The declared conventions need a rotation far beyond a small misalignment and no slip explains it."""


class InconclusiveError(ConventionError):
    """No tested slip fits better, but some images fit the declared conventions far worse than the
    noise (``boresight check`` refuses to say "conventions look right"; the message names them)."""


class IngestError(BoresightError, ValueError):
    """A flight-data file cannot be ingested; the message names the file, the key/column, the row and the value."""


class InterpolationError(IngestError):
    """An image time is outside the data, or the interpolation error estimate exceeds the stated bound."""


# ---- the studies' (studies/)


class PlanError(BoresightError, ValueError):
    """A plan file or dict is malformed; the message names the file, the key and the value."""
