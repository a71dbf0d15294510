"""boresight — camera / star-tracker misalignment from ground landmarks.

The public API, in one place (as skyfield's ``api``): every name below is an entry point, and
nothing else is. Each is imported on first use, so ``import boresight`` costs nothing beyond
this file (``tests/project/test_startup.py``); the layers behind them are mapped in
``docs/architecture.md``.

Data
    ``ObservationSet`` (``ObservationSet.read(path)``), ``simulate(scenario, rng)``,
    ``check(observations)`` → ``ConventionReport`` — the convention doctor (raises
    ``ConventionError`` on a slip).
Estimation
    ``estimate(observations, ...)`` → ``Estimate`` (θ, σ as ``Quantity`` in arcsec), under a
    ``DisturbanceModel``.
Studies
    ``montecarlo_study(scenario, ...)`` → ``MonteCarloResult``; ``sensitivity_study(scenario,
    ...)`` → ``SensitivityResult`` (Kiev 2012 eq 28); ``diagnose(...)`` → ``Diagnosis`` (named
    missing effects; θ as ``theta``, a ``Quantity``);
    ``plan(spec)`` → ``PlanResult`` (a calibration campaign).
Errors
    ``BoresightError`` (every refusal), ``ObservationError``, ``ObservationFileError``,
    ``ObservabilityError``, ``ConventionError``.

>>> import boresight
>>> sorted(set(boresight.__all__) - set(dir(boresight)))
[]
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# DECISION: the names are resolved lazily (PEP 562 module __getattr__): ``import boresight`` and
# ``boresight --help`` must not pay for scipy.stats, astropy or matplotlib. Each entry:
# public name → (module, attribute). Nothing else is exported: the internals (NormalEquations,
# the campaign GLS, the registry) are imported from their modules.
_EXPORTS = {
    # data
    "ObservationSet": ("boresight.observations.model", "ObservationSet"),
    "simulate": ("boresight.observations.simulate", "simulate"),
    "check": ("boresight.observations.doctor", "check"),
    "ConventionReport": ("boresight.observations.doctor", "ConventionReport"),
    # estimation
    "DisturbanceModel": ("boresight.core.disturbances", "DisturbanceModel"),
    "estimate": ("boresight.core.estimation", "estimate"),
    "Estimate": ("boresight.core.result", "Estimate"),
    # studies
    "montecarlo_study": ("boresight.studies.montecarlo", "montecarlo_study"),
    "MonteCarloResult": ("boresight.studies.montecarlo", "MonteCarloResult"),
    "sensitivity_study": ("boresight.studies.sensitivity", "sensitivity_study"),
    "SensitivityResult": ("boresight.studies.sensitivity", "SensitivityResult"),
    "diagnose": ("boresight.studies.discrepancy", "diagnose"),
    "Diagnosis": ("boresight.studies.discrepancy", "Diagnosis"),
    "plan": ("boresight.studies.planning", "plan"),
    "PlanResult": ("boresight.studies.planning", "PlanResult"),
    # errors
    "BoresightError": ("boresight.errors", "BoresightError"),
    "ObservationError": ("boresight.errors", "ObservationError"),
    "ObservationFileError": ("boresight.errors", "ObservationFileError"),
    "ObservabilityError": ("boresight.errors", "ObservabilityError"),
    "ConventionError": ("boresight.observations.doctor", "ConventionError"),
}

__all__ = [*_EXPORTS, "__version__"]


def __getattr__(name: str):
    try:
        module, attr = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module 'boresight' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value  # resolved once
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
