"""Robust losses for ``estimate(loss=...)``: IRLS weights, their constants, and the M-estimator's
sandwich covariance under the noise model (``docs/estimators.md``, "Robust losses").

A robust fit reweights each observation by w(z), z the length of its normalised residual vector
(pixel-level under the noise model, else scaled by ``robust_scale``).

>>> robust_weights([1.0, 4.9], "huber").round(3).tolist()
[1.0, 0.5]
"""

from __future__ import annotations

from typing import Any, cast

import numpy as np

from boresight.core.losses import LOSSES
from boresight.stats import MAD_TO_SIGMA, irls_weight_slope, irls_weights

__all__ = [
    "LOSSES",
    "CHI2_INLIER_Z",
    "MAX_ROBUST_ITERATIONS",
    "ROBUST_TOLERANCE_SIGMA",
    "ROBUST_WEIGHT_TOLERANCE",
    "robust_weights",
    "robust_weight_slope",
    "robust_scale",
    "clean_constants",
    "m_estimator_covariance",
    "m_estimator_covariance_rows",
    "REJECTED_WEIGHT",
    "rejection_warning",
]

#: a robust fit iterates (reweights) at most this many times
MAX_ROBUST_ITERATIONS = 100
#: a robust fit has converged when θ moves by less than this fraction of its σ …
ROBUST_TOLERANCE_SIGMA = 1e-3
#: … and no observation's weight changes by more than this
ROBUST_WEIGHT_TOLERANCE = 1e-2
#: under a robust loss, observations with a pixel-level normalised residual length above this are
#: left out of the χ² check as outliers (a clean one: probability exp(−z²/2) = 1e-5)
CHI2_INLIER_Z = float(np.sqrt(-2.0 * np.log(1e-5)))
#: DECISION: an observation whose robust weight is below this is "rejected outright" (it counts
#: less than 1 % of a clean one) and always reported as a warning (a point moved to the
#: opposite side of the image had z = 14 158 and weight 0 under Huber, and nothing was printed).
#: Huber reaches it at z > 245 (k/0.01), Cauchy at z > 29.8 (c √99), Tukey at z > 4.65 (c √0.9; weight 0 from z = c = 4.9).
REJECTED_WEIGHT = 0.01


def rejection_warning(obs: Any, z: np.ndarray, w: np.ndarray | None, loss: str) -> str | None:
    """The warning for the observations a robust fit rejected outright (weight < REJECTED_WEIGHT)
    in any run: how many, the worst (image, landmark, z, run) and what to do, or None.
    ``z``, ``w``: (R, K) normalised residual lengths and weights per observation of the row set
    ``obs`` (None: no weights, no warning)."""
    if w is None:
        return None
    z, w = np.asarray(z, float), np.asarray(w, float)
    rejected = w < REJECTED_WEIGHT
    if not np.any(rejected):
        return None
    zr = np.where(rejected, z, -np.inf)
    r, k = np.unravel_index(int(np.argmax(zr)), zr.shape)
    n, m = int(obs.image_index[k]), int(obs.target_index[k])
    runs = f" in {int(np.any(rejected, axis=1).sum())} of {obs.runs} runs" if obs.runs > 1 else ""
    where = f"run {r} " if obs.runs > 1 else ""
    return (
        f"the {loss} loss rejected {int(rejected.sum())} observation(s) outright{runs} (weight < {REJECTED_WEIGHT:g}); worst: "
        f"{where}image {n} landmark {str(obs.landmark_ids[m])!r}, normalised residual {z[r, k]:.4g}, weight {w[r, k]:.2g}. "
        "θ ignores them: check those rows (a bad detection, a wrong landmark id) rather than trust the fit blindly"
    )


def robust_weights(z: Any, loss: str) -> np.ndarray:
    """IRLS weights for normalised residual lengths ``z`` (array) under ``loss`` at its constant
    ``LOSSES[loss]`` (the weight functions: ``boresight.stats.irls_weights``)."""
    return irls_weights(z, loss, LOSSES[loss])


def robust_weight_slope(z: Any, loss: str) -> np.ndarray:
    """dw/dz of ``robust_weights`` (array)."""
    return irls_weight_slope(z, loss, LOSSES[loss])


