"""orbits.simulate_passes and boresight.simulate: batches equal single runs, the noise is what the scenario says, the model is exact."""

import warnings
from dataclasses import replace

import numpy as np
import pytest
from oracles import dense_grid
from scipy import stats

import boresight
import orbits
from orbits.camera import project
from orbits.rotations import ARCSEC, misalignment_dcm

SENS = "scenarios/kiev2012-sensitivity.toml"
ALG1 = "scenarios/kiev2012-algorithm1.toml"


def test_a_batch_equals_the_same_runs_one_at_a_time():
    sc = orbits.load_scenario(SENS)
    arrays = orbits.campaign_arrays(sc)
    errors = orbits.draw_scenario_errors(sc, np.random.default_rng(4), 6, arrays)
    batch = orbits.observe(errors, **arrays)
    for k in range(6):
        one = orbits.observe({key: v[k : k + 1] for key, v in errors.items()}, **arrays)
        for f in ("q_is", "r_sc_i_m", "landmark_g_m", "xy_m"):
            assert np.array_equal(getattr(batch, f)[k : k + 1], getattr(one, f)), f


def test_same_seed_same_data_different_seed_different_data():
    a = boresight.simulate(SENS, np.random.default_rng(9), runs=3)
    b = boresight.simulate(SENS, np.random.default_rng(9), runs=3)
    c = boresight.simulate(SENS, np.random.default_rng(10), runs=3)
    assert np.array_equal(a.xy_m, b.xy_m)
    assert not np.array_equal(a.xy_m, c.xy_m)


def test_noise_free_images_are_the_exact_model_with_the_true_theta():
    obs = dense_grid(boresight.simulate(ALG1, np.random.default_rng(0), runs=2))  # the grid (tests/oracles.py)
    C = misalignment_dcm(obs.truth["theta_rad"])[:, None] @ obs.nominal_camera_attitude()
    s = np.einsum("rnij,rnmj->rnmi", C, obs.landmarks_i_m() - obs.r_sc_i_m[:, :, None])
    assert np.abs(project(s, obs.focal_length_m) - obs.xy_m).max() < 1e-15
    assert np.allclose(obs.truth["theta_rad"] / ARCSEC, [20.0, -15.0, 40.0])


def _chi2_interval(sample_var, n, true_var, p=0.999):
    lo, hi = stats.chi2.ppf([(1 - p) / 2, (1 + p) / 2], n - 1) / (n - 1)
    return lo * true_var <= sample_var <= hi * true_var


def test_error_draws_have_the_scenario_sigmas():
    """Each source's sample variance sits in its 99.9% χ² interval (a factor 2 in σ would not)."""
    sc = orbits.load_scenario(SENS)
    e = orbits.draw_scenario_errors(sc, np.random.default_rng(2024), 4000)
    checks = {
        "pixel": (e["pixel_noise_m"].ravel(), sc.sigma_pixel_m),
        "gnss": (e["gnss_error_m"].ravel(), sc.sigma_gnss_m),
        "catalogue": (e["catalogue_error_m"].ravel(), sc.sigma_catalogue_m),
        "star tracker": (e["delta_rad"].ravel(), 4 * ARCSEC),
        "theta": (e["theta_rad"].ravel(), 600 * ARCSEC),
    }
    for name, (x, sigma) in checks.items():
        assert _chi2_interval(np.var(x, ddof=1), x.size, sigma**2), name
        assert not _chi2_interval(np.var(x, ddof=1), x.size, (2 * sigma) ** 2), name


