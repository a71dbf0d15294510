"""Kalman variant (Kiev 2012 eq 32): filterpy twin, consistency (NEES, NIS), batch-GLS equality,
σθ not growing with images, χ² gating, registry, bad input.

Statistical tests use fixed seeds and bounds from the sampling distribution of the statistic
(χ² for NEES/NIS, the standard error of a sample standard deviation, the binomial for false
rejections), each at 99 % or stricter, so that each can fail when the filter is wrong.
"""

from dataclasses import replace

import numpy as np
import pytest
from oracles import dense_grid
from scipy.stats import binom, chi2

import boresight
from boresight.core.algorithms.kalman import (
    default_states,
    joseph_update,
    kalman_filter,
    kalman_filter_filterpy,
    linearized_measurements,
    prior,
    state_layout,
)
from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.normal_equations import NormalEquations
from boresight.reproductions.kiev2012 import kalman_scenario, kalman_table, seminar_kalman_table
from orbits.rotations import ARCSEC

SIGMA0_ARCMIN10 = 600.0  # σθ0 = 10′, the seminar's sensitivity case
K_RUNS = 600  # ≥ 500 runs for the statistical tests


def _case(sigma0_arcsec=SIGMA0_ARCMIN10, mode=None, runs=K_RUNS, seed=0):
    sc = kalman_scenario(sigma0_arcsec=sigma0_arcsec, star_tracker_mode=mode, gnss_mode=mode)
    model = DisturbanceModel.from_scenario(sc)
    obs = boresight.simulate(sc, np.random.default_rng(np.random.SeedSequence(seed)), runs=runs)
    return sc, model, obs


def _nees_bounds(k, n_states=3, p=0.99):
    """Mean of k NEES values of an n-state consistent filter: k·mean ~ χ²(n k)."""
    a = (1 - p) / 2
    return chi2.ppf(a, n_states * k) / k, chi2.ppf(1 - a, n_states * k) / k


def _rel(a, b):
    """max |a − b| relative to max |b|."""
    return np.abs(a - b).max() / np.abs(b).max()


# ---------------------------------------------------------------------------- filterpy twin

TWIN_CASES = {
    # default states (θ + catalogue errors), IEKF, 10′ prior
    "iekf-default": dict(sigma0_arcsec=600.0, mode=None, options={}),
    # every option at once: per-pass + per-image star tracker and GNSS (bias states), gating, drift
    "iekf-biases-gate-drift": dict(
        sigma0_arcsec=600.0, mode="both", options=dict(gate_probability=0.999, sigma_drift_rad_per_sqrt_s=1e-8)
    ),
    "iekf-theta-only": dict(sigma0_arcsec=600.0, mode=None, options=dict(states=("theta",))),
    # landmark 1 unseen in images 5-9 and image 12 empty: dof 6 and 0, no update at image 12
    "iekf-masked-gated": dict(sigma0_arcsec=600.0, mode=None, options=dict(gate_probability=0.999), masked=True),
    # whole-pass relinearisation. DECISION: at the 10″ prior of the seminar's table — with a 10′
    # prior the first update has cond(S) ≈ 2e7 and a 1-ulp change of the linearisation point
    # between outer iterations moves both implementations by ~1e-9 relative (round-off, not a
    # difference between them; docs/kalman.md "Numerics").
    "pass-3": dict(sigma0_arcsec=10.0, mode="both", options=dict(linearization="pass", iterations=3)),
}


@pytest.mark.parametrize("name", list(TWIN_CASES))
def test_batched_filter_equals_filterpy_reference(name):
    case = TWIN_CASES[name]
    _, model, obs = _case(case["sigma0_arcsec"], case["mode"], runs=3, seed=1)
    if case.get("masked"):
        obs = dense_grid(obs)  # the images × landmarks grid (tests/oracles.py)
        mask = obs.mask.copy()
        mask[5:10, 1] = False
        mask[12, :] = False
        obs = replace(obs, mask=mask).to_rows()
    options = dict(case["options"], sigma0_rad=case["sigma0_arcsec"] * ARCSEC)
    batch = kalman_filter(obs, model, **options)
    layout = state_layout(batch.states, obs.n_landmarks)
    for k in range(obs.runs):
        ref = kalman_filter_filterpy(obs.run(k), model, **options)
        assert ref.states == batch.states
        for block, sl in layout.items():
            assert _rel(batch.x_history[k, :, sl], ref.x_history[0, :, sl]) < 1e-10, block
            assert _rel(batch.P_history[k, :, sl, sl], ref.P_history[0, :, sl, sl]) < 1e-10, block
        assert _rel(batch.P_history[k], ref.P_history[0]) < 1e-10
        # NIS of the first image after a 10′ prior is a difference of ~1e6-sized terms: both
        # implementations carry ~1e-10 relative round-off there.
        assert _rel(batch.nis[k], ref.nis[0]) < 1e-8
        np.testing.assert_array_equal(batch.rejected[k], ref.rejected[0])
    np.testing.assert_array_equal(batch.dof, 2 * obs.rows_per_image)
    if case.get("masked"):
        assert batch.dof[5] == 6 and batch.dof[12] == 0
        np.testing.assert_array_equal(batch.x_history[:, 12], batch.x_history[:, 11])


