"""Generic residual diagnostics (boresight.stats.residuals)."""

from __future__ import annotations

import numpy as np
import pytest

from boresight.stats.residuals import (
    autocorrelation,
    binned_residuals,
    effective_sample_size,
    harmonic_fit,
    ljung_box,
    nested_f_test,
    newey_west_covariance,
    newey_west_default_lag,
    outlier_flags,
    robust_sigma,
    robust_z,
)


def rng(seed):
    return np.random.default_rng(np.random.SeedSequence(seed))


def ar1(g, n, rho):
    e = g.standard_normal(n)
    x = np.empty(n)
    x[0] = e[0]
    for i in range(1, n):
        x[i] = rho * x[i - 1] + np.sqrt(1 - rho**2) * e[i]
    return x


def test_robust_scale_and_outliers():
    g = rng(1)
    r = g.normal(0, 2.0, 4000)
    assert robust_sigma(r) == pytest.approx(2.0, rel=0.05)  # 4000 points: MAD known to ~2 %
    r[[5, 17]] = [40.0, -35.0]
    flags = outlier_flags(r)
    assert flags[5] and flags[17]
    assert flags.sum() < 10  # 3.5 sigma: ~2 false flags expected in 4000
    with pytest.raises(ValueError, match="median absolute deviation is 0"):
        robust_z([1.0, 1.0, 1.0, 2.0])


def test_binned_residuals_finds_structure_and_not_noise():
    g = rng(2)
    x = g.uniform(0, 360, 600)
    noise = g.normal(0, 1.0, 600)
    flat = binned_residuals(x, noise, bins=12)
    assert flat.p_value > 0.01 and flat.count.sum() == 600
    bumpy = binned_residuals(x, noise + 0.5 * np.sin(np.radians(2 * x)), bins=12)
    assert bumpy.p_value < 1e-6


def test_harmonic_fit_recovers_amplitude_and_phase():
    g = rng(3)
    x = np.sort(g.uniform(0, 2 * np.pi, 400))
    r = 0.2 + 0.5 * np.cos(3 * x - 1.0) + g.normal(0, 0.1, 400)
    h = harmonic_fit(x, r, max_order=4)
    assert h.amplitude[2] == pytest.approx(0.5, abs=5 * h.amplitude_se[2])
    assert h.phase_rad[2] == pytest.approx(1.0, abs=0.05)
    assert h.p_value[2] < 1e-10 and np.all(h.p_value[[0, 1, 3]] > 1e-3)


def test_autocorrelation_and_effective_sample_size():
    g = rng(4)
    white = g.standard_normal(5000)
    assert effective_sample_size(white) == pytest.approx(5000, rel=0.15)
    x = ar1(g, 5000, 0.6)
    # AR(1): n_eff = n (1 - rho) / (1 + rho) = n / 4
    assert effective_sample_size(x) / 5000 == pytest.approx(0.25, rel=0.2)
    assert autocorrelation(x, 1)[1] == pytest.approx(0.6, abs=0.05)
    assert ljung_box(white, 10)[1] > 0.001 and ljung_box(x, 10)[1] < 1e-10


def test_newey_west_mean_of_ar1_is_calibrated():
    # the standard error of a mean of AR(1) data: HAC close to the Monte Carlo spread, HC0 not
    g = rng(5)
    n, rho = 400, 0.5
    means, se_hac, se_hc0 = [], [], []
    for _ in range(400):
        x = ar1(g, n, rho)
        m = x.mean()
        scores = (x - m)[:, None]
        bread = np.array([[float(n)]])
        means.append(m)
        se_hac.append(np.sqrt(newey_west_covariance(scores, bread, 10)[0, 0]))
        se_hc0.append(np.sqrt(newey_west_covariance(scores, bread, 0)[0, 0]))
    spread = np.std(means, ddof=1)  # ~ sqrt(3/400) = 0.087; known to ~4 % from 400 runs
    assert np.mean(se_hac) / spread == pytest.approx(1.0, abs=0.15)
    assert np.mean(se_hc0) / spread < 0.65  # truth: 1/sqrt(3) = 0.58


def test_nested_f_test_size_and_power():
    g = rng(6)
    x = np.linspace(-1, 1, 200)
    p_null, p_alt = [], []
    for _ in range(300):
        y = 1 + 2 * x + g.normal(0, 1, 200)
        for store, yy in ((p_null, y), (p_alt, y + 0.5 * x**2 * 3)):
            G1 = np.column_stack([np.ones_like(x), x])
            G2 = np.column_stack([G1, x**2])
            rss1 = np.sum((yy - G1 @ np.linalg.lstsq(G1, yy, rcond=None)[0]) ** 2)
            rss2 = np.sum((yy - G2 @ np.linalg.lstsq(G2, yy, rcond=None)[0]) ** 2)
            store.append(nested_f_test(rss1, rss2, 2, 3, 200).p_value)
    # size: 5 % rejections under the null (binomial sd 1.3 % with 300 runs)
    assert np.mean(np.array(p_null) < 0.05) == pytest.approx(0.05, abs=0.04)
    assert np.mean(np.array(p_alt) < 0.05) > 0.9


def test_bad_input_is_named():
    with pytest.raises(ValueError, match=r"residuals: non-finite value nan at index 2"):
        robust_sigma([1.0, 2.0, np.nan])
    with pytest.raises(ValueError, match=r"x and residuals: shapes differ, \(3,\) vs \(2,\)"):
        binned_residuals([1, 2, 3], [1, 2])
    with pytest.raises(ValueError, match=r"bread: expected shape \(2, 2\), got \(3, 3\)"):
        newey_west_covariance(np.ones((5, 2)), np.eye(3))
    with pytest.raises(ValueError, match=r"p_big, p_small: expected p_big > p_small >= 0, got 2, 2"):
        nested_f_test(1.0, 1.0, 2, 2, 10)
    assert newey_west_default_lag(120) == 4
