"""The Cramér–Rao bound: the ONE deliberately independent dense route (a test oracle in the library).

The disturbance model (``boresight.core.disturbances``) perturbs the image-plane residuals of image n
by e_n = Σ_src J_src,n ε_src. Every estimator carries that error structure block by block — one
builder (``boresight.core.gls.structure``) and one block-sparse GLS (``boresight.core.gls.campaign``:
per-image errors eliminated image by image, per-pass and catalogue errors as nuisances). This module
deliberately does NOT: ``full_residual_covariance`` builds the dense covariance Σ of all a run's
residuals draw by draw (one column per independent error: per image, per pass, per landmark; mode
``both`` contributes to both), straight from ``disturbances.error_jacobians``, and
``fisher_information`` whitens with its dense Cholesky factor. A set's per-row pixel σ
(``sigma_xy_m``, NaN: the model's σK) is that row's diagonal of Σ, read here on its own. It is kept independent on purpose so
the tests can compare the fast routes against it (``tests/oracles.py`` lists the deliberate oracles;
``tests/core/test_campaign_gls.py``, ``tests/studies/test_planning.py``, ``tests/core/test_gls_crlb.py`` compare).
Memory grows as (2NM)²: meant for bounds of small campaigns and for checks; the memory budget
refuses a larger one with its estimate before anything is allocated.

The Fisher information of θ under the linearised Gaussian model is I(θ) = Gᵀ Σ⁻¹ G (plus the
prior information, if any); the Cramér–Rao bound is I⁻¹. It does not depend on which
algorithm builds G (any invertible L cancels), so it is computed from image-plane residuals.

Example
-------
>>> import numpy as np
>>> from boresight import simulate
>>> from boresight.core.disturbances import DisturbanceModel
>>> obs = simulate("scenarios/kiev2012-sensitivity.toml", np.random.default_rng(0))
>>> model = DisturbanceModel(sigma_pixel_m=3e-6)
>>> crb = cramer_rao_bound(obs, model, obs.truth["theta_rad"])
>>> crb.unit, crb.shape
(Unit("arcsec2"), (3, 3))
"""

from __future__ import annotations

from typing import Any

import numpy as np
from astropy import units as u

from boresight.core.disturbances import DisturbanceModel, error_jacobians
from boresight.core.gls.structure import modes
from orbits.limits import BYTES_PER_OBSERVATION, check_memory
from orbits.rotations import ARCSEC

__all__ = ["full_residual_covariance", "fisher_information", "cramer_rao_bound", "full_covariance_bytes"]


def full_covariance_bytes(runs: int, n_images: int, n_targets: int, n_passes: int) -> float:
    """Working set (bytes) of the dense route on R runs × N images × M targets (P passes): K = 2NM
    residual components per run; three K × K float64 matrices (Σ, its masked copy, its Cholesky
    factor), the error columns twice (the per-draw columns and their concatenation, K × 3(N + P + M)
    each: one column per independent draw), the dense error Jacobians (three R × N × M × 2 × 3) and
    the images × targets view (``BYTES_PER_OBSERVATION`` per cell, ``observations.model``)."""
    R, N, M, P = (float(v) for v in (runs, n_images, n_targets, n_passes))
    K = 2.0 * N * M
    return R * (3 * 8 * K**2 + 2 * 8 * K * 3 * (N + P + M) + 3 * 8 * N * M * 6 + BYTES_PER_OBSERVATION * N * M)


def _check_budget(obs: Any, who: str) -> None:
    """Refuse (``MemoryBudgetError`` with the estimate) the dense route before anything is allocated."""
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    P = int(np.unique(np.asarray(obs.pass_index)).size)
    check_memory(
        f"{who}: the dense residual covariance (the Cramér–Rao oracle) of {R} run(s) × {N} images × {M} targets"
        f" ({2 * N * M} residual components per run)",
        full_covariance_bytes(R, N, M, P),
        hint="the GLS of boresight.estimate(..., weighting='gls') gives the same bound without the dense Σ (its covariance)",
    )