# ---------------------------------------------------------------------------- consistency


def test_nees_mean_inside_99_percent_chi2_bounds():
    """600 runs, 20 images, 10′ prior: mean NEES of θ after the last image ~ χ²(3K)/K."""
    _, model, obs = _case(seed=2)
    res = kalman_filter(obs, model, sigma0_rad=SIGMA0_ARCMIN10 * ARCSEC)
    nees = res.nees(obs.truth["theta_rad"])[:, -1]
    lo, hi = _nees_bounds(obs.runs)
    assert lo < nees.mean() < hi, (nees.mean(), lo, hi)
    # the innovations too: Σ NIS ~ χ²(Σ dof) over all images and runs (white innovations)
    dof = res.dof.sum() * obs.runs
    assert chi2.ppf(0.005, dof) < res.nis.sum() < chi2.ppf(0.995, dof), res.nis.sum() / dof


@pytest.mark.parametrize(
    "label, mode, filter_model, states",
    [
        # landmarks weighted as independent with pixel noise only (the slides' unit weighting)
        ("pixel-only R", None, DisturbanceModel(sigma_pixel_m=3e-6), ("theta",)),
        # a per-pass star-tracker bias treated as fresh noise in every image
        ("per-pass bias as per-image noise", "per_pass", None, ("theta", "catalogue")),
    ],
)
def test_a_filter_that_ignores_shared_errors_fails_the_nees_test(label, mode, filter_model, states):
    """The NEES test has power: the overconfident variants of the seminar-style filter fail it."""
    _, model, obs = _case(mode=mode, seed=3)
    res = kalman_filter(obs, filter_model or model, sigma0_rad=SIGMA0_ARCMIN10 * ARCSEC, states=states)
    nees = res.nees(obs.truth["theta_rad"])[:, -1]
    assert nees.mean() > _nees_bounds(obs.runs)[1], label
    if filter_model is None:  # the same data with the bias as a state is consistent
        good = kalman_filter(obs, model, sigma0_rad=SIGMA0_ARCMIN10 * ARCSEC)
        assert "star_tracker_bias" in good.states
        lo, hi = _nees_bounds(obs.runs)
        assert lo < good.nees(obs.truth["theta_rad"])[:, -1].mean() < hi


def test_sigma_theta_does_not_grow_from_4_to_20_images():
    """Unlike the seminar's table (σθx 1.7″ → 4.6″), σθ(20 images) ≤ σθ(4 images) within sampling error.

    Each sample σ has relative standard error 1/sqrt(2(K−1)); their ratio at most sqrt(2) times
    that (less: the two are positively correlated). Tolerance: 3 of those.
    """
    _, model, obs = _case(sigma0_arcsec=10.0, seed=4)
    res = kalman_filter(obs, model, sigma0_rad=10.0 * ARCSEC)
    err = (res.theta_history_rad - obs.truth["theta_rad"][:, None]) / ARCSEC
    s4, s20 = err[:, 3].std(axis=0, ddof=1), err[:, 19].std(axis=0, ddof=1)
    tol = 3.0 / np.sqrt(obs.runs - 1)
    assert np.all(s20 <= s4 * (1 + tol)), (s4, s20)
    # and the filter's own σ agrees with the scatter at 20 images (per axis, χ²(K−1) on the variance)
    pred = np.sqrt(res.P_history[:, 19, [0, 1, 2], [0, 1, 2]].mean(axis=0)) / ARCSEC
    k = obs.runs - 1
    ratio = s20**2 / pred**2
    assert np.all((chi2.ppf(0.005 / 3, k) / k < ratio) & (ratio < chi2.ppf(1 - 0.005 / 3, k) / k)), ratio