def test_per_pass_errors_are_shared_by_every_image_of_a_pass():
    sc = orbits.load_scenario(ALG1)
    sc = replace(
        sc,
        sigma_star_tracker_arcsec=(4.0, 4.0, 4.0),
        star_tracker_error_mode="per_pass",
        sigma_gnss_m=15.0,
        gnss_error_mode="both",
    )
    e = orbits.draw_scenario_errors(sc, np.random.default_rng(1), 2000)
    d = e["delta_rad"]
    assert np.array_equal(d, np.broadcast_to(d[:, :1], d.shape))
    g = e["gnss_error_m"]
    # "both": per-pass bias + per-image noise, each σ = 15 m: total var 2σ², image-to-image covariance σ²
    assert _chi2_interval(np.var(g[:, 0, 0], ddof=1), 2000, 2 * 15.0**2)
    cov = np.cov(g[:, 0, 0], g[:, 5, 0])[0, 1]
    assert cov == pytest.approx(15.0**2, abs=4 * 15.0**2 * np.sqrt(2 / 2000) * 1.5)


def test_campaign_of_two_passes_draws_one_bias_per_pass():
    sc = orbits.load_scenario(ALG1)
    p2 = replace(sc.passes[0], site_lat_deg=-20.0, site_lon_deg=140.0, direction="descending")
    sc = replace(sc, passes=(sc.passes[0], p2), sigma_star_tracker_arcsec=(4.0, 4.0, 4.0), star_tracker_error_mode="per_pass")
    obs = boresight.simulate(sc, np.random.default_rng(3), runs=5)
    assert obs.n_images == 20 and obs.n_landmarks == 8
    d = obs.truth["delta_rad"]
    assert np.array_equal(d[:, :10], np.broadcast_to(d[:, :1], (5, 10, 3)))
    assert np.array_equal(d[:, 10:], np.broadcast_to(d[:, 10:11], (5, 10, 3)))
    assert not np.allclose(d[:, 0], d[:, 10])
    # each image sees only its own pass's landmarks
    seen = dense_grid(obs).mask
    assert not seen[:10, 4:].any() and not seen[10:, :4].any()
    assert obs.t_s[10] == pytest.approx(86400.0 + 5.0)


def test_visibility_mask_drops_landmarks_outside_the_field():
    sc = orbits.load_scenario(ALG1)
    narrow = replace(sc, camera=orbits.Camera(1.0, 12.0))
    obs = boresight.simulate(narrow, np.random.default_rng(0))
    # at 400 km the ±50 km landmarks are ±7.1° off the boresight: outside a 12° field
    assert obs.n_observations < obs.n_images * obs.n_targets
    assert np.all(np.abs(obs.xy_m[0]) <= 1.0 * np.tan(np.radians(6.0)))


def test_a_batch_that_drops_rows_for_one_runs_sake_says_so():
    """boresight.simulate keeps only the rows on the detector in every run of a batch (the rows are shared
    by the runs). With seed 5, the second 5 000-run batch of kiev2012-sensitivity has three landmarks that
    leave the detector in some run: they are dropped from all 5 000, and a UserWarning says how many and
    why. A single run (the detector edge of one image, nothing coupled) and an unaffected batch say nothing."""
    rng = np.random.default_rng(5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        first = boresight.simulate(SENS, rng, runs=5000)  # every landmark on the detector in every run
        boresight.simulate(SENS, np.random.default_rng(5), runs=1)
    assert first.n_observations == 4
    with pytest.warns(UserWarning, match=r"3 of 4 observations land beyond the detector .* 5000 runs .* dropped from every run"):
        second = boresight.simulate(SENS, rng, runs=5000)
    assert second.n_observations == 1


def test_the_old_name_orbits_simulate_warns_and_is_the_passes_simulator():
    """``orbits.simulate`` was a second ``simulate`` beside ``boresight.simulate`` (another return type);
    renamed ``simulate_passes``, the old name still resolves for one release and warns on every use."""
    for _ in range(2):
        with pytest.warns(DeprecationWarning, match=r"orbits\.simulate is deprecated, use orbits\.simulate_passes"):
            old = orbits.simulate
        assert old is orbits.simulate_passes
    assert "simulate" not in orbits.__all__ and "simulate_passes" in orbits.__all__