def full_residual_covariance(obs: Any, theta_rad: Any, model: DisturbanceModel) -> np.ndarray:
    """Dense covariance of all image-plane residuals of each run, (R, 2NM, 2NM).

    Built source by source with one column per independent error draw (per image, per pass,
    per landmark); masked rows get unit variance and no correlation. Memory grows as (2NM)²:
    meant for a bound and for checks, not for a 45 000-run Monte Carlo (``boresight.core.gls.structure``
    and ``boresight.core.gls.campaign`` carry the same structure block by block). Refused with its
    estimate (``full_covariance_bytes``, ``orbits.limits.MemoryBudgetError``) before anything is
    allocated when it would not fit the memory budget.
    """
    _check_budget(obs, "full_residual_covariance")
    own = getattr(obs, "sigma_xy_m", None)  # a row's own pixel σ (NaN: the model's), before the view drops it
    rows = None if own is None else (np.asarray(obs.image_index), np.asarray(obs.target_index))
    obs = obs.dense_view()  # dense by design: the independent oracle (module docstring), the budget asked first
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    K = 2 * N * M
    pixel_var = np.full((N, M, 2), model.sigma_pixel_m**2)
    if rows is not None:
        own = np.asarray(own, float)
        pixel_var[rows[0], rows[1]] = np.where(np.isnan(own), model.sigma_pixel_m, own) ** 2
    J = error_jacobians(obs, theta_rad)
    cols, var = [], []
    st_img, st_pass = modes(model.star_tracker_mode)
    g_img, g_pass = modes(model.gnss_mode)
    st_var = np.asarray(model.sigma_star_tracker_rad) ** 2
    for key, v, per_img, per_pass in (
        ("star_tracker", st_var, st_img, st_pass),
        ("gnss", np.full(3, model.sigma_gnss_m**2), g_img, g_pass),
    ):
        Jx = J[key]  # (R, N, M, 2, 3)
        if per_img:
            for n in range(N):
                c = np.zeros((R, N, M, 2, 3))
                c[:, n] = Jx[:, n]
                cols.append(c.reshape(R, K, 3))
                var.append(v)
        if per_pass:
            for p in np.unique(obs.pass_index):
                sel = (obs.pass_index == p)[None, :, None, None, None]
                cols.append(np.where(sel, Jx, 0.0).reshape(R, K, 3))
                var.append(v)
    for m in range(M):
        c = np.zeros((R, N, M, 2, 3))
        c[:, :, m] = J["catalogue"][:, :, m]
        cols.append(c.reshape(R, K, 3))
        var.append(np.full(3, model.sigma_catalogue_m**2))
    Jall = np.concatenate(cols, axis=-1)
    v = np.concatenate(var)
    S = np.einsum("rik,k,rjk->rij", Jall, v, Jall) + np.diag(pixel_var.reshape(K))
    valid = np.repeat(obs.mask, 2, axis=1).reshape(K)
    S = np.where((valid[:, None] & valid[None, :])[None], S, 0.0)
    d = np.arange(K)
    S[:, d, d] = np.where(valid, S[:, d, d], 1.0)
    return S


def fisher_information(obs: Any, model: DisturbanceModel, theta_rad: Any = None, prior_sigma_rad: Any = None) -> np.ndarray:
    """Fisher information of θ (rad⁻²), (R, 3, 3): Gᵀ Σ⁻¹ G (+ diag(1/σθ0²) with a prior).

    G is Algorithm 3's exact Jacobian and Σ the dense residual covariance at ``theta_rad``
    ((3,) or (R, 3); default 0 — the information depends on θ only at second order).
    """
    from boresight.core.measurement import linearize

    _check_budget(obs, "fisher_information")
    theta = np.zeros(3) if theta_rad is None else np.asarray(theta_rad, float)
    G, _ = linearize(obs.dense_view(), theta)  # dense view: not yet on the row model (docs/architecture.md, port status)
    R = obs.runs
    Gf = G.reshape(R, -1, 3)
    S = full_residual_covariance(obs, theta, model)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise ValueError("fisher_information: the residual covariance is singular — is sigma_pixel_m zero?") from None
    W = np.linalg.solve(L, Gf)
    info = np.swapaxes(W, -1, -2) @ W
    if prior_sigma_rad is not None:
        info = info + np.diag(1.0 / np.broadcast_to(np.asarray(prior_sigma_rad, float), (3,)) ** 2)
    sym: np.ndarray = 0.5 * (info + np.swapaxes(info, -1, -2))
    return sym


def cramer_rao_bound(obs: Any, model: DisturbanceModel, theta: Any = None, prior_sigma_arcsec: Any = None) -> u.Quantity:
    """Cramér–Rao bound on the covariance of any unbiased θ estimate, in arcsec².

    ``theta``: linearisation point, a Quantity (angle) or radians, (3,) or (R, 3); default 0.
    Returns a Quantity (R, 3, 3), or (3, 3) for a one-run ``obs``. Raises ``ObservabilityError``
    if the information is singular (an unobservable axis has no finite bound), and
    ``orbits.limits.MemoryBudgetError`` with its estimate, before allocating, when the dense Σ
    would not fit the memory budget.
    """
    from boresight.errors import ObservabilityError, axis_name

    th = None
    if theta is not None:
        th = theta.to_value(u.rad) if isinstance(theta, u.Quantity) else np.asarray(theta, float)
    prior = None if prior_sigma_arcsec is None else np.asarray(prior_sigma_arcsec, float) * ARCSEC
    info = fisher_information(obs, model, th, prior)
    lam, vec = np.linalg.eigh(info)
    if np.any(~(lam[:, 0] > 1e-14 * lam[:, -1])):
        r = int(np.flatnonzero(~(lam[:, 0] > 1e-14 * lam[:, -1]))[0])
        raise ObservabilityError(
            f"cramer_rao_bound: the Fisher information is singular (run {r}); weak axis {axis_name(vec[r, :, 0])}",
            weak_axis=vec[r, :, 0],
            condition_number=float("inf"),
            run=r,
        )
    crb = np.linalg.inv(info) / ARCSEC**2
    crb = 0.5 * (crb + np.swapaxes(crb, -1, -2))
    if obs.runs == 1:
        crb = crb[0]
    return crb * u.arcsec**2
