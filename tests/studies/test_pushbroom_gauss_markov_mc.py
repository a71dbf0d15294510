"""Honesty of σθ on pushbroom strips whose star-tracker error is mostly Gauss–Markov (boresight.core.line_scan), and
the line sensitivities' Gauss–Markov source (its own test's docstring derives its tolerance).

Run k simulates one ZY-3-like strip (3.1 s, roll 10°, 40 GCPs, pixels 0.3 px) with the tracker error
``TrackerNoise(σ_w = 0.1″, σ_c = 2″, τ = 20 s)`` per sample at 4 Hz (``default_rng([SEED, k])``) and fits θ twice on the
same rows: under the Gauss–Markov model (σ_w, σ_c, τ: the truth's) and under the white-only model (σ_w alone, what the
estimator could do before). Over 3 s a τ = 20 s process is nearly a common rotation of every line, which θ cannot tell
from itself: it moves θ̂ by ~σ_c, and only the model that knows it says so.

**Tolerance** (derived): if the reported σ_k of run k is θ̂'s true standard deviation, z_k = (θ̂_k − θ)/σ_k are
independent N(0, 1) (one linearisation: θ is 60″, second order ~1e-8 of it), so Σ_k z_k² ~ χ²_N per axis. The test
accepts Σ z² between the χ²_N quantiles at α/2 and 1 − α/2, α = 1e-3 per axis: an honest σ fails an axis with
probability 1e-3 (3e-3 for the three). With N = 200 the band on mean z² is 0.70 … 1.36 (a σ off by more than ~15 %
low or ~20 % high is caught); with N = 2 000 (slow) 0.90 … 1.11. The white-only model's σ must fail the band on every
axis: its mean z² is ~(σ_GM/σ_white)², measured 1 466, 1 393 and 3.47 (x, y, z; 200 strips, against 0.94, 0.98 and 0.92
under the Gauss–Markov model), far outside (θz, about the boresight, is the axis the pixels leave weakest, so the
tracker's share of it is smallest). Run: ``python -m pytest -s -m "slow or not slow" -p no:cacheprovider
tests/studies/test_pushbroom_gauss_markov_mc.py`` (prints the figures; docs/pushbroom.md quotes them).
"""

import numpy as np
import pytest
from scipy.stats import chi2

from boresight.core.line_scan import LineScanUnknowns, estimate_line_scan
from boresight.observations.strip import line_noise_model, strip_observations
from orbits.pushbroom import LineScanParameters
from orbits.strip import GcpLayout, StripConfig, TrackerNoise, simulate_strip, strip_geometry, zy3_like_sensor

SEED = 20261128
ARCSEC = np.pi / 180 / 3600
TRUTH = LineScanParameters(theta_rad=np.array([20.0, -35.0, 50.0]) * ARCSEC)
TRACKER = TrackerNoise(sigma_white_arcsec=0.1, sigma_correlated_arcsec=2.0, correlation_time_s=20.0)
SIGMA_PX, PITCH, ALPHA = 0.3, 7e-6, 1e-3


def _gm_model():
    """The Gauss–Markov noise model of ``TRACKER`` (the truth's)."""
    return line_noise_model(
        SIGMA_PX,
        TRACKER.sigma_white_arcsec,
        PITCH,
        sigma_star_tracker_correlated_arcsec=TRACKER.sigma_correlated_arcsec,
        correlation_time_s=TRACKER.correlation_time_s,
    )


@pytest.fixture(scope="module")
def geometry():
    return strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=10.0))


def _z_squared(geometry, n_runs):
    """(mean z² (3,) under the Gauss–Markov model, under the white-only model, mean reported σ of each (3,) ″, scatter ″)."""
    gm = _gm_model()
    white = line_noise_model(SIGMA_PX, TRACKER.sigma_white_arcsec, PITCH)
    z2 = {"gm": np.zeros(3), "white": np.zeros(3)}
    sig = {"gm": np.zeros(3), "white": np.zeros(3)}
    err = np.empty((n_runs, 3))
    for k in range(n_runs):
        sim = simulate_strip(geometry, TRUTH, np.random.default_rng([SEED, k]), GcpLayout(n_gcps=40), TRACKER, SIGMA_PX)
        obs = strip_observations(sim)
        for name, model in (("gm", gm), ("white", white)):
            fit = estimate_line_scan(obs, LineScanUnknowns(), model)
            e = fit.x[:3] - TRUTH.theta_rad
            z2[name] += (e / fit.sigma[:3]) ** 2 / n_runs
            sig[name] += fit.sigma[:3] / ARCSEC / n_runs
            if name == "gm":
                err[k] = e / ARCSEC
    return z2, sig, err.std(axis=0, ddof=1)


@pytest.mark.parametrize("n_runs", [200, pytest.param(2000, marks=pytest.mark.slow)])
def test_sigma_is_honest_under_a_gauss_markov_tracker(geometry, n_runs):
    z2, sig, scatter = _z_squared(geometry, n_runs)
    lo, hi = chi2.ppf([ALPHA / 2, 1 - ALPHA / 2], n_runs) / n_runs
    print(
        f"\n{n_runs} strips: scatter {scatter}″; mean σ Gauss–Markov {sig['gm']}″, white-only {sig['white']}″; "
        f"mean z² Gauss–Markov {z2['gm']}, white-only {z2['white']} (band {lo:.3f} … {hi:.3f})"
    )
    assert np.all((lo <= z2["gm"]) & (z2["gm"] <= hi))
    assert np.all(z2["white"] > hi)


def test_line_sensitivities_split_sigma_with_the_gauss_markov_source(geometry):
    """``line_scan_sensitivities`` under the Gauss–Markov model: pixel² + white² + Gauss–Markov² = σθ² (the optimal
    gain's split, to round-off), the Gauss–Markov source holds θx and θy (it is nearly a common rotation of the strip),
    and 40 resimulations with common random numbers (each σ doubled; ``resimulate_lines`` draws the process) agree with
    the linear propagation within 4 of their standard errors on every axis and source (the FD's SE is its per-run
    spread over √40, so an honest agreement fails an axis with probability ~6e-5)."""
    from boresight.studies.sensitivity import line_scan_sensitivities

    sim = simulate_strip(geometry, TRUTH, np.random.default_rng([SEED, 999_999]), GcpLayout(n_gcps=40), TRACKER, SIGMA_PX)
    model = _gm_model()
    r = line_scan_sensitivities(strip_observations(sim), LineScanUnknowns(), model, runs=40, seed=5)
    assert r.sources == ["pixel", "star_tracker", "star_tracker_gm"]
    total = np.sqrt(sum(r.contribution[s] ** 2 for s in r.sources))
    np.testing.assert_allclose(total, r.sigma_theta_arcsec, rtol=1e-10)
    assert np.all(r.share("star_tracker_gm")[:2] > 0.95)
    for s in r.sources:
        assert np.all(np.abs(r.fd_coef[s] - r.coef[s]) < 4 * r.fd_se[s]), (s, r.fd_coef[s], r.coef[s], r.fd_se[s])
