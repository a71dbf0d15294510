"""Residual error structure under the disturbance model, Fisher information and the Cramér–Rao bound.

The disturbance model (``boresight.core.disturbances``) perturbs the image-plane residuals of image n
by e_n = Σ_src J_src,n ε_src. What matters for estimation is which errors are *shared*:

* per image (block-diagonal in images): pixel noise (also independent per landmark),
  star-tracker δ and GNSS ξ in mode ``per_image`` — common to the landmarks of one image;
* shared by several images (global nuisance columns U with prior variances v): star-tracker
  and GNSS errors in mode ``per_pass`` (one 3-vector per pass), and catalogue errors (one
  3-vector per landmark, seen in every image of that landmark). Mode ``both`` contributes to both.

So the residual covariance of one run is Σ = blockdiag(D_n) + U diag(v) Uᵀ. An algorithm whose
residual is q = L q_image (``residual_map``) gets D → L D Lᵀ, U → L U.

The Fisher information of θ under the linearised Gaussian model is I(θ) = Gᵀ Σ⁻¹ G (plus the
prior information, if any); the Cramér–Rao bound is I⁻¹. It does not depend on which
algorithm builds G (any invertible L cancels), so it is computed from image-plane residuals
with a dense Σ over all of a run's residuals — a deliberately different route from the GLS
estimator in ``boresight.estimate``, which whitens per image and eliminates the shared errors
as nuisance parameters (Schur complement); the tests check the two agree.

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

from dataclasses import dataclass

import numpy as np
from astropy import units as u

from orbits.rotations import ARCSEC

from boresight.core.disturbances import DisturbanceModel, error_jacobians

__all__ = ["ErrorStructure", "error_structure", "full_residual_covariance", "fisher_information", "cramer_rao_bound"]


@dataclass(frozen=True)
class ErrorStructure:
    """Residual covariance of a run as blockdiag(D) + U diag(variance) Uᵀ.

    ``D`` (R, N, 2M, 2M) per-image covariance (unit variance on masked rows); ``U``
    (R, N, 2M, p) columns of the shared errors; ``variance`` (p,) their prior variances;
    ``labels`` (p,) which error each column is (e.g. ``'star_tracker pass 0 axis 1'``).
    """

    D: np.ndarray
    U: np.ndarray
    variance: np.ndarray
    labels: tuple


def _mapped_jacobians(obs, theta_rad, L):
    J = error_jacobians(obs, theta_rad)
    if L is not None:
        J = {k: L @ v for k, v in J.items()}
    return J


def _modes(mode):
    return mode in ("per_image", "both"), mode in ("per_pass", "both")


def _pixel_block(obs, model, L):
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    if L is None:
        blocks = np.broadcast_to(np.eye(2), (R, N, M, 2, 2))
    else:
        blocks = L @ np.swapaxes(L, -1, -2)
    D = np.zeros((R, N, M, 2, M, 2))
    idx = np.arange(M)
    D[:, :, idx, :, idx, :] = model.sigma_pixel_m**2 * np.moveaxis(blocks, 2, 0)
    return D.reshape(R, N, 2 * M, 2 * M)


def _finish_masked(obs, D):
    mask2 = np.repeat(obs.mask, 2, axis=1)  # (N, 2M)
    off = ~(mask2[:, :, None] & mask2[:, None, :])
    D = np.where(off[None], 0.0, D)
    diag = np.arange(D.shape[-1])
    D[..., diag, diag] = np.where(mask2[None], D[..., diag, diag], 1.0)
    return D


def error_structure(obs, theta_rad, model: DisturbanceModel, residual_map=None) -> ErrorStructure:
    """Split the residual covariance into per-image blocks and shared nuisance columns.

    ``theta_rad`` (3,) or (R, 3): linearisation point. ``residual_map`` (R, N, M, 2, 2) maps
    image-plane residuals to the algorithm's residuals (None: image plane).
    """
    if not isinstance(model, DisturbanceModel):
        raise TypeError(f"model must be a boresight.DisturbanceModel, got {type(model).__name__}")
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    J = _mapped_jacobians(obs, theta_rad, residual_map)
    Jst = J["star_tracker"].reshape(R, N, 2 * M, 3)
    Jg = J["gnss"].reshape(R, N, 2 * M, 3)
    D = _pixel_block(obs, model, residual_map)
    st_var = np.asarray(model.sigma_star_tracker_rad) ** 2
    st_img, st_pass = _modes(model.star_tracker_mode)
    g_img, g_pass = _modes(model.gnss_mode)
    if st_img:
        D = D + np.einsum("rnik,k,rnjk->rnij", Jst, st_var, Jst)
    if g_img:
        D = D + model.sigma_gnss_m**2 * np.einsum("rnik,rnjk->rnij", Jg, Jg)
    D = _finish_masked(obs, D)

    cols, var, labels = [], [], []
    passes = np.unique(obs.pass_index)
    for on, Jx, v, name in ((st_pass, Jst, st_var, "star_tracker"), (g_pass, Jg, np.full(3, model.sigma_gnss_m**2), "gnss")):
        if not on:
            continue
        for p in passes:
            sel = (obs.pass_index == p)[None, :, None, None]
            for k in range(3):
                if v[k] > 0:
                    cols.append(np.where(sel, Jx[..., k : k + 1], 0.0))
                    var.append(v[k])
                    labels.append(f"{name} pass {int(p)} axis {k}")
    if model.sigma_catalogue_m > 0:
        Jc = J["catalogue"]  # (R, N, M, 2, 3)
        for m in range(M):
            if not obs.mask[:, m].any():
                continue
            for k in range(3):
                c = np.zeros((R, N, M, 2))
                c[:, :, m, :] = Jc[:, :, m, :, k]
                cols.append(c.reshape(R, N, 2 * M, 1))
                var.append(model.sigma_catalogue_m**2)
                labels.append(f"catalogue {obs.landmark_ids[m]} axis {k}")
    U = np.concatenate(cols, axis=-1) if cols else np.zeros((R, N, 2 * M, 0))
    return ErrorStructure(D=D, U=U, variance=np.asarray(var, float), labels=tuple(labels))


def full_residual_covariance(obs, theta_rad, model: DisturbanceModel) -> np.ndarray:
    """Dense covariance of all image-plane residuals of each run, (R, 2NM, 2NM).

    Built source by source with one column per independent error draw (per image, per pass,
    per landmark); masked rows get unit variance and no correlation. Memory grows as (2NM)²:
    meant for a bound, not for a 45 000-run Monte Carlo (use ``error_structure`` there).
    """
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    K = 2 * N * M
    J = error_jacobians(obs, theta_rad)
    cols, var = [], []
    st_img, st_pass = _modes(model.star_tracker_mode)
    g_img, g_pass = _modes(model.gnss_mode)
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
    S = np.einsum("rik,k,rjk->rij", Jall, v, Jall) + model.sigma_pixel_m**2 * np.eye(K)
    valid = np.repeat(obs.mask, 2, axis=1).reshape(K)
    S = np.where((valid[:, None] & valid[None, :])[None], S, 0.0)
    d = np.arange(K)
    S[:, d, d] = np.where(valid, S[:, d, d], 1.0)
    return S


def fisher_information(obs, model: DisturbanceModel, theta_rad=None, prior_sigma_rad=None) -> np.ndarray:
    """Fisher information of θ (rad⁻²), (R, 3, 3): Gᵀ Σ⁻¹ G (+ diag(1/σθ0²) with a prior).

    G is Algorithm 3's exact Jacobian and Σ the dense residual covariance at ``theta_rad``
    ((3,) or (R, 3); default 0 — the information depends on θ only at second order).
    """
    from boresight.core.measurement import linearize

    theta = np.zeros(3) if theta_rad is None else np.asarray(theta_rad, float)
    G, _ = linearize(obs, theta)
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
    return 0.5 * (info + np.swapaxes(info, -1, -2))


def cramer_rao_bound(obs, model: DisturbanceModel, theta=None, prior_sigma_arcsec=None):
    """Cramér–Rao bound on the covariance of any unbiased θ estimate, in arcsec².

    ``theta``: linearisation point, a Quantity (angle) or radians, (3,) or (R, 3); default 0.
    Returns a Quantity (R, 3, 3), or (3, 3) for a one-run ``obs``. Raises ``ObservabilityError``
    if the information is singular (an unobservable axis has no finite bound).
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
