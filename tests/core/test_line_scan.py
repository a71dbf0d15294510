"""Pushbroom rows (boresight.core.line_scan, boresight.observations.strip): a strip's detections as rows on the
attitude-sample table, the line's measurement model and θ estimated with the one GLS.

Noise-free recovery (issue 29's must-show): θ to 1e-6″ jointly with a 2 ms line-time offset, a focal scale and one
chip's look-angle offsets. The floor is inverse location's tolerance (1e-8 line ≈ 4e-14 rad per detection, measured
θ errors ~3e-8″); 1e-6″ leaves a factor 30. Every other tolerance is the same floor carried to its unknown
(δt: the pitch it trades with, 1e-6″ / (v/H ≈ 0.014 rad/s) ≈ 3e-10 s; κ, chip offsets: 1e-6″ ≈ 5e-12 rad).
"""

import numpy as np
import pytest

from boresight.core.disturbances import DisturbanceModel
from boresight.core.line_scan import LineScanUnknowns, estimate_line_scan, line_scan_residuals
from boresight.observations.strip import strip_observations
from orbits.pushbroom import LineScanParameters
from orbits.strip import GcpLayout, StripConfig, simulate_strip, strip_geometry, zy3_like_sensor

ARCSEC = np.pi / 180 / 3600
TRUTH = LineScanParameters(
    theta_rad=np.array([20.0, -35.0, 50.0]) * ARCSEC,
    line_time_offset_s=2e-3,
    focal_scale=3e-5,
    chip_offsets_rad=np.array([[0.0, 0.0], [1e-5, -2e-5], [0.0, 0.0]]),
)
UNKNOWNS = LineScanUnknowns(line_time_offset=True, focal_scale=True, chip_offsets=((1, 0), (1, 1)))


@pytest.fixture(scope="module")
def geometry():
    return strip_geometry(StripConfig(zy3_like_sensor(), roll_deg=20.0, tracker_mount_rotvec_deg=(10.0, -5.0, 3.0)))


def test_a_strip_is_rows_on_the_attitude_sample_table(geometry):
    """One image per detection at its measured line's time, in time order; the tracker's samples are the sample
    table (each line between its two bracketing samples); the residual of every row is 0 at the truth (to the inverse
    location's floor) and not at θ = 0."""
    sim = simulate_strip(geometry, TRUTH, np.random.default_rng(1), GcpLayout(n_gcps=120))
    obs = strip_observations(sim)
    assert obs.n_images == obs.n_observations == sim.line_measured.size and obs.has_samples
    assert np.all(np.diff(obs.t_s) >= 0) and obs.n_samples == geometry.trajectory.tracker_t_s.size
    t = obs.sample_t_s
    lo, hi = t[obs.sample_index[:, 0]], t[obs.sample_index[:, 1]]
    assert np.all((lo <= obs.t_s) & (obs.t_s <= hi)) and np.all(obs.sample_index[:, 1] == obs.sample_index[:, 0] + 1)
    x_true = np.r_[TRUTH.theta_rad, 2e-3, 3e-5, 1e-5, -2e-5]
    F = obs.focal_length_m
    r_true = line_scan_residuals(obs, x_true, UNKNOWNS)
    assert np.abs(r_true).max() < 1e-7 * 7e-6  # 1e-7 px
    assert np.abs(line_scan_residuals(obs, np.zeros(7), UNKNOWNS)).max() > 10 * 7e-6 and F == 1.7


@pytest.mark.parametrize("tracker_sigma_arcsec", [0.0, 2.0])
def test_noise_free_recovery_with_timing_focal_scale_and_a_chip(geometry, tracker_sigma_arcsec):
    """θ to 1e-6″ with δt = 2 ms, κ = 3e-5 and chip 1's (along, across) offsets estimated jointly, with the pixel
    noise alone and with a 2″ star-tracker error per sample in the noise model (the GLS on the sample table)."""
    sim = simulate_strip(geometry, TRUTH, np.random.default_rng(2), GcpLayout(n_gcps=200))
    obs = strip_observations(sim)
    model = DisturbanceModel(
        sigma_pixel_m=7e-6,
        sigma_star_tracker_rad=(tracker_sigma_arcsec * ARCSEC,) * 3,
        star_tracker_mode="per_image",
        sigma_gnss_m=5.0,
        gnss_mode="per_pass",
        sigma_catalogue_m=1.0,
    )
    fit = estimate_line_scan(obs, UNKNOWNS, model)
    assert np.abs(fit.x[:3] - TRUTH.theta_rad).max() / ARCSEC < 1e-6
    assert abs(fit.x[3] - 2e-3) < 3e-10 and abs(fit.x[4] - 3e-5) < 5e-12
    assert np.abs(fit.x[5:] - [1e-5, -2e-5]).max() < 5e-12
    assert fit.iterations <= 4 and fit.chi2 < 1e-6 and fit.names[3] == "line_time_offset_s"
    assert fit.fit.structure.has_samples and np.all(np.isfinite(fit.sigma))


