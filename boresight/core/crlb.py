"""The Cramér–Rao bound: the ONE deliberately independent dense route (a test oracle in the library).

The disturbance model (``boresight.core.disturbances``) perturbs the image-plane residual of each
observation (row) k by e_k = Σ_src J_src,k ε_src. Every estimator carries that error structure block
by block — one builder (``boresight.core.gls.structure``) and one GLS on rows (``boresight.core.gls.rows``:
single-use targets folded into their rows, shared targets, images and passes eliminated by a sparse
Schur complement). This module deliberately does NOT: ``full_residual_covariance`` builds the dense
covariance Σ (2K × 2K) of all a run's residuals draw by draw (one column per independent error: per
image, per pass, per target; mode ``both`` contributes to both), straight from
``disturbances.error_jacobians`` on the rows, and ``fisher_information`` whitens with its dense
Cholesky factor. A set's per-row pixel σ (``sigma_xy_m``, NaN: the model's σK) is that row's diagonal
of Σ, read here on its own. It is kept independent on purpose so
the tests can compare the fast routes against it (``tests/oracles.py`` lists the deliberate oracles;
``tests/core/test_campaign_gls.py``, ``tests/studies/test_planning.py``, ``tests/core/test_gls_crlb.py`` compare).
It reads the rows (no images × targets array); memory grows as (2K)² for K observations: meant for
bounds of small campaigns and for checks; the memory budget refuses a larger one with its estimate
before anything is allocated.

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
from boresight.errors import InputValueError
from orbits.limits import check_memory
from orbits.rotations import ARCSEC

__all__ = ["full_residual_covariance", "fisher_information", "cramer_rao_bound", "full_covariance_bytes"]


def full_covariance_bytes(runs: int, n_observations: int, n_images: int, n_targets: int, n_passes: int) -> float:
    """Working set (bytes) of the dense route on R runs × K observations (N images, T targets, P passes):
    2K residual components per run; three 2K × 2K float64 matrices (Σ, a product, its Cholesky factor),
    the error columns twice (the per-draw columns and their concatenation, 2K × 3(N + P + T) each: one
    column per independent draw) and the error Jacobians (three R × K × 2 × 3)."""
    R, K, N, T, P = (float(v) for v in (runs, n_observations, n_images, n_targets, n_passes))
    K2 = 2.0 * K
    return R * (3 * 8 * K2**2 + 2 * 8 * K2 * 3 * (N + P + T) + 3 * 8 * K * 6)


def _check_budget(obs: Any, who: str) -> None:
    """Refuse (``MemoryBudgetError`` with the estimate) the dense route before anything is allocated."""
    R, K, N, T = obs.runs, obs.n_observations, obs.n_images, obs.n_targets
    P = int(np.unique(np.asarray(obs.pass_index)).size)
    check_memory(
        f"{who}: the dense residual covariance (the Cramér–Rao oracle) of {R} run(s) × {K} observations"
        f" ({2 * K} residual components per run; {N} images, {T} targets)",
        full_covariance_bytes(R, K, N, T, P),
        hint="the GLS of boresight.estimate(..., weighting='gls') gives the same bound without the dense Σ (its covariance)",
    )


def full_residual_covariance(obs: Any, theta_rad: Any, model: DisturbanceModel) -> np.ndarray:
    """Dense covariance of all image-plane residuals of each run, (R, 2K, 2K): row k's two components
    at 2k, 2k + 1, rows in the set's canonical (image, target) order.

    Built source by source with one column per independent error draw (per image, per pass,
    per target). Memory grows as (2K)²: meant for a bound and for checks, not for a 45 000-run Monte
    Carlo (``boresight.core.gls.structure`` and ``boresight.core.gls.rows`` carry the same structure
    block by block). Refused with its estimate (``full_covariance_bytes``,
    ``orbits.limits.MemoryBudgetError``) before anything is allocated when it would not fit the
    memory budget.
    """
    _check_budget(obs, "full_residual_covariance")
    R, K = obs.runs, obs.n_observations
    img, tgt = np.asarray(obs.image_index), np.asarray(obs.target_index)
    pass_of_row = np.asarray(obs.pass_index)[img]
    pixel_var = np.full((K, 2), model.sigma_pixel_m**2)
    own = getattr(obs, "sigma_xy_m", None)  # a row's own pixel σ (NaN: the model's)
    if own is not None:
        own = np.asarray(own, float)
        pixel_var = np.where(np.isnan(own), model.sigma_pixel_m, own) ** 2
    J = error_jacobians(obs, theta_rad)  # (R, K, 2, 3) per source
    cols, var = [], []
    st_img, st_pass = modes(model.star_tracker_mode)
    g_img, g_pass = modes(model.gnss_mode)
    st_var = np.asarray(model.sigma_star_tracker_rad) ** 2

    def column(Jx: np.ndarray, on: np.ndarray) -> np.ndarray:
        """The draw acting on the rows ``on`` (K,) bool: Jx there, zero elsewhere, (R, 2K, 3)."""
        return np.where(on[None, :, None, None], Jx, 0.0).reshape(R, 2 * K, 3)

    for key, v, per_img, per_pass in (
        ("star_tracker", st_var, st_img, st_pass),
        ("gnss", np.full(3, model.sigma_gnss_m**2), g_img, g_pass),
    ):
        if per_img:
            for n in range(obs.n_images):
                cols.append(column(J[key], img == n))
                var.append(v)
        if per_pass:
            for p in np.unique(obs.pass_index):
                cols.append(column(J[key], pass_of_row == p))
                var.append(v)
    for t in range(obs.n_targets):
        cols.append(column(J["catalogue"], tgt == t))
        var.append(np.full(3, model.sigma_catalogue_m**2))
    Jall = np.concatenate(cols, axis=-1)
    v = np.concatenate(var)
    S: np.ndarray = np.einsum("rik,k,rjk->rij", Jall, v, Jall) + np.diag(pixel_var.reshape(2 * K))
    return S


def fisher_information(obs: Any, model: DisturbanceModel, theta_rad: Any = None, prior_sigma_rad: Any = None) -> np.ndarray:
    """Fisher information of θ (rad⁻²), (R, 3, 3): Gᵀ Σ⁻¹ G (+ diag(1/σθ0²) with a prior).

    G is Algorithm 3's exact Jacobian of every observation and Σ the dense residual covariance at
    ``theta_rad`` ((3,) or (R, 3); default 0 — the information depends on θ only at second order).
    """
    from boresight.core.measurement import linearize

    _check_budget(obs, "fisher_information")
    theta = np.zeros(3) if theta_rad is None else np.asarray(theta_rad, float)
    G, _ = linearize(obs, theta)  # (R, K, 2, 3)
    R = obs.runs
    Gf = G.reshape(R, -1, 3)
    S = full_residual_covariance(obs, theta, model)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        raise InputValueError("fisher_information: the residual covariance is singular — is sigma_pixel_m zero?") from None
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
