"""The one naming rule: when ``boresight.diagnose`` names an effect, and how large it must be.

Used by the diagnosis' verdicts (``naming.naming_rounds``), its minimum detectable sizes
(``naming.identifiability``) and the naming model (``naming_power``: the diagnosis' nameable sizes
and the campaign planner's scores): one definition, three users.

A candidate e with separable rank k and likelihood-ratio statistic Δχ²_e (``linear.extend``)
on n whitened data rows, tested at the Holm level ``level`` (α/K at the first step, K the
candidates in play), is

* **named** when it is *significant* (p = P(χ²(k) ≥ Δχ²_e) ≤ level) **and** *decisive* by BIC
  (ΔBIC = k ln n − Δχ²_e < 0), and no other significant candidate is an alternative
  (``AMBIGUITY_DLOGL``; the ambiguity test is in ``naming.naming_rounds``);
* **significant, not decisive** when p ≤ level but Δχ²_e ≤ k ln n: the data show the candidate's
  structure, but not strongly enough for BIC to prefer the larger model. The diagnosis reports it
  by name with the amount of data that would decide (``more_data_factor``), never as "no candidate
  explains";
* **not significant** otherwise.

Both legs are one threshold on Δχ²_e: ``critical_value`` = max(χ²_{1−level}(k), k ln n). For
one-parameter effects on a few hundred rows the LR leg binds (χ²_{0.99857}(1) = 10.2 against
ln 400 = 6.0); for the six-parameter thermal effect BIC binds (6 ln 400 = 35.9 against 21.6), so a
size quoted from the LR leg alone is named far less often than promised (the thermal effect at the
LR leg's "80 %" size was named in 1 seed of 10). With Δχ²_e ~ χ²(k, λ), λ = cᵀ C⊥ᵀC⊥ c for an effect of size c, the probability of
passing both legs is P(χ²(k, λ) > crit) and the **nameable non-centrality** λ* solves
P(χ²(k, λ*) > crit) = power (``nameable_noncentrality``); the reported minimum detectable size of
parameter j is √(λ*/F_jj) (F = C⊥ᵀC⊥ in the parameter's units).

>>> round(float(critical_value(1, 0.01 / 7, 400)), 2), round(float(critical_value(6, 0.01 / 7, 400)), 2)
(10.17, 35.95)
>>> classify(12.0, 1, 0.01 / 7, 400), classify(30.0, 6, 0.01 / 7, 400)
('named', 'significant, not decisive')
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.stats import chi2_isf, chi2_sf

__all__ = [
    "AMBIGUITY_DLOGL",
    "NamingRule",
    "bic_threshold",
    "critical_value",
    "classify",
    "nameable_noncentrality",
    "more_data_factor",
]

#: ambiguity rule: ΔlogL below this between two significant candidates' single fits
AMBIGUITY_DLOGL = 2.0

NAMED = "named"
NOT_DECISIVE = "significant, not decisive"
NOT_SIGNIFICANT = "not significant"


def bic_threshold(k, n_rows):
    """k ln n: the Δχ² above which BIC prefers the model with k more parameters (n ≥ 2 rows)."""
    return np.asarray(k, float) * np.log(np.maximum(np.asarray(n_rows, float), 2.0))


def critical_value(k, level, n_rows):
    """The naming threshold on Δχ²: max(χ²_{1−level}(k), k ln n) (module docstring); broadcasts."""
    return np.maximum(chi2_isf(level, k), bic_threshold(k, n_rows))


def classify(delta_chi2: float, k: int, level: float, n_rows: int) -> str:
    """``"named"``, ``"significant, not decisive"`` or ``"not significant"`` (module docstring;
    ambiguity with other candidates is judged separately)."""
    if k < 1 or not chi2_sf(delta_chi2, k) <= level:
        return NOT_SIGNIFICANT
    return NAMED if delta_chi2 > bic_threshold(k, n_rows) else NOT_DECISIVE


def nameable_noncentrality(k: int, level: float, n_rows: int, power: float) -> float:
    """λ* with P(χ²(k, λ*) > ``critical_value``(k, level, n)) = power: the smallest non-centrality
    the naming rule (both legs) passes with the given power.

    >>> round(nameable_noncentrality(1, 0.05, 10, 0.8), 2)  # LR leg binds: the classical 7.85
    7.85
    """
    from boresight.stats import minimum_detectable_noncentrality

    if k < 1:
        return float("inf")
    # the same power calculation at the level whose critical value is the rule's threshold
    return minimum_detectable_noncentrality(int(k), float(chi2_sf(critical_value(k, level, n_rows), k)), power)


def more_data_factor(delta_chi2: float, k: int, n_rows: int) -> float:
    """About how many times the data would make a significant, not decisive candidate decisive.

    With f times the data (the same geometry repeated) the expected statistic is k + f λ̂,
    λ̂ = max(Δχ² − k, 0) the observed non-centrality, while the BIC threshold grows to k ln(f n);
    the factor is the smallest f ≥ 1 with k + f λ̂ > k ln(f n) (a point estimate: λ̂ is one
    noisy draw). inf when λ̂ = 0.

    >>> round(more_data_factor(30.0, 6, 400), 2)
    1.32
    """
    lam = max(float(delta_chi2) - k, 0.0)
    if lam <= 0:
        return float("inf")
    g = lambda f: k + f * lam - k * np.log(f * max(n_rows, 2))  # noqa: E731
    if g(1.0) > 0:
        return 1.0
    hi = 2.0
    while g(hi) <= 0:
        hi *= 2.0
    from scipy import optimize

    return float(optimize.brentq(g, 1.0, hi, xtol=1e-6))


@dataclass(frozen=True)
class NamingRule:
    """The naming rule's settings as the planner models it (defaults: ``boresight.diagnose``'s).

    ``level`` α/K (Holm's first step), ``alpha`` the level of "e adds something once f is in",
    ``power`` the power of the quoted sizes, ``dlogl`` the ambiguity margin, ``rho_max`` the
    separability cut (``linear.SEPARABILITY_RHO``).
    """

    level: float
    alpha: float
    power: float
    dlogl: float = AMBIGUITY_DLOGL
    rho_max: float = 0.995

    @classmethod
    def from_diagnose(cls, level: float, alpha: float, power: float) -> NamingRule:
        from boresight.studies.discrepancy.linear import SEPARABILITY_RHO

        return cls(level=level, alpha=alpha, power=power, dlogl=AMBIGUITY_DLOGL, rho_max=SEPARABILITY_RHO)

    def critical_value(self, k, n_rows):
        """The detection threshold of this rule (``critical_value`` at ``level``)."""
        return critical_value(k, self.level, n_rows)
