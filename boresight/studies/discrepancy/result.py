"""The result of ``boresight.diagnose``: the :class:`Diagnosis` dataclass, whose fields are
``diagnosis.json``'s keys (``docs/discrepancy.md`` gives the schema and its versions)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

__all__ = ["Diagnosis", "DIAGNOSIS_FORMAT", "DIAGNOSIS_VERSION"]

DIAGNOSIS_FORMAT = "boresight-diagnosis"
DIAGNOSIS_VERSION = "1.5"
# 1.1: "withdrawn"; 1.2: "not_decisive"; 1.3: "named_final"; 1.4: "pass_scatter";
# 1.5: "variance_components" replaces "pass_scatter"; "tails"; identifiability entries gain
# "confounded_with", then "min_nameable" and "nameable_rival" (added keys inside an entry: readers of 1.5
# ignore them, so the version stays)


@dataclass(frozen=True)
class Diagnosis:
    """The result of a diagnosis. Its fields are ``diagnosis.json``'s keys (``as_json()``);
    ``details`` (not in the JSON) keeps the residual tests, candidate tables and the data for
    the plots. ``docs/discrepancy.md`` gives every entry's keys.

    Attributes
    ----------
    format, version : str
        ``"boresight-diagnosis"`` and the schema version (``DIAGNOSIS_VERSION``).
    named : list of str
        The effects named, in the order they were named.
    steps : list of dict
        One per naming step: the effect, its estimate and σ at its naming (effect units, ``unit``),
        Δχ², p-value and χ²/dof before and after.
    named_final : list of dict
        The named effects' values in the final joint fit with θ.
    withdrawn : list of dict
        Names withdrawn because the structure left over questions them.
    ambiguous : list of dict
        Groups of candidates the data cannot tell apart (``effects``, ``would_split``).
    not_decisive : list of dict
        Candidates that are significant but not decisive by BIC (floated, not named).
    not_separable : list of dict
        Candidates the base model absorbs or that are undetectable in their physical range, with the
        θ shift at their typical size (``theta_shift_arcsec``) and what data would separate them.
    unexplained_structure : bool
        True when the final model's residuals still fail a test.
    identifiability : list of dict
        One per candidate, before naming: ``status`` (separability from θ and the nuisances),
        ``confounded_with`` (candidates it is not separable from), σ, correlations, minimum
        detectable and typical sizes (effect units, ``unit``).
    theta_arcsec, theta_sigma_arcsec : list of float
        θ of the final model and its σ, arcsec (``theta`` and ``theta_sigma`` give them as Quantities).
    variance_components : dict or None
        The noise model's scales re-estimated (REML) when the χ² test still failed; None otherwise.
    tails : dict or None
        The normalised residuals' tails when the outlier test failed; None otherwise.
    details : dict
        Not in the JSON: residual tests, candidate rounds and the data for the plots.
    """

    format: str
    version: str
    named: list
    steps: list
    named_final: list
    withdrawn: list
    ambiguous: list
    not_decisive: list
    not_separable: list
    unexplained_structure: bool
    identifiability: list
    theta_arcsec: list
    theta_sigma_arcsec: list
    variance_components: Any = None
    tails: Any = None
    details: dict = field(default_factory=dict, repr=False, compare=False)

    def as_json(self) -> dict:
        """``diagnosis.json``: every field in declaration order but ``details``, as plain JSON values."""
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self) if f.name != "details"}

    @property
    def theta(self):
        """θ of the final model as an astropy Quantity (arcsec), the public API's form of ``theta_arcsec``."""
        from astropy import units as u

        return np.asarray(self.theta_arcsec, float) * u.arcsec

    @property
    def theta_sigma(self):
        """θ's σ as an astropy Quantity (arcsec), the form of ``theta_sigma_arcsec``."""
        from astropy import units as u

        return np.asarray(self.theta_sigma_arcsec, float) * u.arcsec

    def summary(self) -> str:
        from boresight.studies.discrepancy.report import summary_text

        return summary_text(self)


def _plain(v):
    from boresight.files import json_ready

    return json_ready(v)


def scalar_or_list(a):
    a = np.atleast_1d(np.asarray(a, float))
    return float(a[0]) if a.size == 1 else [float(x) for x in a]
