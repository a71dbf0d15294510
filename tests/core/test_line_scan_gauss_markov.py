"""Pushbroom lines under a star tracker with a Gauss–Markov error (boresight.core.line_scan, its module docstring).

* **The oracle** (a test oracle, independent of ``gls.rows``' tridiagonal prior): the rows' dense covariance written
  from the model's definition, Σ = E + Σ_axes Z_a (σ_w² I + σ_c² K) Z_aᵀ in the rows' whitened units, K_km =
  exp(−|t_k − t_m|/τ) on the strip's tracker sample times, Z_a (2K, S) each row's unit tracker column of axis a at its
  line's two samples with their weights; the GLS (XᵀΣ⁻¹X)⁻¹ XᵀΣ⁻¹ q. Tolerance 1e-9 relative (two exact routes;
  round-off ~1e-12 here).
* **Noise-free recovery**: θ back to the inverse location's floor (1e-6″, as ``tests/core/test_line_scan.py``
  derives) under the Gauss–Markov model.
* **σ_c = 0 is today's model**: the fit with a zero Gauss–Markov σ equals the white model's bit for bit.
"""

import numpy as np
import pytest

from boresight.core.gls.rows import row_gls
from boresight.core.line_scan import LineScanUnknowns, estimate_line_scan, line_scan_rows, stacked_rows, tracker_correlation
from boresight.errors import InputValueError
from boresight.observations.strip import line_noise_model, strip_observations
from orbits.pushbroom import LineScanParameters
from orbits.strip import GcpLayout, StripConfig, TrackerNoise, simulate_strip, strip_geometry, zy3_like_sensor

ARCSEC = np.pi / 180 / 3600
TRUTH = LineScanParameters(theta_rad=np.array([20.0, -35.0, 50.0]) * ARCSEC)
SIGMA_PX, SIGMA_W, SIGMA_C, TAU_S = 0.3, 0.2, 1.0, 2.0  # τ = 2 s: the 3 s strip's samples partly correlated
PITCH = 7e-6


@pytest.fixture(scope="module")
def strip():
    geo = strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=10.0))
    sim = simulate_strip(
        geo, TRUTH, np.random.default_rng(3), GcpLayout(n_gcps=40), TrackerNoise(SIGMA_W, SIGMA_C, TAU_S), SIGMA_PX
    )
    return strip_observations(sim)


def _model(sigma_c=SIGMA_C):
    return line_noise_model(SIGMA_PX, SIGMA_W, PITCH, sigma_star_tracker_correlated_arcsec=sigma_c, correlation_time_s=TAU_S)


def test_the_gauss_markov_gls_equals_the_dense_covariance(strip):
    """The normal equations of the GLS with the tridiagonal AR(1) prior against the dense Σ = E + Z (σ_w² I + σ_c² K) Zᵀ."""
    x = TRUTH.theta_rad + 3 * ARCSEC  # off the truth: q ≠ 0
    st, cols = line_scan_rows(strip, x, LineScanUnknowns(), _model())
    assert st.sample_correlation is not None and cols.A.shape[-1] == 6  # three white, three Gauss–Markov columns
    ne = row_gls(st, cols).normal_equations
    # the oracle: unit (1″) tracker columns of each axis, gathered densely onto the samples
    _, unit = line_scan_rows(strip, x, LineScanUnknowns(), line_noise_model(SIGMA_PX, 1.0, PITCH))
    K, S = strip.n_observations, strip.sample_t_s.size
    t = strip.sample_t_s
    Kc = np.exp(-np.abs(t[:, None] - t[None, :]) / TAU_S)
    Sigma = np.eye(2 * K)
    img = strip.image_index
    for a in range(3):
        Z = np.zeros((K, 2, S))
        for i in range(2):
            for k in range(K):
                Z[k, :, strip.sample_index[img[k], i]] += strip.sample_weight[img[k], i] * unit.A[0, k, :, a]
        Z = Z.reshape(2 * K, S)
        Sigma += Z @ (SIGMA_W**2 * np.eye(S) + SIGMA_C**2 * Kc) @ Z.T
    X, q = cols.X[0].reshape(2 * K, -1), cols.q[0].reshape(-1)
    Si = np.linalg.inv(Sigma)
    assert np.max(np.abs(ne.data_information[0] - X.T @ Si @ X)) / np.max(np.abs(X.T @ Si @ X)) < 1e-9
    assert np.max(np.abs(ne.vector[0] - X.T @ Si @ q)) / np.max(np.abs(X.T @ Si @ q)) < 1e-9
    assert abs(ne.weighted_sum_squares[0] - q @ Si @ q) / (q @ Si @ q) < 1e-9


def test_noise_free_recovery_under_the_gauss_markov_model():
    """θ to 1e-6″ on a noise-free strip (no tracker or pixel error drawn) fitted under the Gauss–Markov model."""
    geo = strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=-15.0))
    obs = strip_observations(simulate_strip(geo, TRUTH, np.random.default_rng(4), GcpLayout(n_gcps=60)))
    fit = estimate_line_scan(obs, LineScanUnknowns(), _model())
    assert np.abs(fit.x[:3] - TRUTH.theta_rad).max() / ARCSEC < 1e-6
    assert fit.chi2 < 1e-6 and fit.converged
    # the correlated part widens σθ over the white model's
    white = estimate_line_scan(obs, LineScanUnknowns(), _model(0.0))
    assert np.all(fit.sigma[:2] > 3 * white.sigma[:2])


