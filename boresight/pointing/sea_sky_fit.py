"""Estimating the perpendicularity error (alpha, beta) from a sea-sky scan.

Three estimators, from crude to careful:

* the closed form from special points (USV sea-sky eqs 15-23) lives in :mod:`.sea_sky`;
* :func:`grid_search_deg` -- the paper's two-stage 21 x 21 grid search on the mean
  |h'' - h'| (USV sea-sky eq 24);
* :func:`fit_least_squares` -- beyond the paper: ``scipy.optimize.least_squares`` on eq 12-14
  with a robust loss, and standard errors that allow for residuals correlated along the scan
  (Newey-West HAC sandwich, cross-checked by an effective-sample-size inflation).

Example
-------
>>> from boresight.pointing import load_sea_sky, grid_search_deg, special_points_deg
>>> s = load_sea_sky()
>>> a0, b0 = special_points_deg(s.azimuth_deg, s.h_meas_deg).coarse_estimate_deg()
>>> g = grid_search_deg(s.azimuth_deg, s.h_meas_deg, s.pitch_deg, s.roll_deg, a0, b0)
>>> round(g.alpha_deg, 4), round(g.beta_deg, 4)
(0.9469, 0.3678)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from boresight.errors import InputValueError
from boresight.pointing.data import SeaSkyScan
from boresight.pointing.sea_sky import los_vector, s_alpha, s_beta, s_pitch, s_roll, special_points_deg
from boresight.stats.residuals import (
    autocorrelation,
    effective_sample_size,
    newey_west_covariance,
    newey_west_default_lag,
    robust_sigma,
)

__all__ = [
    "mean_abs_error_deg",
    "GridStage",
    "GridSearchResult",
    "grid_search_deg",
    "SeaSkyFit",
    "fit_least_squares",
    "PAPER_GRID_STAGES",
]

#: USV sea-sky section 4: (half-width, step) in degrees of the two 21 x 21 grid stages.
PAPER_GRID_STAGES = ((1.0, 0.1), (0.1, 0.01))
_LOSSES = ("linear", "huber", "soft_l1", "cauchy")
# DECISION: Huber's 1.345 sigma threshold (95 % efficiency at the Gaussian) scales every robust loss.
_HUBER_K = 1.345


class Geometry:
    """The attitude-dependent vectors of eq 12 that do not depend on (alpha, beta).

    sin h' = e_z^T S_P^T S_R^T (S_a S_b) S_R S_P A = v^T (S_a S_b) u, with u = S_R S_P A (eq 4)
    and v = S_R S_P e_z; shapes (n, 3).
    """

    def __init__(self, azimuth_deg, pitch_deg, roll_deg, gain: float = 1.0):
        q = np.radians(np.asarray(azimuth_deg, dtype=float))
        P = gain * np.radians(np.asarray(pitch_deg, dtype=float))
        R = gain * np.radians(np.asarray(roll_deg, dtype=float))
        T = np.einsum("...ij,...jk->...ik", s_roll(R), s_pitch(P))
        self.u = np.einsum("...ij,...j->...i", T, los_vector(q))
        self.v = T[..., :, 2]  # T e_z

    def elevation_deg(self, alpha_deg, beta_deg):
        """dh' in degrees, shape ``alpha.shape + (n,)`` (alpha, beta broadcast together)."""
        M = np.einsum("...ij,...jk->...ik", s_alpha(np.radians(alpha_deg)), s_beta(np.radians(beta_deg)))
        s = np.einsum("ni,...ij,nj->...n", self.v, M, self.u)
        return np.degrees(np.arcsin(np.clip(s, -1.0, 1.0)))


