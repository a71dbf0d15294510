"""boresight.stats: the one χ² band, σ / rate intervals and detectable size (issue 18)."""

import numpy as np
import pytest

from boresight import stats


def test_chi2_band_covers_its_level():
    """Fraction of χ²(d)/d draws inside the 99.9 % band: binomial σ √(p(1−p)/n) = 1.0e-4 at
    n = 100 000, so |rate − 0.999| < 5σ = 5e-4 (seed fixed)."""
    rng = np.random.default_rng(7)
    d = 157
    x = rng.chisquare(d, 100_000)
    inside = 1.0 - stats.chi2_outside(x, d).mean()
    assert abs(inside - stats.CHI2_LEVEL) < 5e-4


def test_chi2_outside_ignores_zero_dof_and_broadcasts():
    out = stats.chi2_outside([0.0, 10.0, 1e6], [0, 10, 10])
    assert out.tolist() == [False, False, True]


def test_sigma_interval_covers_its_level():
    """95 % interval of σ from n = 20 samples, 4 000 trials: coverage σ = √(.95·.05/4000) =
    3.4e-3, tolerance 5σ = 0.017."""
    rng = np.random.default_rng(3)
    s = rng.standard_normal((4000, 20)).std(axis=1, ddof=1)
    lo, hi = stats.sigma_interval(s, 20, 0.95)
    assert abs(np.mean((lo <= 1.0) & (1.0 <= hi)) - 0.95) < 0.017


def test_binomial_interval_edges_and_refusals():
    assert stats.binomial_interval(0, 10)[0] == 0.0 and stats.binomial_interval(10, 10)[1] == 1.0
    lo, hi = stats.binomial_interval(31, 40, 0.95)
    assert lo < 31 / 40 < hi
    with pytest.raises(ValueError, match="k, n"):
        stats.binomial_interval(11, 10)


def test_noncentrality_guards():
    assert stats.minimum_detectable_noncentrality(0, 0.05, 0.8) == float("inf")
    assert stats.minimum_detectable_noncentrality(1, 0.05, 0.05) == 0.0
    with pytest.raises(ValueError, match="alpha"):
        stats.minimum_detectable_noncentrality(1, 1.5, 0.8)


def test_mad_constant_is_the_normal_quartile():
    from scipy.stats import norm

    assert stats.MAD_TO_SIGMA == pytest.approx(1.0 / norm.ppf(0.75), rel=1e-15)


def test_stats_imports_scipy_only_inside_functions():
    """Importing boresight.stats costs numpy only: scipy is imported where it is used (start-up)."""
    import ast
    import pathlib

    for path in pathlib.Path(stats.__file__).parent.glob("*.py"):
        top = [n for n in ast.parse(path.read_text()).body if isinstance(n, (ast.Import, ast.ImportFrom))]
        names = [a.name for n in top if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in top if isinstance(n, ast.ImportFrom)]
        assert not [m for m in names if m.split(".")[0] == "scipy"], path.name


def test_minimum_detectable_noncentrality_at_the_edges_of_float64():
    """A power that rounding puts just above a tiny α (the naming rule's level at α = 1e-300) needs
    no signal, never a root-finder error (found by the slow fuzz: diagnose --alpha 1e-300 --power 1e-300)."""
    from boresight.stats import minimum_detectable_noncentrality as m

    assert m(1, 9.999999999999506e-301, 1e-300) == 0.0
    assert abs(m(1, 0.05, 0.8) - 7.85) < 0.01


def test_tails_equal_scipy_stats_to_the_last_bit():
    """``chi2_sf``, ``chi2_isf`` and ``ncx2_sf`` are scipy.special's routines behind scipy.stats'
    chi2.sf/isf and ncx2.sf (imported without scipy.stats, issue 19): equal bit for bit on valid
    arguments, and a negative χ² is in the tail with probability 1 as in scipy.stats."""
    from scipy import stats as sps

    from boresight.stats import chi2_isf, chi2_sf, ncx2_sf

    rng = np.random.default_rng(3)
    x, k = rng.uniform(0, 200, 5000), rng.integers(1, 12, 5000).astype(float)
    nc, p = rng.uniform(1e-12, 400, 5000), rng.uniform(1e-12, 1, 5000)
    assert np.array_equal(chi2_sf(x, k), sps.chi2.sf(x, k))
    assert np.array_equal(chi2_isf(p, k), sps.chi2.isf(p, k))
    assert np.array_equal(ncx2_sf(x, k, nc), sps.ncx2.sf(x, k, nc))
    assert chi2_sf(-3.0, 2) == sps.chi2.sf(-3.0, 2) == 1.0


def test_hotelling_t2_isf_is_the_scaled_f_point_and_covers():
    """T² ≤ hotelling_t2_isf(0.05, n) is the 95 % confidence region of a bivariate mean: equal to
    2(n−1)/(n−2)·F(2, n−2) from scipy.stats, and covering the true mean in 95 % of 20 000 seeded
    samples of n = 6 (binomial σ of the rate 0.0015: the ±0.006 tolerance is 4σ); NaN for n ≤ 2."""
    import scipy.stats as sps

    from boresight.stats import hotelling_t2_isf

    n = np.array([3, 6, 20, 200])
    assert np.allclose(hotelling_t2_isf(0.05, n), 2 * (n - 1) / (n - 2) * sps.f.isf(0.05, 2, n - 2), rtol=1e-12)
    assert np.isnan(hotelling_t2_isf(0.05, [1, 2])).all()
    x = np.random.default_rng(5).normal(size=(20_000, 6, 2)) @ np.array([[2.0, 0.0], [1.0, 0.5]])
    m = x.mean(axis=1)
    S = np.einsum("rki,rkj->rij", x - m[:, None], x - m[:, None]) / 5
    t2 = 6 * np.einsum("ri,rij,rj->r", m, np.linalg.inv(S), m)
    assert abs(np.mean(t2 <= hotelling_t2_isf(0.05, 6)) - 0.95) < 0.006
