"""Semi-parametric least-squares collocation (Tang 2014 eqs 11-19).

Model (eq 11): delta = G X + h + eps, with G X the parametric part (eq 10), h a smooth
systematic signal and eps noise. Penalised least squares (eq 13)

    V^T V + a h^T R_f h = min,   V = G X + h - delta                       (eq 12)

with smoothing factor a and regular matrix R_f, has the solution (eq 18)

    h = M^-1 (I - G (G^T G)^-1 G^T) delta,   X = (G^T G)^-1 G^T (delta - h),
    M = I + a R_f - G (G^T G)^-1 G^T.

R_f is the distance matrix of the test positions (eq 19): R_f,ij = |(x_i, y_i) - (x_j, y_j)|,
with x azimuth and y elevation. The smoothing factor is chosen by leave-one-out
cross-validation (section "Selection of a and R_f").

The paper gives h only at the calibration points. To predict at new points (the held-out
validation set, and each left-out point of the cross-validation) h is extended by the linear
radial-basis interpolant through the fitted h -- the same distance function as R_f
(``scipy.interpolate.RBFInterpolator(kernel="linear")``, phi(r) = -r, plus a constant).

Example
-------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> x, y = rng.uniform(-20, 20, (2, 40))
>>> G = np.column_stack([np.ones(40), x])
>>> delta = 0.1 + 0.01 * x + 0.05 * np.sin(x / 5) + 0.001 * rng.standard_normal(40)
>>> fit = collocation_fit(G, delta, distance_matrix(x, y), smoothing=1e-3)
>>> fit.h.shape, fit.X.shape
((40,), (2,))
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.linalg import lstsq, qr, solve

from boresight.errors import InputValueError

__all__ = [
    "distance_matrix",
    "CollocationFit",
    "collocation_fit",
    "LooResult",
    "loo_cross_validation",
    "SemiParametricModel",
    "fit_semiparametric",
]


def distance_matrix(x, y) -> np.ndarray:
    """Regular matrix R_f of Tang 2014 eq 19: Euclidean distances of points (x_i, y_i), shape ``(n, n)``."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1 or x.shape != y.shape:
        raise InputValueError(f"x, y: expected equal shapes (n,), got {x.shape}, {y.shape}")
    return np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])


@dataclass(frozen=True)
class CollocationFit:
    """Solution of Tang 2014 eq 18: ``X`` shape ``(p,)``, ``h`` and ``V`` shape ``(n,)``."""

    X: np.ndarray
    h: np.ndarray
    V: np.ndarray  # G X + h - delta (eq 12)
    smoothing: float


def _check_G_delta(G, delta):
    G = np.asarray(G, dtype=float)
    d = np.asarray(delta, dtype=float)
    if G.ndim != 2 or d.shape != (G.shape[0],):
        raise InputValueError(f"G, delta: expected shapes (n, p) and (n,), got {G.shape}, {d.shape}")
    if G.shape[0] <= G.shape[1]:
        raise InputValueError(f"G: need more points than parameters, got shape {G.shape}")
    if not np.all(np.isfinite(d)):
        raise InputValueError(f"delta: non-finite value {d[~np.isfinite(d)][0]}")
    return G, d


def collocation_fit(G, delta, R_f, smoothing: float) -> CollocationFit:
    """Tang 2014 eq 18 for one smoothing factor a = ``smoothing`` > 0.

    Parameters
    ----------
    G : array (n, p)   parametric design matrix (eq 10 columns)
    delta : array (n,) observed pointing errors
    R_f : array (n, n) regular matrix (eq 19)
    """
    G, d = _check_G_delta(G, delta)
    n = G.shape[0]
    R_f = np.asarray(R_f, dtype=float)
    if R_f.shape != (n, n):
        raise InputValueError(f"R_f: expected shape ({n}, {n}), got {R_f.shape}")
    if not (np.isfinite(smoothing) and smoothing > 0):
        raise InputValueError(f"smoothing: expected a finite value > 0, got {smoothing}")
    # DECISION: the projector G (G^T G)^-1 G^T is formed from a QR of G (no normal equations),
    # because the eq-10 columns are nearly collinear over a +-20 deg range.
    Q, _ = qr(G, mode="economic")
    H = Q @ Q.T
    M = np.eye(n) + smoothing * R_f - H
    h = solve(M, d - H @ d)  # eq 18
    X = lstsq(G, d - h)[0]  # eq 18
    return CollocationFit(X, h, G @ X + h - d, float(smoothing))


