"""Step 6 of the diagnosis (issue 20): extra rotation errors per image and per pass estimated by
moments on the named model (``workflow._diagnose_problem`` redoes the diagnosis with them)."""

from __future__ import annotations

import numpy as np

from boresight.studies.discrepancy.linear import (
    extend,
)
from boresight.studies.discrepancy.state import _State
from orbits.errors import BoresightError
from orbits.rotations import ARCSEC


def _rotations_problem(problem, s_img, s_pass):
    from dataclasses import replace

    m = problem.model

    def add(old, s):
        return tuple(np.sqrt(np.asarray(old, float) ** 2 + s**2))

    return problem.with_model(
        replace(
            m,
            sigma_image_rotation_rad=add(m.sigma_image_rotation_rad, s_img),
            sigma_pass_rotation_rad=add(m.sigma_pass_rotation_rad, s_pass),
        )
    )


def _with_rotations(problem, st, s_img, s_pass, probes=True):
    """The model of ``st`` refitted with extra per-image / per-pass rotations σ (rad); the residual
    probes' columns only when asked (the per-image σ needs χ² alone)."""
    return _State(_rotations_problem(problem, s_img, s_pass), st.theta, st.named, [], probes=probes)


def _pass_probe_excess(s2):
    P = s2.cl.probes.get("pass")
    if P is None:
        return -1.0
    ext = extend(s2.base, P)
    return float(ext.delta_chi2 - ext.rank)


def _moment_sigma(fit, excess):
    """The σ ≥ 0 (rad) at which ``excess(fit(σ))`` (a statistic minus its dof, decreasing in σ)
    crosses 0; 0 when it does not exceed its dof at σ = 0."""
    from scipy.optimize import brentq

    f = lambda s: excess(fit(s))  # noqa: E731
    if f(0.0) <= 0:
        return 0.0
    lo, hi = 0.0, 1.0 * ARCSEC
    while f(hi) > 0:
        lo, hi = hi, 2 * hi
        if hi > 3600 * ARCSEC:
            raise BoresightError("diagnose: the unexplained scatter exceeds 1°")
    # DECISION: 1 % of σ is far below its sampling error (a moment estimate)
    return float(brentq(f, lo, hi, xtol=1e-3 * ARCSEC, rtol=1e-2))