def robust_scale(q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """MAD_TO_SIGMA (1.4826) × median |component| over the valid residual components, per run (R,)
    (the components are centred at 0 by the fit: the median absolute deviation about 0)."""
    a = np.where(valid, np.abs(q), np.nan).reshape(q.shape[0], -1)
    return MAD_TO_SIGMA * np.nanmedian(a, axis=1)


_KAPPA: dict[str, tuple[float, float]] = {}


def clean_constants(loss: str) -> tuple[float, float]:
    """(κ1, κ2) = (E[w + z w′/2], E[w² z²]/2) for a clean observation, z the length of a standard
    normal 2-vector (Rayleigh), truncated at CHI2_INLIER_Z: the expected slope of the estimating
    function per component (trace of ∂ψ/∂r over 2) and the variance of ψ per component."""
    from scipy.integrate import quad

    if loss not in _KAPPA:
        f = lambda z: z * np.exp(-0.5 * z * z)  # noqa: E731 - Rayleigh density
        norm = 1.0 - np.exp(-0.5 * CHI2_INLIER_Z**2)
        brk = [LOSSES[loss]] if LOSSES[loss] < CHI2_INLIER_Z else None
        k1 = quad(
            lambda z: (robust_weights(z, loss) + 0.5 * z * robust_weight_slope(z, loss)) * f(z), 0, CHI2_INLIER_Z, points=brk
        )[0]
        k2 = quad(lambda z: 0.5 * (robust_weights(z, loss) * z) ** 2 * f(z), 0, CHI2_INLIER_Z, points=brk)[0]
        _KAPPA[loss] = (k1 / norm, k2 / norm)
    return _KAPPA[loss]


def m_estimator_covariance(
    obs: Any,
    theta: np.ndarray,
    G: np.ndarray,
    q: np.ndarray,
    model: Any,
    L: np.ndarray | None,
    z: np.ndarray,
    loss: str,
    prior_info: np.ndarray | None,
) -> np.ndarray:
    """Sandwich covariance of the robust GLS fit (Huber & Ronchetti, Robust Statistics, 2nd ed. 2009, ch. 7:
    the M-estimator of regression, cov = J⁻¹ K J⁻¹, (Eψ²/(Eψ′)²)(XᵀX)⁻¹ for i.i.d. errors),
    with the per-image/per-pass/catalogue nuisances carried as random effects with their prior.

    The IRLS fit solves Σ_i Z_iᵀ ψ(r_i) − [0; ν] − P x = 0 over the joint [x, ν] (whitened rows Z_i
    of an observation, ψ(r) = w(|r|) r, the nuisance prior and the prior P on θ quadratic).
    Linearised, x̂ − x = A Σ_i z̃_i ψ_i + (prior terms), with J the expected slope of the estimating
    function (observation i: ψ′_i = E[tr ∂ψ/∂r]/2 per component), A = (Schur complement of J onto
    x)⁻¹ and z̃_i the rows reduced by J (``gls.rows.row_reduced_rows``). Its covariance is

        cov = A [Σ_i m_i z̃_i z̃_iᵀ + Σ_priors] A = A + A [Σ_i (m_i − ψ′_i) z̃_i z̃_iᵀ] A,

    m_i = E|ψ_i|²/2, because the quadratic prior rows contribute equally to both brackets. For an
    observation the model describes (pixel-level z ≤ CHI2_INLIER_Z) ψ′ and m are the loss's
    expected constants for a standard normal 2-vector (``clean_constants``) — the residual itself
    is shrunk by the nuisances (leverage), the true error is not; for an outlier (z above) its own
    values, w + z w′/2 (≥ 0) and w² z²/2. Without outliers and w ≡ 1 this is the GLS inverse
    information; in scaled units (R, n, n). ``obs`` a row set; G (R, K, 2, n), q (R, K, 2), L (R, K, 2, 2)
    or None and z (R, K) one row per observation.
    """
    from boresight.core.gls.campaign import row_problem

    st, cols = row_problem(obs, theta, G, q, model, L)
    return m_estimator_covariance_rows(st, cols, z, loss, prior_info)


def m_estimator_covariance_rows(st: Any, cols: Any, z: np.ndarray, loss: str, prior_info: np.ndarray | None) -> np.ndarray:
    """``m_estimator_covariance`` on rows already built: the row structure ``st`` and whitened columns ``cols`` of the
    one GLS (``gls.rows.RowStructure``, ``RowColumns``; the pushbroom lines' ``core.line_scan.stacked_rows``), z (R, K)."""
    from boresight.core.gls.campaign import single_threaded_blas
    from boresight.core.gls.rows import row_gls, row_reduced_rows

    k1, k2 = clean_constants(loss)
    inl = z <= CHI2_INLIER_Z
    psi1 = np.where(inl, k1, np.maximum(robust_weights(z, loss) + 0.5 * z * robust_weight_slope(z, loss), 0.0))
    meat = np.where(inl, k2, 0.5 * (robust_weights(z, loss) * z) ** 2)
    fit = row_gls(st, cols, np.asarray(psi1, float))
    ne = fit.normal_equations
    if prior_info is not None:
        ne.add_prior(information=prior_info)
    A = ne.solve(check=False).covariance
    with single_threaded_blas():
        _, zt = row_reduced_rows(fit, A, leverage=False)  # (R, K, 2, n)
    D = np.einsum("rk,rkci,rkcj->rij", meat - psi1, zt, zt)
    cov = A + A @ D @ A
    return cast(np.ndarray, 0.5 * (cov + np.swapaxes(cov, -1, -2)))