def _check_scan_arrays(azimuth_deg, h_meas_deg, pitch_deg, roll_deg):
    q = np.asarray(azimuth_deg, dtype=float)
    arrays = {"azimuth_deg": q, "h_meas_deg": np.asarray(h_meas_deg, dtype=float)}
    for k, v in (("pitch_deg", pitch_deg), ("roll_deg", roll_deg)):
        a = np.asarray(v, dtype=float)
        arrays[k] = np.broadcast_to(a, q.shape) if a.ndim == 0 else a  # a scalar: level hull etc.
    n = q.shape
    for k, a in arrays.items():
        if a.ndim != 1 or a.shape != n:
            raise InputValueError(f"{k}: expected shape {n} like azimuth_deg, got {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise InputValueError(f"{k}: non-finite value {a[bad[0]]} at index {bad[0]}")
    if n[0] < 3:
        raise InputValueError(f"azimuth_deg: need at least 3 frames, got {n[0]}")
    return arrays.values()


def mean_abs_error_deg(alpha_deg, beta_deg, azimuth_deg, h_meas_deg, pitch_deg=0.0, roll_deg=0.0):
    """L = mean_i |h''_i - h'_i| of USV sea-sky eq 24, in degrees.

    ``alpha_deg`` and ``beta_deg`` broadcast together (e.g. a grid of shape ``(21, 21)``); the scan
    arrays have shape ``(n,)``. Returns the broadcast shape of (alpha, beta).
    """
    q, h, P, R = _check_scan_arrays(azimuth_deg, h_meas_deg, pitch_deg, roll_deg)
    a, b = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(beta_deg, float))
    return np.mean(np.abs(Geometry(q, P, R).elevation_deg(a, b) - h), axis=-1)


@dataclass(frozen=True)
class GridStage:
    """One stage of the eq-24 grid search. ``objective_deg`` has shape ``(n_alpha, n_beta)``."""

    alpha_grid_deg: np.ndarray
    beta_grid_deg: np.ndarray
    objective_deg: np.ndarray
    alpha_deg: float
    beta_deg: float
    objective_min_deg: float
    runner_up_gap_deg: float  # second-smallest minus smallest objective value


@dataclass(frozen=True)
class GridSearchResult:
    """Result of :func:`grid_search_deg`: the last stage's minimiser and every stage."""

    alpha_deg: float
    beta_deg: float
    objective_deg: float
    stages: tuple[GridStage, ...]


def grid_search_deg(
    azimuth_deg, h_meas_deg, pitch_deg, roll_deg, alpha0_deg, beta0_deg, *, stages=PAPER_GRID_STAGES
) -> GridSearchResult:
    """Coarse-to-fine grid search of USV sea-sky eq 24 around (alpha0, beta0).

    Each stage evaluates L on a (2m+1) x (2m+1) grid, m = half_width / step (21 x 21 for the
    paper's stages ``((1.0, 0.1), (0.1, 0.01))``), centred on the previous minimiser.
    # DECISION: ties go to the first minimum in alpha-major order (numpy argmin); the stage
    # records the gap to the runner-up so a near-tie is visible.

    Parameters
    ----------
    azimuth_deg, h_meas_deg, pitch_deg, roll_deg : arrays of shape (n,)
    alpha0_deg, beta0_deg : float
        Centre of the first stage, normally the coarse estimate of eq 23.
    stages : sequence of (half_width_deg, step_deg)
    """
    q, h, P, R = _check_scan_arrays(azimuth_deg, h_meas_deg, pitch_deg, roll_deg)
    geom = Geometry(q, P, R)
    a0, b0 = float(alpha0_deg), float(beta0_deg)
    if not (np.isfinite(a0) and np.isfinite(b0)):
        raise InputValueError(f"alpha0_deg, beta0_deg: expected finite, got {alpha0_deg}, {beta0_deg}")
    done = []
    for half, step in stages:
        if not (step > 0 and half >= step):
            raise InputValueError(f"stages: expected half_width >= step > 0, got ({half}, {step})")
        m = int(round(half / step))
        k = np.arange(-m, m + 1)
        ag, bg = a0 + step * k, b0 + step * k
        L = np.mean(np.abs(geom.elevation_deg(ag[:, None], bg[None, :]) - h), axis=-1)
        i, j = np.unravel_index(int(np.argmin(L)), L.shape)
        flat = np.sort(L.ravel())
        a0, b0 = float(ag[i]), float(bg[j])
        done.append(GridStage(ag, bg, L, a0, b0, float(flat[0]), float(flat[1] - flat[0])))
    return GridSearchResult(a0, b0, done[-1].objective_min_deg, tuple(done))