def test_boresight_estimate_takes_pushbroom_strips_through_the_registry(geometry):
    """``boresight.estimate`` on lines (one strip, or a list: a campaign) dispatches to the registry row ``line_scan``
    (``estimate_lines``): θ, σ and the floated unknowns are ``estimate_line_scan``'s exactly (the same call), the noise
    model is the set's own (``gls`` by default), residuals are one per row; a frame algorithm on lines and the line
    model on a frame set are refused, and so is a fit without a noise model."""
    from boresight import estimate
    from boresight.core.registry import lookup
    from boresight.errors import InputValueError

    noise = {"pixel": {"sigma_m": 0.3 * 7e-6}, "star_tracker": {"sigma_arcsec": [0.3] * 3, "error_mode": "per_image"}}
    sims = [simulate_strip(geometry, TRUTH, np.random.default_rng(k), GcpLayout(n_gcps=80), sigma_pixel=0.3) for k in (1, 2)]
    strips = [strip_observations(s, noise) for s in sims]
    model = DisturbanceModel.from_observations(strips[0])
    ref = estimate_line_scan(strips, UNKNOWNS, model)
    est = estimate(strips, unknowns=UNKNOWNS)
    assert est.algorithm == "line_scan" and est.weighting == "gls" and lookup("pushbroom").name == "line_scan"
    assert np.array_equal(est.theta.to_value("arcsec"), ref.theta_arcsec)
    assert np.allclose(est.sigma.to_value("arcsec"), ref.sigma[:3] / ARCSEC, rtol=1e-12, atol=0)
    assert est.residuals.shape == (sum(o.n_observations for o in strips), 2) and est.dof == ref.dof
    dt, sdt = est.effects["line_time_offset"]  # the quantity; its unit is the Quantity's (as the frame's effects)
    assert dt.to_value("s") == ref.x[3] and np.isclose(sdt.to_value("s"), ref.sigma[3], rtol=1e-12)
    assert est.joint_labels[:4] == ("theta_x", "theta_y", "theta_z", "line_time_offset")
    assert est.joint_units[:4] == ("arcsec", "arcsec", "arcsec", "s")
    one = estimate(strips[0])
    assert np.array_equal(one.theta.to_value("arcsec"), estimate_line_scan(strips[0], model=model).theta_arcsec)
    with pytest.raises(InputValueError, match="estimated by 'line_scan'"):
        estimate(strips[0], algorithm="ground_plane")
    with pytest.raises(InputValueError, match="noise model"):
        estimate(strip_observations(sims[0]))
    from boresight import simulate

    frame = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
    with pytest.raises(InputValueError, match="not pushbroom lines"):
        estimate(frame, algorithm="line_scan")


@pytest.mark.parametrize("loss", ["huber", "cauchy", "tukey"])
def test_robust_losses_on_lines_down_weight_gross_detections(geometry, loss):
    """``estimate(strip, loss=…)`` on lines (``core.robust``'s losses through ``estimate_line_scan``): six of ~300
    detections moved by 20 lines (three also by 15 pixels) — 70-280 σ at 0.3 px — pull the least-squares θz by more
    than 5σ (measured: 14.7σ); each loss weights those six below 0.05 (measured ≤ 0.04, Huber's c/z) and every other row
    above 0.2 (measured ≥ 0.215, Tukey), and brings every axis of θ within 3σ of the truth (measured ≤ 1.2σ). On the
    clean strip the robust σ (the M-estimator sandwich) is within 5 % of the GLS σ (the losses' Gaussian efficiency:
    measured 1.00-1.03)."""
    from boresight import estimate

    truth = LineScanParameters(theta_rad=np.array([20.0, -35.0, 50.0]) * ARCSEC)
    noise = {"pixel": {"sigma_m": 0.3 * 7e-6}, "star_tracker": {"sigma_arcsec": [0.3] * 3, "error_mode": "per_image"}}
    from orbits.strip import TrackerNoise

    sim = simulate_strip(geometry, truth, np.random.default_rng(3), GcpLayout(n_gcps=150), TrackerNoise(0.3), sigma_pixel=0.3)
    clean = strip_observations(sim, noise)
    rng = np.random.default_rng(9)
    bad = rng.choice(sim.line_measured.size, 6, replace=False)
    sim.line_measured[bad] += rng.choice([-1, 1], 6) * 20.0
    sim.pixel_measured[bad[:3]] += 15.0
    dirty = strip_observations(sim, noise)
    z_ls = (estimate(dirty).theta.value - [20, -35, 50]) / estimate(dirty).sigma.value
    assert np.max(np.abs(z_ls)) > 5
    est = estimate(dirty, loss=loss)
    assert est.loss == loss and est.converged and est.robust_weights is not None
    assert np.all(np.abs(est.theta.value - [20, -35, 50]) <= 3 * est.sigma.value)
    rows_bad = np.isin(np.arange(dirty.n_observations), _rows_of(dirty, sim, bad))
    assert rows_bad.sum() == 6
    assert np.all(est.robust_weights[rows_bad] < 0.05) and np.all(est.robust_weights[~rows_bad] > 0.2)
    ratio = estimate(clean, loss=loss).sigma.value / estimate(clean).sigma.value
    assert np.all((ratio >= 0.99) & (ratio <= 1.05)), ratio


def _rows_of(obs, sim, detections):
    """The rows of ``obs`` holding the simulated ``detections`` (matched by their measured line: continuous draws, so
    each is one row's)."""
    lines = np.asarray(obs.line_scan.line)[obs.image_index]
    return np.array([int(np.flatnonzero(np.abs(lines - sim.line_measured[d]) < 1e-9)[0]) for d in detections])