def test_iterated_update_reaches_the_map_estimate_and_one_step_does_not():
    """IEKF (3 steps per image) ≈ the converged whole-pass Gauss-Newton MAP; a plain EKF is ~1″ off."""
    _, model, obs = _case(runs=100, seed=5)
    iekf = kalman_filter(obs, model)
    ekf = kalman_filter(obs, model, iterations=1)
    mapx = kalman_filter(obs, model, linearization="pass", iterations=5)
    assert np.abs(iekf.theta_rad - mapx.theta_rad).max() / ARCSEC < 0.01
    assert np.abs(ekf.theta_rad - mapx.theta_rad).max() / ARCSEC > 0.1


# ---------------------------------------------------------------------------- batch GLS


def _gls_normal_equations(obs, model, states, sigma0_rad, x_lin):
    """The batch GLS with the filter's prior, per-image covariances and linearisation point, on
    the project's ``NormalEquations`` (full-covariance whitening, Schur elimination of the
    shared-error states). Nuisance columns are scaled by their prior σ, as ``boresight.estimate``
    does: unscaled (rad and m mixed) the elimination loses ~1e-7 relative."""
    x0, P0 = prior(model, states, sigma0_rad, 0.0, obs.n_landmarks)
    nx = x0.size
    H, r, R = linearized_measurements(obs, x_lin, model, states)
    D = np.sqrt(np.diag(P0))
    D[:3] = 1.0
    ne = NormalEquations(n_params=nx, runs=obs.runs)
    ne.update(H * D, r, covariance=R)
    info = np.zeros((nx, nx))
    info[:3, :3] = np.linalg.inv(P0[:3, :3])
    info[3:, 3:] = np.eye(nx - 3)
    mean = np.zeros((obs.runs, nx))
    mean[:, :3] = x0[:3] - x_lin[:, :3]
    ne.add_prior(information=info, mean=mean)
    sol = (ne.eliminate(3) if nx > 3 else ne).solve()
    return x_lin[:, :3] + sol.theta, sol.covariance


@pytest.mark.parametrize("sigma0_arcsec", [10.0, 600.0])
@pytest.mark.parametrize("mode", [None, "both"])
def test_zero_process_noise_filter_equals_batch_gls(sigma0_arcsec, mode):
    """Same prior, same per-image covariances, same linearisation point → the same θ and P_θ (1e-9)."""
    _, model, obs = _case(sigma0_arcsec, mode, runs=50, seed=6)
    theta_lin = obs.truth["theta_rad"] + 2.0 * ARCSEC  # a fixed point near, not at, the truth
    res = kalman_filter(
        obs, model, sigma0_rad=sigma0_arcsec * ARCSEC, linearization="pass", iterations=1, theta_lin_rad=theta_lin
    )
    x_lin = np.concatenate([theta_lin, np.zeros((obs.runs, res.x.shape[1] - 3))], axis=1)
    theta, P = _gls_normal_equations(obs, model, res.states, sigma0_arcsec * ARCSEC, x_lin)
    assert _rel(res.theta_rad, theta) < 1e-9
    assert _rel(res.P_theta, P) < 1e-9
    # and the estimate moved: the test compares a real update, not the linearisation point
    assert np.abs(res.theta_rad - theta_lin).max() > 1.0 * ARCSEC


