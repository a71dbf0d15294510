"""Generic residual diagnostics: pure functions over numpy arrays (``boresight.stats``).

These are the building blocks of the "find the missing effect" workflow: after any fit, ask
which points are outliers (:func:`robust_z`, :func:`outlier_flags`), whether the residuals still
carry structure against some variable (:func:`binned_residuals`, :func:`harmonic_fit`), how
correlated they are along the acquisition order (:func:`autocorrelation`,
:func:`effective_sample_size`, :func:`ljung_box`), what that does to parameter uncertainty
(:func:`newey_west_covariance`), and whether an extra model term is supported
(:func:`nested_f_test`, :func:`gaussian_aic`).

Residuals are measured - predicted (project convention). Nothing here knows about units: pass
plain floats in one consistent unit.

Example
-------
>>> import numpy as np
>>> r = np.array([0.1, -0.2, 0.05, 3.0, -0.1, 0.0, 0.15])
>>> np.flatnonzero(outlier_flags(r))
array([3])
"""

from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

import numpy as np

from boresight.errors import InputValueError

__all__ = [
    "MAD_TO_SIGMA",
    "robust_sigma",
    "robust_z",
    "outlier_flags",
    "BinnedResiduals",
    "binned_residuals",
    "HarmonicFit",
    "harmonic_fit",
    "autocorrelation",
    "effective_sample_size",
    "ljung_box",
    "newey_west_default_lag",
    "newey_west_covariance",
    "NestedTest",
    "nested_f_test",
    "gaussian_aic",
]

#: 1 / Phi^-1(3/4): scales a median absolute deviation to a Gaussian sigma.
MAD_TO_SIGMA = 1.0 / NormalDist().inv_cdf(0.75)