def _rho_derivatives(loss: str, z: np.ndarray):
    """rho'(z), rho''(z) of scipy's loss functions (z = (r / f_scale)^2)."""
    if loss == "linear":
        return np.ones_like(z), np.zeros_like(z)
    if loss == "huber":
        small = z <= 1.0
        zs = np.where(small, 1.0, z)
        return np.where(small, 1.0, zs**-0.5), np.where(small, 0.0, -0.5 * zs**-1.5)
    if loss == "soft_l1":
        return (1 + z) ** -0.5, -0.5 * (1 + z) ** -1.5
    if loss == "cauchy":
        return 1 / (1 + z), -1 / (1 + z) ** 2
    raise InputValueError(f"loss: expected one of {_LOSSES}, got {loss!r}")


@dataclass(frozen=True)
class SeaSkyFit:
    """Least-squares (alpha, beta[, attitude gain]) with standard errors.

    ``params`` / ``names``: the estimate, shape ``(p,)`` (degrees for alpha and beta, the gain is
    dimensionless). ``se`` is the headline standard error (HAC); ``se_iid`` ignores serial
    correlation (HC0 sandwich); ``se_ess`` inflates ``se_iid`` by sqrt(n / n_eff).
    ``residuals_deg`` = measured - fitted, shape ``(n,)``; ``psi_weights`` = psi(r) / r.
    """

    names: tuple[str, ...]
    params: np.ndarray
    se: np.ndarray
    se_iid: np.ndarray
    se_ess: np.ndarray
    cov_hac: np.ndarray
    residuals_deg: np.ndarray
    fitted_deg: np.ndarray
    psi_weights: np.ndarray
    loss: str
    f_scale_deg: float
    use_attitude: bool
    n: int
    n_eff: float
    max_lag: int
    rss_deg2: float
    success: bool
    message: str
    acf: np.ndarray = field(repr=False)

    @property
    def alpha_deg(self) -> float:
        return float(self.params[0])

    @property
    def beta_deg(self) -> float:
        return float(self.params[1])

    def summary(self) -> str:
        parts = [
            f"{nm} = {v:.4f} ± {s:.4f}" + (" deg" if nm != "attitude_gain" else "")
            for nm, v, s in zip(self.names, self.params, self.se)
        ]
        return ", ".join(parts) + (
            f"  (loss={self.loss}, f_scale={self.f_scale_deg:.3f} deg, HAC lag {self.max_lag},"
            f" n={self.n}, n_eff={self.n_eff:.1f})"
        )