def _predict_h(points, h, new_points):
    return RBFInterpolator(points, h, kernel="linear", degree=0)(new_points)


@dataclass(frozen=True)
class LooResult:
    """Leave-one-out CV: ``smoothing`` and ``score`` (mean squared LOO error), shape ``(m,)``."""

    smoothing: np.ndarray
    score: np.ndarray
    best: float


def loo_cross_validation(G, delta, x, y, smoothing_grid) -> LooResult:
    """Choose the smoothing factor by leave-one-out cross-validation (Tang 2014, after eq 18).

    For each a in ``smoothing_grid`` and each point k, fit eq 18 on the other n-1 points and
    predict delta_k = G_k X + h(x_k, y_k) (h extended by the linear RBF); the score is the mean
    of the squared prediction errors, and ``best`` its minimiser.
    """
    G, d = _check_G_delta(G, delta)
    pts = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    if pts.shape[0] != G.shape[0]:
        raise InputValueError(f"x, y: expected {G.shape[0]} points like G, got {pts.shape[0]}")
    grid = np.asarray(smoothing_grid, dtype=float)
    if grid.ndim != 1 or grid.size == 0 or np.any(~(grid > 0)):
        raise InputValueError(f"smoothing_grid: expected a 1-d array of values > 0, got {smoothing_grid}")
    n = G.shape[0]
    R_full = distance_matrix(pts[:, 0], pts[:, 1])
    scores = np.empty(grid.size)
    for ia, a in enumerate(grid):
        err = np.empty(n)
        for k in range(n):
            keep = np.arange(n) != k
            f = collocation_fit(G[keep], d[keep], R_full[np.ix_(keep, keep)], a)
            err[k] = d[k] - (G[k] @ f.X + _predict_h(pts[keep], f.h, pts[k : k + 1])[0])
        scores[ia] = np.mean(err**2)
    return LooResult(grid, scores, float(grid[int(np.argmin(scores))]))


@dataclass(frozen=True)
class SemiParametricModel:
    """A fitted semi-parametric model for one error component (azimuth or elevation)."""

    points: np.ndarray  # (n, 2) calibration positions (x, y)
    fit: CollocationFit
    loo: LooResult | None

    def predict(self, G_new, x_new, y_new) -> np.ndarray:
        """Model error G X + h at new points; ``G_new`` shape ``(m, p)``, returns ``(m,)``."""
        new = np.column_stack([np.asarray(x_new, float), np.asarray(y_new, float)])
        return np.asarray(G_new, float) @ self.fit.X + _predict_h(self.points, self.fit.h, new)


def fit_semiparametric(G, delta, x, y, smoothing=None, smoothing_grid=None) -> SemiParametricModel:
    """Fit eq 18 with R_f from eq 19; ``smoothing`` fixed, or chosen by LOO over ``smoothing_grid``.

    # DECISION: the default grid is 25 log-spaced values 1e-5 .. 1e1 (times 1/mean distance),
    # wide enough to span "interpolate the residuals" to "parametric only".
    """
    G, d = _check_G_delta(G, delta)
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    R_f = distance_matrix(x, y)
    loo = None
    if smoothing is None:
        if smoothing_grid is None:
            smoothing_grid = np.logspace(-5, 1, 25) / np.mean(R_f[R_f > 0])
        loo = loo_cross_validation(G, d, x, y, smoothing_grid)
        smoothing = loo.best
    return SemiParametricModel(np.column_stack([x, y]), collocation_fit(G, d, R_f, smoothing), loo)