def test_a_zero_gauss_markov_sigma_is_the_white_model_bit_for_bit(strip):
    """σ_c = 0: no extra columns, no prior correlation, and the fit is the white model's exactly."""
    white = line_noise_model(SIGMA_PX, SIGMA_W, PITCH)
    zero = _model(0.0)
    assert not zero.has_correlated_tracker
    st, cols = line_scan_rows(strip, TRUTH.theta_rad, LineScanUnknowns(), zero)
    assert st.sample_correlation is None and cols.A.shape[-1] == 3
    a, b = estimate_line_scan(strip, LineScanUnknowns(), white), estimate_line_scan(strip, LineScanUnknowns(), zero)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.covariance, b.covariance) and a.chi2 == b.chi2


def test_tracker_correlation_and_refusals():
    """φ = exp(−Δt/τ) between consecutive samples, 0 at the first; unsorted times and a frame camera's GLS refused."""
    phi = tracker_correlation([0.0, 0.5, 0.75, 2.0], 2.0)
    assert np.allclose(phi, [0.0, np.exp(-0.25), np.exp(-0.125), np.exp(-0.625)], rtol=0, atol=1e-15)
    with pytest.raises(InputValueError, match="sample 2 at 0.4"):
        tracker_correlation([0.0, 0.5, 0.4], 2.0)
    from boresight.core.gls.structure import scaled_columns

    J = {k: np.zeros((1, 2, 2, 3)) for k in ("star_tracker", "gnss", "catalogue")}
    with pytest.raises(InputValueError, match="pushbroom lines' tracker samples only"):
        scaled_columns(J, _model())


def test_a_campaigns_strips_are_separate_processes(strip):
    """Two strips stacked (``stacked_rows``): φ = 0 at the second strip's first sample, so with nothing else shared the
    campaign's reduced information is the sum of the strips' (1e-10: round-off)."""
    geo = strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=-5.0))
    sim = simulate_strip(
        geo, TRUTH, np.random.default_rng(5), GcpLayout(n_gcps=30), TrackerNoise(SIGMA_W, SIGMA_C, TAU_S), SIGMA_PX
    )
    other = strip_observations(sim)
    x = TRUTH.theta_rad
    st, cols = stacked_rows([strip, other], x, LineScanUnknowns(), _model())
    assert st.sample_correlation[strip.sample_t_s.size, 3:].tolist() == [0.0, 0.0, 0.0]
    assert np.all(st.sample_correlation[1 : strip.sample_t_s.size, 3:] > 0)
    both = row_gls(st, cols).normal_equations
    parts = [row_gls(*line_scan_rows(o, x, LineScanUnknowns(), _model())).normal_equations for o in (strip, other)]
    for name in ("data_information", "vector", "weighted_sum_squares"):
        total = sum(getattr(p, name) for p in parts)
        assert np.max(np.abs(getattr(both, name) - total)) <= 1e-10 * np.max(np.abs(total))


def test_a_gauss_markov_scenario_estimates_under_its_own_model():
    """A pushbroom scenario with ``star_tracker_correlated_arcsec``: ``strip_noise_model`` carries σ_c and τ (no
    refusal); its simulated sets carry no white-only noise mapping, so ``boresight.estimate`` asks for the model
    rather than fit an overconfident σ, and with ``model=`` names the Gauss–Markov part in ``sigma_includes``."""
    from boresight import estimate
    from boresight.observations.strip import simulate_strip_scenario, strip_noise_model
    from orbits.strip import strip_scenario_from_dict

    doc = {
        "kind": "pushbroom",
        "strip": {"roll_deg": 10.0},
        "gcps": {"n_gcps": 30},
        "noise": {
            "sigma_pixel_px": 0.3,
            "star_tracker_white_arcsec": 0.1,
            "star_tracker_correlated_arcsec": 2.0,
            "correlation_time_s": 20.0,
        },
        "truth": {"theta_arcsec": [20.0, -35.0, 50.0]},
    }
    sc = strip_scenario_from_dict(doc, "gm.toml")
    model = strip_noise_model(sc)
    assert model.sigma_star_tracker_correlated_rad == (2.0 * ARCSEC,) * 3 and model.star_tracker_correlation_time_s == 20.0
    strips = simulate_strip_scenario(sc, np.random.default_rng(9))
    assert strips[0].noise is None
    with pytest.raises(InputValueError, match="GLS under a noise model"):
        estimate(strips)
    est = estimate(strips, model=model)
    assert "Gauss–Markov [2, 2, 2]″, τ 20 s" in est.sigma_includes


def test_a_robust_fit_under_the_gauss_markov_model(strip):
    """The robust losses run on the same GLS: on this clean strip hardly a detection passes Huber's corner, so the Huber
    fit is the least-squares θ (within 1e-6 σ; measured 7e-12) and its M-estimator sandwich σ the GLS σ within 1 %
    (measured 0.2 %) — the sandwich's tracker term carries the samples' correlation K (``row_sandwich_middle``);
    treating the Gauss–Markov columns as white per sample would give θx's GLS σ 0.29″ instead of 0.77″ here."""
    ls = estimate_line_scan(strip, LineScanUnknowns(), _model())
    hu = estimate_line_scan(strip, LineScanUnknowns(), _model(), loss="huber")
    assert np.all(np.abs(hu.x[:3] - ls.x[:3]) < 1e-6 * ls.sigma[:3])
    assert np.all(np.abs(hu.sigma[:3] / ls.sigma[:3] - 1) < 0.01)