def fit_least_squares(
    scan: SeaSkyScan,
    *,
    loss: str = "huber",
    f_scale_deg: float | None = None,
    use_attitude: bool = True,
    fit_attitude_gain: bool = False,
    x0_deg: tuple[float, float] | None = None,
    max_lag: int | None = None,
    mask=None,
) -> SeaSkyFit:
    """Nonlinear least-squares (alpha, beta) from USV sea-sky eqs 12-14 (beyond the paper).

    Parameters
    ----------
    scan : SeaSkyScan
        Frames in acquisition order (the HAC covariance uses that order).
    loss : {"huber", "linear", "soft_l1", "cauchy"}
        ``scipy.optimize.least_squares`` loss.
    f_scale_deg : float, optional
        Robust-loss scale; default 1.345 x the robust sigma (1.4826 MAD) of the residuals at x0.
    use_attitude : bool
        Use the hull pitch/roll in eq 12; ``False`` sets P = R = 0 (eqs 15-16 model).
    fit_attitude_gain : bool
        Add a third parameter k multiplying P and R (k = 0: no attitude, k = 1: eq 12), so the
        attitude terms can be tested as a nested model.
    x0_deg : (alpha, beta), optional
        Starting point; default the coarse estimate from the scan's special points.
    max_lag : int, optional
        Newey-West lag; default floor(4 (n/100)^(2/9)) (4 for n = 120).
    mask : bool array of shape (n,), optional
        Frames to use (e.g. to drop flagged outliers).

    Standard errors
    ---------------
    The M-estimator sandwich B^-1 S B^-1 with B = sum psi'(r_i) J_i J_i^T and
    S the Bartlett-weighted sum of score cross-products g_i g_{i-l}^T, g_i = J_i psi(r_i)
    (Newey-West HAC, :func:`boresight.stats.residuals.newey_west_covariance`), times
    n / (n - p). Residuals along a scan are serially correlated (the hull moves slowly, and
    unmodelled azimuth structure repeats), so the iid formula is over-confident.
    """
    if loss not in _LOSSES:
        raise InputValueError(f"loss: expected one of {_LOSSES}, got {loss!r}")
    if mask is not None:
        scan = scan.subset(mask)
    q, h, P, R = _check_scan_arrays(scan.azimuth_deg, scan.h_meas_deg, scan.pitch_deg, scan.roll_deg)
    if not use_attitude and fit_attitude_gain:
        raise InputValueError("fit_attitude_gain=True needs use_attitude=True")
    start = tuple(float(v) for v in special_points_deg(q, h).coarse_estimate_deg()) if x0_deg is None else x0_deg
    names = ("alpha_deg", "beta_deg") + (("attitude_gain",) if fit_attitude_gain else ())
    x0 = np.array(list(start) + ([1.0] if fit_attitude_gain else []), dtype=float)
    if use_attitude and not fit_attitude_gain:
        geom = Geometry(q, P, R)
    elif not use_attitude:
        geom = Geometry(q, 0.0 * P, 0.0 * R)

    def model(x):
        g = Geometry(q, P, R, gain=x[2]) if fit_attitude_gain else geom
        return g.elevation_deg(x[0], x[1])

    def resid(x):  # measured - predicted (project convention)
        return h - model(x)

    if f_scale_deg is None:
        s = robust_sigma(resid(x0))
        f_scale_deg = _HUBER_K * s if s > 0 else 1.0
    if not f_scale_deg > 0:
        raise InputValueError(f"f_scale_deg: expected > 0, got {f_scale_deg}")
    sol = least_squares(resid, x0, loss=loss, f_scale=f_scale_deg, x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    x = sol.x
    r = resid(x)
    # central-difference Jacobian of the model (n, p) at the solution
    eps = 1e-6
    J = np.column_stack([(model(x + eps * e) - model(x - eps * e)) / (2 * eps) for e in np.eye(x.size)])
    z = (r / f_scale_deg) ** 2
    d1, d2 = _rho_derivatives(loss, z)
    psi = d1 * r
    dpsi = d1 + 2 * z * d2
    n, p = J.shape
    bread = (J * dpsi[:, None]).T @ J
    scores = J * psi[:, None]
    lag = newey_west_default_lag(n) if max_lag is None else int(max_lag)
    corr = n / (n - p)
    cov_hac = corr * newey_west_covariance(scores, bread, lag)
    cov_iid = corr * newey_west_covariance(scores, bread, 0)
    n_eff = effective_sample_size(psi)
    se_iid = np.sqrt(np.diag(cov_iid))
    return SeaSkyFit(
        names=names,
        params=x,
        se=np.sqrt(np.diag(cov_hac)),
        se_iid=se_iid,
        se_ess=se_iid * np.sqrt(n / n_eff),
        cov_hac=cov_hac,
        residuals_deg=r,
        fitted_deg=h - r,
        psi_weights=np.where(r != 0, psi / np.where(r != 0, r, 1.0), 1.0),
        loss=loss,
        f_scale_deg=float(f_scale_deg),
        use_attitude=use_attitude,
        n=n,
        n_eff=n_eff,
        max_lag=lag,
        rss_deg2=float(r @ r),
        success=bool(sol.success),
        message=str(sol.message),
        acf=autocorrelation(psi, min(10, n - 1)),
    )