def _as_1d(name: str, x: Any, min_len: int = 1) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1:
        raise InputValueError(f"{name}: expected shape (n,), got {a.shape}")
    if a.shape[0] < min_len:
        raise InputValueError(f"{name}: expected at least {min_len} values, got {a.shape[0]}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise InputValueError(f"{name}: non-finite value {a[bad[0]]} at index {bad[0]}")
    return a


def robust_sigma(residuals: Any) -> float:
    """Gaussian-equivalent scale 1.4826 * MAD of residuals, shape ``(n,)``.

    >>> round(robust_sigma([1.0, -1.0, 0.0, 100.0]), 4)
    1.4826
    """
    r = _as_1d("residuals", residuals)
    return float(MAD_TO_SIGMA * np.median(np.abs(r - np.median(r))))


def robust_z(residuals: Any) -> np.ndarray:
    """Robust z-scores (r - median) / (1.4826 MAD), shape ``(n,)``.

    Raises ``InputValueError`` (a ``ValueError``) if the MAD is zero (more than half of the residuals equal).
    """
    r = _as_1d("residuals", residuals)
    s = robust_sigma(r)
    if s == 0.0:
        raise InputValueError("residuals: median absolute deviation is 0, robust z undefined")
    z: np.ndarray = (r - np.median(r)) / s
    return z


def outlier_flags(residuals: Any, threshold: float = 3.5) -> np.ndarray:
    """Boolean mask, shape ``(n,)``, of points with ``|robust_z| > threshold``.

    # DECISION: the default 3.5 is Iglewicz & Hoaglin's cut for modified z-scores; with
    # n = 120 Gaussian points it flags none with probability ~0.95.
    """
    if not threshold > 0:
        raise InputValueError(f"threshold: expected > 0, got {threshold}")
    flags: np.ndarray = np.abs(robust_z(residuals)) > threshold
    return flags


@dataclass(frozen=True)
class BinnedResiduals:
    """Residual structure against one variable; arrays have shape ``(n_bins,)``.

    ``chi2``/``p_value`` test "every bin mean is zero" with each bin's standard error of the
    mean (empty and single-point bins skipped); a small p-value says structure remains. If the
    residuals are serially correlated, pass ``n_eff_factor`` = n_eff / n to
    :func:`binned_residuals` so the test is not over-confident.
    """

    edges: np.ndarray
    centres: np.ndarray
    mean: np.ndarray
    sem: np.ndarray
    count: np.ndarray
    chi2: float
    dof: int
    p_value: float


def binned_residuals(x: Any, residuals: Any, bins: Any = 12, *, n_eff_factor: float = 1.0) -> BinnedResiduals:
    """Mean residual, its standard error and count in bins of ``x`` (shapes ``(n,)``).

    ``bins`` is a number of equal-width bins or an array of edges (as in
    ``scipy.stats.binned_statistic``).

    >>> b = binned_residuals(np.arange(8.0), np.array([1, -1, 1, -1, 5, 6, 5, 6.0]), bins=2)
    >>> b.mean.tolist(), b.count.tolist()
    ([0.0, 5.5], [4, 4])
    """
    from scipy import stats

    xa = _as_1d("x", x)
    r = _as_1d("residuals", residuals)
    if xa.shape != r.shape:
        raise InputValueError(f"x and residuals: shapes differ, {xa.shape} vs {r.shape}")
    if not 0 < n_eff_factor <= 1:
        raise InputValueError(f"n_eff_factor: expected in (0, 1], got {n_eff_factor}")
    mean, edges, _ = stats.binned_statistic(xa, r, "mean", bins=bins)
    std, _, _ = stats.binned_statistic(xa, r, lambda v: np.std(v, ddof=1) if v.size > 1 else np.nan, bins=edges)
    count, _, _ = stats.binned_statistic(xa, r, "count", bins=edges)
    count = count.astype(int)
    with np.errstate(invalid="ignore", divide="ignore"):
        sem = std / np.sqrt(count * n_eff_factor)
    ok = (count > 1) & np.isfinite(sem) & (sem > 0)
    chi2 = float(np.sum((mean[ok] / sem[ok]) ** 2))
    dof = int(ok.sum())
    p = float(stats.chi2.sf(chi2, dof)) if dof else float("nan")
    return BinnedResiduals(edges, 0.5 * (edges[1:] + edges[:-1]), mean, sem, count, chi2, dof, p)


@dataclass(frozen=True)
class HarmonicFit:
    """Least-squares harmonics of residuals against an angle; arrays shape ``(max_order,)``.

    r ~ c0 + sum_k (a_k cos k x + b_k sin k x); ``amplitude`` = hypot(a_k, b_k), ``phase_rad`` =
    atan2(b_k, a_k) (so the term is amplitude * cos(k x - phase)). ``p_value[k-1]`` is the F-test
    of dropping order k alone from the full fit.
    """

    orders: np.ndarray
    amplitude: np.ndarray
    phase_rad: np.ndarray
    amplitude_se: np.ndarray
    p_value: np.ndarray
    offset: float


def harmonic_fit(angle_rad: Any, residuals: Any, max_order: int = 4) -> HarmonicFit:
    """Fit harmonics 1..max_order of ``angle_rad`` (shape ``(n,)``) to residuals (shape ``(n,)``).

    >>> x = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    >>> h = harmonic_fit(x, 0.3 * np.cos(2 * x - 0.5), max_order=3)
    >>> np.round(h.amplitude, 6).tolist(), round(float(h.phase_rad[1]), 6)
    ([0.0, 0.3, 0.0], 0.5)
    """
    x = _as_1d("angle_rad", angle_rad)
    r = _as_1d("residuals", residuals)
    if x.shape != r.shape:
        raise InputValueError(f"angle_rad and residuals: shapes differ, {x.shape} vs {r.shape}")
    if max_order < 1 or 2 * max_order + 2 > x.size:
        raise InputValueError(f"max_order: expected 1 <= max_order <= (n-2)/2 = {(x.size - 2) // 2}, got {max_order}")
    k = np.arange(1, max_order + 1)
    G = np.column_stack([np.ones_like(x)] + [f(kk * x) for kk in k for f in (np.cos, np.sin)])
    coef, *_ = np.linalg.lstsq(G, r, rcond=None)
    rss_full = float(np.sum((r - G @ coef) ** 2))
    dof = x.size - G.shape[1]
    s2 = rss_full / dof if dof > 0 else np.nan
    cov = s2 * np.linalg.pinv(G.T @ G)
    a, b = coef[1::2], coef[2::2]
    amp = np.hypot(a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        # delta-method standard error of the amplitude
        va, vb = np.diag(cov)[1::2], np.diag(cov)[2::2]
        cab = np.array([cov[1 + 2 * i, 2 + 2 * i] for i in range(max_order)])
        amp_se = np.sqrt((a * a * va + b * b * vb + 2 * a * b * cab) / np.where(amp > 0, amp * amp, np.nan))
    pvals = []
    for i in range(max_order):
        keep = [j for j in range(G.shape[1]) if j not in (1 + 2 * i, 2 + 2 * i)]
        c_red, *_ = np.linalg.lstsq(G[:, keep], r, rcond=None)
        rss_red = float(np.sum((r - G[:, keep] @ c_red) ** 2))
        pvals.append(nested_f_test(rss_red, rss_full, len(keep), G.shape[1], x.size).p_value)
    return HarmonicFit(k, amp, np.arctan2(b, a), amp_se, np.asarray(pvals), float(coef[0]))


def autocorrelation(residuals: Any, max_lag: int | None = None) -> np.ndarray:
    """Sample autocorrelation rho_0..rho_max_lag (rho_0 = 1) of residuals in acquisition order.

    Shape ``(max_lag + 1,)``; default ``max_lag = n // 4``. Uses the biased (1/n) estimator,
    which keeps the sequence positive-definite.

    >>> np.round(autocorrelation([1.0, -1.0, 1.0, -1.0], 2), 3).tolist()
    [1.0, -0.75, 0.5]
    """
    r = _as_1d("residuals", residuals, min_len=2)
    n = r.size
    if max_lag is None:
        max_lag = n // 4
    if not 0 <= max_lag < n:
        raise InputValueError(f"max_lag: expected 0 <= max_lag < n = {n}, got {max_lag}")
    d = r - r.mean()
    c0 = float(d @ d)
    if c0 == 0.0:
        raise InputValueError("residuals: zero variance, autocorrelation undefined")
    return np.array([float(d[: n - k] @ d[k:]) / c0 for k in range(max_lag + 1)])


def effective_sample_size(residuals: Any) -> float:
    """Effective number of independent residuals, n / (1 + 2 sum_k rho_k).

    The sum is Geyer's initial positive sequence: pairs (rho_{2m} + rho_{2m+1}) are summed while
    positive, so noise in the tail of the autocorrelation does not inflate or shrink the answer.
    Capped to ``[1, n]`` (a negatively correlated series is not credited with more than n points).

    >>> rng = np.random.default_rng(1)
    >>> e = rng.standard_normal(2001)
    >>> ar = np.convolve(e, np.ones(5) / 5, mode="valid")   # MA(4): n_eff ~ n / 5
    >>> 0.12 < effective_sample_size(ar) / ar.size < 0.3
    True
    """
    r = _as_1d("residuals", residuals, min_len=3)
    n = r.size
    rho = autocorrelation(r, n - 1)
    total = -1.0  # Geyer: tau = -1 + 2 * sum_m Gamma_m, Gamma_m = rho_2m + rho_2m+1, rho_0 = 1
    for m in range((n - 1) // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if pair <= 0:
            break
        total += 2.0 * pair
    tau = max(total, 1.0)
    return float(min(max(n / tau, 1.0), n))


def ljung_box(residuals: Any, lags: int = 10) -> tuple[float, float]:
    """Ljung-Box portmanteau test of "no serial correlation" up to ``lags``: (Q, p-value)."""
    from scipy import stats

    r = _as_1d("residuals", residuals, min_len=3)
    n = r.size
    if not 1 <= lags < n:
        raise InputValueError(f"lags: expected 1 <= lags < n = {n}, got {lags}")
    rho = autocorrelation(r, lags)[1:]
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, float(stats.chi2.sf(q, lags))


def newey_west_default_lag(n: int) -> int:
    """Newey & West (1994) plug-in bandwidth floor(4 (n/100)^(2/9)); 4 for n = 120."""
    if n < 1:
        raise InputValueError(f"n: expected >= 1, got {n}")
    return int(np.floor(4.0 * (n / 100.0) ** (2.0 / 9.0)))


def newey_west_covariance(scores: Any, bread: Any, max_lag: int | None = None) -> np.ndarray:
    """HAC (Newey-West, Bartlett kernel) sandwich covariance of an M-estimator.

    Parameters
    ----------
    scores : array, shape (n, p)
        Per-observation estimating-function contributions g_i (for least squares
        g_i = J_i r_i, for a robust loss g_i = J_i psi(r_i)), in acquisition order.
    bread : array, shape (p, p)
        Derivative of sum_i g_i with respect to the parameters (J^T J for least squares,
        J^T diag(psi'(r)) J for a robust loss), up to sign.
    max_lag : int, optional
        Bartlett truncation lag L; default :func:`newey_west_default_lag`. ``0`` gives the
        heteroscedasticity-robust (HC0, White) sandwich.

    Returns
    -------
    array, shape (p, p)
        B^-1 S B^-1 with S = sum_{l=-L..L} (1 - ``|l|``/(L+1)) sum_i g_i g_{i-l}^T.

    >>> g = np.array([[1.0], [-1.0], [1.0], [-1.0]])
    >>> newey_west_covariance(g, np.eye(1), 0).tolist(), newey_west_covariance(g, np.eye(1), 1).tolist()
    ([[4.0]], [[1.0]])
    """
    g = np.asarray(scores, dtype=float)
    if g.ndim != 2:
        raise InputValueError(f"scores: expected shape (n, p), got {g.shape}")
    n, p = g.shape
    B = np.asarray(bread, dtype=float)
    if B.shape != (p, p):
        raise InputValueError(f"bread: expected shape ({p}, {p}), got {B.shape}")
    if max_lag is None:
        max_lag = newey_west_default_lag(n)
    if not 0 <= max_lag < n:
        raise InputValueError(f"max_lag: expected 0 <= max_lag < n = {n}, got {max_lag}")
    S = g.T @ g
    for lag in range(1, max_lag + 1):
        w = 1.0 - lag / (max_lag + 1.0)
        gamma = g[lag:].T @ g[:-lag]
        S += w * (gamma + gamma.T)
    Binv = np.linalg.inv(B)
    cov: np.ndarray = Binv @ S @ Binv.T
    return cov


@dataclass(frozen=True)
class NestedTest:
    """F-test of a small model (p_small parameters) nested in a big one (p_big)."""

    f_stat: float
    df_num: int
    df_den: int
    p_value: float
    delta_aic: float  # AIC(big) - AIC(small); negative favours the big model


def nested_f_test(rss_small: float, rss_big: float, p_small: int, p_big: int, n: float) -> NestedTest:
    """F = ((RSS_s - RSS_b)/(p_b - p_s)) / (RSS_b/(n - p_b)), p-value from ``scipy.stats.f``.

    ``n`` may be a (non-integer) effective sample size to allow for correlated residuals.

    >>> t = nested_f_test(10.0, 5.0, 1, 2, 12)
    >>> round(t.f_stat, 3), round(t.p_value, 4)
    (10.0, 0.0101)
    """
    from scipy import stats

    if not p_big > p_small >= 0:
        raise InputValueError(f"p_big, p_small: expected p_big > p_small >= 0, got {p_big}, {p_small}")
    if not n > p_big:
        raise InputValueError(f"n: expected > p_big = {p_big}, got {n}")
    if rss_big <= 0 or rss_small <= 0:
        raise InputValueError(f"rss: expected > 0, got rss_small={rss_small}, rss_big={rss_big}")
    df_num = p_big - p_small
    df_den = n - p_big
    f = ((rss_small - rss_big) / df_num) / (rss_big / df_den)
    p = float(stats.f.sf(f, df_num, df_den))
    daic = gaussian_aic(rss_big, n, p_big) - gaussian_aic(rss_small, n, p_small)
    return NestedTest(float(f), int(df_num), int(round(df_den)), p, float(daic))


def gaussian_aic(rss: float, n: float, k: int) -> float:
    """AIC of a Gaussian least-squares fit, n ln(RSS/n) + 2k (constants dropped)."""
    if rss <= 0 or n <= 0:
        raise InputValueError(f"rss, n: expected > 0, got {rss}, {n}")
    return float(n * np.log(rss / n) + 2 * k)
