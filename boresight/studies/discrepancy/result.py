"""The result of ``boresight.diagnose``: the :class:`Diagnosis` dataclass, whose fields are
``diagnosis.json``'s keys (``docs/discrepancy.md`` gives the schema and its versions)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Diagnosis", "DIAGNOSIS_FORMAT", "DIAGNOSIS_VERSION"]

DIAGNOSIS_FORMAT = "boresight-diagnosis"
DIAGNOSIS_VERSION = "1.5"
# 1.1: "withdrawn"; 1.2: "not_decisive"; 1.3: "named_final"; 1.4: "pass_scatter";
# 1.5: "variance_components" replaces "pass_scatter"; "tails"


@dataclass(frozen=True)
class Diagnosis:
    """The result of a diagnosis. Its fields are ``diagnosis.json``'s keys (``as_json()``);
    ``details`` (not in the JSON) keeps the residual tests, candidate tables and the data for
    the plots."""

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
        keys = (
            "format",
            "version",
            "named",
            "steps",
            "named_final",
            "withdrawn",
            "ambiguous",
            "not_decisive",
            "not_separable",
            "unexplained_structure",
            "identifiability",
            "theta_arcsec",
            "theta_sigma_arcsec",
            "variance_components",
            "tails",
        )
        return {k: _plain(getattr(self, k)) for k in keys}

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