def test_joseph_update_equals_the_information_form():
    rng = np.random.default_rng(7)
    A = rng.normal(size=(5, 4, 4))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    H = rng.normal(size=(5, 6, 4))
    B = rng.normal(size=(5, 6, 6))
    R = B @ np.swapaxes(B, -1, -2) + np.eye(6)
    y = rng.normal(size=(5, 6))
    x, P_post, *_ = joseph_update(np.zeros((5, 4)), P, H, y, R)
    info = np.linalg.inv(P) + np.swapaxes(H, -1, -2) @ np.linalg.solve(R, H)
    np.testing.assert_allclose(P_post, np.linalg.inv(info), rtol=1e-10, atol=1e-12)
    x_info = np.linalg.solve(info, np.swapaxes(H, -1, -2) @ np.linalg.solve(R, y[..., None]))[..., 0]
    np.testing.assert_allclose(x, x_info, rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------------------- gating


def test_gating_rejects_an_outlier_image_and_keeps_the_clean_ones():
    """A 1e-4 m (33 σK, ≈ 9″) error on one landmark of image 10 — a misidentified landmark."""
    p_gate = 0.999
    _, model, obs = _case(runs=200, seed=8)
    grid = dense_grid(obs)  # the images × landmarks grid (tests/oracles.py)
    xy = grid.xy_m.copy()
    xy[:, 10, 2, 0] += 1e-4
    bad = replace(grid, xy_m=xy).to_rows()
    res = kalman_filter(bad, model, gate_probability=p_gate)
    assert res.rejected[:, 10].all()
    clean = np.delete(res.rejected, 10, axis=1)
    assert clean.sum() <= binom.ppf(0.9999, clean.size, 1 - p_gate), clean.sum()
    # on runs without a false rejection the gated filter is the filter that never saw image 10
    ok = ~clean.any(axis=1)
    assert ok.sum() > obs.runs // 2
    keep = np.delete(np.arange(obs.n_images), 10)
    without = kalman_filter(obs.images(keep), model)
    assert _rel(res.theta_rad[ok], without.theta_rad[ok]) < 1e-12
    # without the gate the outlier pulls θ by far more than that
    ungated = kalman_filter(bad, model)
    assert np.abs(ungated.theta_rad - without.theta_rad).max() / ARCSEC > 0.1


# ---------------------------------------------------------------------------- table, registry


def test_kalman_table_columns_and_the_one_image_row_matches_the_seminars_sensitivity_case():
    """With the 10′ prior, one image at nadir is the seminar's eq 28 case: σθ = 6.09, 6.09, 8.36″."""
    runs = 400
    t = kalman_table(runs=runs, seed=9, sigma0_arcsec=600.0, n_images=(1, 4, 20))
    assert [int(n) for n in t["n_images"]] == [1, 4, 20]
    assert t["sigma_theta_x"].unit == "arcsec" and t.meta["runs"] == runs and t.meta["seed"] == 9
    se = 1.0 / np.sqrt(2 * (runs - 1))
    for ax, seminar in zip("xyz", (6.09, 6.09, 8.36)):
        assert abs(t[f"sigma_theta_{ax}"][0] / seminar - 1) < 3 * se, (ax, t[f"sigma_theta_{ax}"][0])
        assert t[f"max_abs_theta_{ax}"][0] > t[f"sigma_theta_{ax}"][0]
    assert np.all((t["nees_lo"] < t["nees_mean"]) & (t["nees_mean"] < t["nees_hi"]))
    sem = seminar_kalman_table()
    assert [int(n) for n in sem["n_images"]] == [1, 2, 4, 8, 12, 20] and float(sem["sigma_theta_x"][2]) == 1.7


def test_registered_with_boresight_estimate():
    sc, model, obs = _case(runs=2, seed=10)
    est = boresight.estimate(obs, algorithm="kalman", weighting="gls", model=model, prior_sigma_arcsec=600.0)
    res = kalman_filter(obs, model, sigma0_rad=600.0 * ARCSEC)
    np.testing.assert_allclose(est.theta.to_value("arcsec"), res.theta_rad / ARCSEC, rtol=0, atol=1e-12)
    assert est.algorithm == "kalman" and est.covariance.shape == (2, 3, 3) and est.converged.all()
    assert est.algorithm_result.states == default_states(model)
    with pytest.raises(ValueError, match="weighting must be 'gls', got 'unit'"):
        boresight.estimate(obs, algorithm="kalman", weighting="unit", model=model)
    # the default weighting of the Kalman filter is its full noise model
    default = boresight.estimate(obs, algorithm="kalman", model=model, prior_sigma_arcsec=600.0)
    assert default.weighting == "gls"
    np.testing.assert_array_equal(default.theta.to_value("arcsec"), est.theta.to_value("arcsec"))
    with pytest.raises(ValueError, match="needs model=DisturbanceModel"):
        boresight.estimate(replace(obs, noise=None), algorithm="kalman", weighting="gls")
    # with no model= the filter uses the noise model the observations carry (issue 11)
    carried = boresight.estimate(obs, algorithm="kalman", prior_sigma_arcsec=600.0)
    mine = boresight.estimate(obs, algorithm="kalman", model=DisturbanceModel.from_observations(obs), prior_sigma_arcsec=600.0)
    np.testing.assert_array_equal(carried.theta.value, mine.theta.value)


# ---------------------------------------------------------------------------- bad input


def test_bad_input_raises_value_errors_naming_the_field():
    sc, model, obs = _case(runs=2, seed=11)
    with pytest.raises(ValueError, match="states must start with 'theta', got \\('catalogue',\\)"):
        kalman_filter(obs, model, states=("catalogue",))
    with pytest.raises(ValueError, match="unknown block 'drift'"):
        kalman_filter(obs, model, states=("theta", "drift"))
    with pytest.raises(ValueError, match="star_tracker_mode is 'per_image'"):
        kalman_filter(obs, model, states=("theta", "star_tracker_bias"))
    with pytest.raises(ValueError, match="iterations must be an integer ≥ 1, got 0"):
        kalman_filter(obs, model, iterations=0)
    with pytest.raises(ValueError, match="gate_probability must be in \\(0, 1\\) or None, got 1.0"):
        kalman_filter(obs, model, gate_probability=1.0)
    with pytest.raises(ValueError, match="linearization must be one of"):
        kalman_filter(obs, model, linearization="smoother")
    with pytest.raises(ValueError, match="sigma0_rad must be finite and > 0"):
        kalman_filter(obs, model, sigma0_rad=-1.0)
    with pytest.raises(ValueError, match="sigma_drift_rad_per_sqrt_s must be finite and ≥ 0"):
        kalman_filter(obs, model, sigma_drift_rad_per_sqrt_s=-1e-9)
    with pytest.raises(ValueError, match="obs.runs must be 1"):
        kalman_filter_filterpy(obs, model)
    with pytest.raises(ValueError, match="unknown option\\(s\\) \\['gate'\\]"):
        kalman_filter_filterpy(obs.run(0), model, gate=0.99)
    with pytest.raises(ValueError, match="n_images must lie in 1..20"):
        kalman_table(runs=2, n_images=(1, 21))
    with pytest.raises(ValueError, match="S = H P Hᵀ \\+ R is singular"):
        kalman_filter(obs, DisturbanceModel(), states=("theta",))


# ---------------------------------------------------------------------------- the χ² verdict (issue 31, class 1)


def test_kalman_carries_the_noise_model_chi2_verdict_and_its_warning():
    """The filter's Σ NIS over the accepted images is the noise-model χ² of the whole pass: for a
    linear-Gaussian model with the prior as 3 pseudo-observations, Σ NIS equals the minimised batch
    GLS objective with the prior, χ²(Σ m_n) (m_n = 2 × landmarks of image n), so ``estimate``
    must check it against the same band (``stats.chi2_band`` at ``CHI2_LEVEL``) and warn as the
    least-squares algorithms do. Before issue 31 every Kalman run printed "no noise model … no
    expected range", and a file with 8 of its 80 points moved 50 px gave χ² = 4.5e4 / 160, exit 0,
    no warning.

    False alarms: 200 clean runs at CHI2_LEVEL = 0.999 give ≤ binom.ppf(0.9999, 200, 0.001) = 3
    outside the band when the dof are right (an off-by-half dof would flag every run); the mean of
    the 200 χ²/dof is within 4 standard errors of 1."""
    from boresight.stats import CHI2_LEVEL

    sc, model, obs = _case(sigma0_arcsec=600.0, runs=200, seed=31)
    est = boresight.estimate(obs, algorithm="kalman", model=model)
    c2m, dofm = np.asarray(est.chi2_model), np.asarray(est.dof_model)
    assert np.all(dofm == 2 * obs.n_observations), dofm
    # mean of 200 χ²(160)/160: standard error √(2/160)/√200 = 0.0079; 4 of them
    assert abs(np.mean(c2m / dofm) - 1) < 4 * np.sqrt(2 / 160) / np.sqrt(obs.runs), np.mean(c2m / dofm)
    alarms = sum(1 for w in est.warnings if "noise model does not describe" in w)
    assert alarms <= binom.ppf(0.9999, obs.runs, 1 - CHI2_LEVEL), alarms
    clean = boresight.estimate(obs.run(0), algorithm="kalman", model=model)
    assert "under the noise model" in clean.chi2_text() and "no noise model" not in clean.chi2_text()
    assert "noise model" in clean.sigma_includes and "GLS" in clean.sigma_includes

    # 10 % of the points moved 50 px (pixel pitch of the scenario's camera): outside the band, warned
    single = dense_grid(boresight.simulate(sc, np.random.default_rng(np.random.SeedSequence(32)), runs=1))  # tests/oracles.py
    pitch = sc.camera.pixel_pitch_m or 5e-6
    xy = single.xy_m.copy()
    rng = np.random.default_rng(33)
    nn, mm = np.nonzero(single.mask)
    pick = rng.choice(nn.size, size=nn.size // 10, replace=False)
    xy[0, nn[pick], mm[pick], 0] += 50 * pitch
    bad = replace(single, xy_m=xy).to_rows()
    k = boresight.estimate(bad, algorithm="kalman", model=model)
    ls = boresight.estimate(bad, model=model)
    assert "OUTSIDE" in k.chi2_text() and "OUTSIDE" in ls.chi2_text()
    assert any("noise model does not describe" in w for w in k.warnings), k.warnings
