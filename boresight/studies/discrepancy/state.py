"""A fitted model of the diagnosis: θ and the named effects by Gauss–Newton on the one campaign GLS
(:class:`State`), and the final model θ is quoted from (an ambiguous or not-decisive group floated,
``final_state``) with the named effects' joint values (``final_values``)."""

from __future__ import annotations

import numpy as np

from boresight.studies.discrepancy.linear import (
    fit_base,
)
from boresight.studies.discrepancy.result import scalar_or_list
from boresight.studies.discrepancy.structure import residual_tests
from orbits.errors import BoresightError
from orbits.rotations import ARCSEC

#: Gauss–Newton convergence for θ (rad) and for named effects (in units of their typical size)
_TOL_THETA = 1e-6 * ARCSEC
_TOL_EFFECT = 1e-6
_MAX_GN = 20


class State:
    """θ (rad) and named effect values (candidate units) with the converged linearisation."""

    def __init__(self, problem, theta, named, cand_names, probes=True):
        self.problem = problem
        self.nb = getattr(problem, "n_base", 3)
        self.to_display = getattr(problem, "base_to_display", 1.0 / ARCSEC)
        self.theta = np.asarray(theta, float)
        self.named = {k: np.asarray(v, float) for k, v in named.items()}
        self.converged = False
        # Gauss–Newton on θ and the named effects alone; the candidate and probe columns are
        # whitened once, at the converged estimate.
        for _ in range(_MAX_GN):
            cl = problem.linearize(self.theta, self.named)
            bf = fit_base(cl.lin)
            step = bf.b[: cl.lin.n_fitted]
            nb = self.nb
            big = np.max(np.abs(step[:nb])) > _TOL_THETA
            i = nb
            for name in self.named:
                k = self.named[name].size
                big = big or np.max(np.abs(step[i : i + k])) > _TOL_EFFECT
                self.named[name] = self.named[name] + step[i : i + k] * named_scales(problem, name)
                i += k
            self.theta = self.theta + step[:nb]
            if not big:
                self.converged = True
                break
        self.cl = problem.linearize(self.theta, self.named, cand_names, probes=probes)
        self.base = fit_base(self.cl.lin)

    @property
    def cov(self):
        return self.base.covariance()

    def theta_arcsec(self):
        return self.theta * self.to_display

    def theta_sigma_arcsec(self):
        return np.sqrt(np.diag(self.cov)[: self.nb]) * self.to_display


def cl_scales(problem, name):
    cs = problem.candidates[name].columns(problem.obs, np.zeros(3), None)
    return problem.column_scales(problem.candidates[name], cs)


def named_scales(problem, name):
    c = problem.candidates[name]
    if c.scales is not None:
        return np.asarray(c.scales, float)
    return cl_scales(problem, name)


def final_state(problem, rec, st, tests, alpha):
    """The state θ is quoted from and its residual tests: the last named model, with the last
    ambiguous group (or the not-decisive candidates) floated, unnamed.

    DECISION: an ambiguous group is real structure the data cannot attribute: θ, its σ and the
    residual verdict come from the named model with the whole group floated (unnamed), so θ's σ
    covers not knowing which of them it is; a group the data cannot even fit jointly falls back on
    its first member. A significant candidate that is not decisive by BIC (rule.py) is floated the
    same way: the data show its structure, so θ must not be quoted as if it were absent.
    """
    group = rec["ambiguous"][-1]["effects"] if rec["ambiguous"] else [e["effect"] for e in rec["not_decisive"]]
    if not group:
        return st, tests
    for members in (group, group[:1]):
        named = dict(st.named)
        for g in members:
            named[g] = np.zeros(problem.candidates[g].n_params)
        try:
            floated = State(problem, st.theta, named, [], probes=True)
        except BoresightError:  # a degenerate group: try its first member alone
            continue
        (rec["ambiguous"][-1] if rec["ambiguous"] else rec)["floated"] = members
        return floated, residual_tests(floated.base, floated.cl.probes, alpha)
    return st, tests


def final_values(problem, st, names) -> list:
    """Each named effect's value and marginal σ in the final model (θ, every named effect and any
    floated group, fitted jointly): what the effects are, where each step's ``estimate`` is the
    value at its own naming, before the later names were added (a time tag named before a drift
    is pulled by the drift it cannot yet see: 0.0192 vs 0.0200 s, docs/discrepancy.md)."""
    order = list(st.named)
    sig = np.sqrt(np.clip(np.diag(st.cov), 0, None))
    out = []
    for name in names:
        c = problem.candidates[name]
        i0 = st.nb + sum(st.named[m].size for m in order[: order.index(name)])
        k = c.n_params
        out.append(
            {
                "effect": name,
                "estimate": scalar_or_list(st.named[name]),
                "sigma": scalar_or_list(sig[i0 : i0 + k] * named_scales(problem, name)),
                "unit": c.units[0] if k == 1 else list(c.units),
            }
        )
    return out
