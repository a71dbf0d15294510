"""orbits.strip: the strip simulator (issue 29) — GCPs inside the swath, detections by inverse location with the
hidden effects, star-tracker errors per sample — and the forward model's smoothness in each parameter."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from orbits.pushbroom import LineScanParameters, geodetic_from_itrs, locate_on_chips
from orbits.rotations import ARCSEC, dcm_from_quat
from orbits.strip import (
    GcpLayout,
    StripConfig,
    TrackerNoise,
    simulate_campaign,
    simulate_strip,
    strip_geometry,
    zy3_like_sensor,
)

SENSOR = zy3_like_sensor()
LAYOUT = GcpLayout(n_gcps=60)


@pytest.fixture(scope="module")
def geo():
    return strip_geometry(StripConfig(SENSOR, roll_deg=20.0))


def _rows_on_drawn_chip(sim, line0, pixel0):
    """The detection of each GCP on the chip its drawn pixel belongs to."""
    chip0, _ = SENSOR.chip_of(pixel0)
    rows = [np.flatnonzero((sim.detection_gcp == k) & (sim.detection_chip == chip0[k]))[0] for k in range(line0.size)]
    return np.array(rows)


#: the seven unknowns of the identifiability checks: θ = (20, −30, 40)″, a 2 ms line-time offset, a 1e-4 focal
#: scale and chip 1's look-angle offsets (4, −3) µrad
SEVEN_TRUTH = np.array([20 * ARCSEC, -30 * ARCSEC, 40 * ARCSEC, 2e-3, 1e-4, 4e-6, -3e-6])
#: their central-difference steps
SEVEN_STEPS = np.array([1e-6, 1e-6, 1e-6, 1e-4, 1e-5, 1e-6, 1e-6])


def _seven(x):
    """``LineScanParameters`` of the seven unknowns ``x`` (``SEVEN_TRUTH``'s order)."""
    off = np.zeros((3, 2))
    off[1] = x[5:7]
    return LineScanParameters(theta_rad=x[:3], line_time_offset_s=x[3], focal_scale=x[4], chip_offsets_rad=off)


def _located(geo, sim, x):
    """The (line, pixel) of every detection of ``sim`` under the seven unknowns ``x``, concatenated."""
    ground = sim.gcp_g_m[sim.detection_gcp]
    line, pixel = locate_on_chips(SENSOR, geo.datation, geo.trajectory, ground, sim.detection_chip, _seven(x))
    return np.concatenate([line, pixel])


def _jacobian(geo, sim, x, steps=SEVEN_STEPS):
    """The central-difference Jacobian of ``_located`` at ``x``."""
    columns = [
        (_located(geo, sim, x + s * e) - _located(geo, sim, x - s * e)) / (2 * s)
        for e, s in zip(np.eye(x.size), steps, strict=True)
    ]
    return np.stack(columns, 1)


def _drawn(seed, n):
    rng = np.random.default_rng(seed)
    return rng.uniform(200, 9799, n), rng.uniform(200, SENSOR.n_pixels - 201, n)


@pytest.mark.parametrize("roll", [-30.0, 30.0, -45.0])
def test_a_rolled_strip_images_its_site_at_its_centre(roll):
    """``StripConfig``'s site is seen by the centre chip near the strip's centre line and the boresight's column, at
    ±30° and −45° roll. The offsets allowed: along-track, the centre chip sits 40 px ahead of the line (≈ 40 lines;
    measured 38.5), aberration ≈ 13-15 m ≈ 7 lines and light time < 1 m: 60 lines; across-track, the boresight
    (tan ψy = 0) is column 12 287.5 on chip 1 (the columns count the overlaps twice), and aberration and the Earth's
    turn move the site by ~2 px (measured 2.1): 10 px. Before the nadir point was iterated (``_nadir_point``) the
    site was 11.5 km along-track from the centre at ±30° (crossing line −225 to −289, outside the strip), as the
    first-order nadir point is off by ~γ² (γ = 2.7° at 30°), and a roll toward the wrong side would miss it by
    2γ across-track."""
    from orbits.pushbroom import inverse_location

    g = strip_geometry(StripConfig(SENSOR, roll_deg=roll))
    line, pixel, chip = inverse_location(SENSOR, g.datation, g.trajectory, g.site_g_m[None], g.line_range).primary()
    assert chip[0] == 1
    assert abs(line[0] - (g.config.n_lines - 1) / 2) < 60.0
    a0, a1, _ = SENSOR.chips[1].tan_psi_y
    boresight_column = SENSOR.first_pixel(1) - a0 / a1  # tan ψy = 0 on chip 1 (its 1e-13 j² term moves it 4e-5 px)
    assert boresight_column == pytest.approx(12_287.5)
    assert abs(pixel[0] - boresight_column) < 10.0


def test_the_nominal_camera_is_the_body_whatever_the_tracker_mount():
    """The world's chain (``docs/architecture.md``): the tracker reports A = C_ES C_IE and the nominal camera is
    C_SK,nom A = C_ESᵀ C_ES C_IE = C_IE, the body (the rolled orbital frame), whatever the mount. With a mount of (10°,
    −5°, 3°) and no effect, ``camera_attitude`` equals the body's attitude law axis_dcm(0, roll) C_IO(t) at the
    tracker's samples and half-way between them (the orbital frame turns uniformly, so its SLERP is exact): measured
    5e-16 rad; the test allows 1e-12. A mount transposed in the world or in the model, or the tracker's matrix taken
    from its quaternion untransposed, turns the camera by up to twice the mount (~20°)."""
    from orbits.attitude import nadir
    from orbits.pushbroom import camera_attitude
    from orbits.rotations import axis_dcm

    g = strip_geometry(StripConfig(SENSOR, roll_deg=20.0, n_lines=2000, tracker_mount_rotvec_deg=(10.0, -5.0, 3.0)))
    tk = g.trajectory.tracker_t_s
    t = np.concatenate([tk[2:-2], 0.5 * (tk[2:-3] + tk[3:-2])])
    r, v = g.orbit.state(g.u0_rad + g.orbit.mean_motion_rad_s * t)
    body = np.einsum("ij,njk->nik", axis_dcm(0, np.radians(20.0)), nadir(r, v))
    camera = camera_attitude(g.trajectory, t, LineScanParameters())
    turn = Rotation.from_matrix(np.einsum("nij,nkj->nik", camera, body)).magnitude()
    assert np.max(turn) < 1e-12
    np.testing.assert_allclose(camera[: tk.size - 4], g.C_IE[2:-2], rtol=0, atol=1e-12)


def test_without_effects_the_detections_are_the_drawn_image_points(geo):
    """Placement (direct location, nominal model) and detection (inverse location, true model = nominal) invert each
    other: ≤ 1e-6 line and pixel; heights as drawn; same seed, same strip."""
    sim = simulate_strip(geo, LineScanParameters(), np.random.default_rng(11), LAYOUT)
    line0, pixel0 = _drawn(11, LAYOUT.n_gcps)
    rows = _rows_on_drawn_chip(sim, line0, pixel0)
    assert np.max(np.abs(sim.line_true[rows] - line0)) < 1e-6
    assert np.max(np.abs(sim.pixel_true[rows] - pixel0)) < 1e-6
    _, _, h = geodetic_from_itrs(sim.gcp_g_m)
    np.testing.assert_allclose(h, sim.gcp_height_m, rtol=0, atol=1e-5)
    assert 300 <= h.min() and h.max() <= 3000
    again = simulate_strip(geo, LineScanParameters(), np.random.default_rng(11), LAYOUT)
    np.testing.assert_array_equal(again.line_measured, sim.line_measured)


def test_line_time_offset_and_chip_offset_move_the_detections_as_derived(geo):
    """A line-time offset δt images every point δt/T lines earlier (exactly: t(L′) = t_nom(L′) + δt = t*); an
    across-track offset δψy of chip 1 moves its points by −δψy / (d tan ψy/dj) pixels and no other chip's (to first
    order: the measured departure is ≤ 1.2e-5 px for a 1 px offset — the chip's along-track slope, 1e-9 per pixel,
    moves the line by 2e-4 and the Earth's crab turns that into ~1e-5 px)."""
    T = geo.config.line_period_s
    line0, pixel0 = _drawn(12, LAYOUT.n_gcps)
    sim = simulate_strip(geo, LineScanParameters(line_time_offset_s=2e-3), np.random.default_rng(12), LAYOUT)
    rows = _rows_on_drawn_chip(sim, line0, pixel0)
    np.testing.assert_allclose(sim.line_true[rows] - line0, -2e-3 / T, rtol=0, atol=1e-6)
    off = np.zeros((3, 2))
    off[1, 1] = SENSOR.chips[1].tan_psi_derivative(0.0)[1]  # one pixel
    sim = simulate_strip(geo, LineScanParameters(chip_offsets_rad=off), np.random.default_rng(12), LAYOUT)
    rows = _rows_on_drawn_chip(sim, line0, pixel0)
    chip0, j0 = SENSOR.chip_of(pixel0)
    on1 = chip0 == 1
    expect = -off[1, 1] / SENSOR.chips[1].tan_psi_derivative(j0[on1])[:, 1]
    np.testing.assert_allclose(sim.pixel_true[rows][on1] - pixel0[on1], expect, rtol=0, atol=1e-4)
    np.testing.assert_allclose(sim.pixel_true[rows][~on1], pixel0[~on1], rtol=0, atol=1e-6)


def test_jitter_moves_the_detections_by_its_amplitude_at_its_frequency(geo):
    """A 0.65 Hz roll jitter (about x_K, along-track) of one IFOV, p/F, moves the detections across-track by the
    sinusoid at the line's time, ≈ −1 px × sin(2π f t + φ) (first order: measured slope −1.0004, departure from it
    ≤ 0.0012 px — the IFOV changes across the 20° off-nadir field; the test allows 5 % and 0.05 px)."""
    ifov = SENSOR.chips[0].tan_psi_derivative(0.0)[1]
    jit = LineScanParameters(jitter_frequency_hz=[0.65], jitter_amplitude_rad=[[ifov, 0, 0]], jitter_phase_rad=[[0.3, 0, 0]])
    line0, pixel0 = _drawn(13, LAYOUT.n_gcps)
    sim = simulate_strip(geo, jit, np.random.default_rng(13), LAYOUT)
    rows = _rows_on_drawn_chip(sim, line0, pixel0)
    t = geo.datation.time_s(line0)
    dpix = sim.pixel_true[rows] - pixel0
    amp = np.sin(2 * np.pi * 0.65 * t + 0.3)
    slope = np.sum(dpix * amp) / np.sum(amp * amp)
    assert abs(abs(slope) - 1.0) < 0.05
    assert np.max(np.abs(dpix - slope * amp)) < 0.05


def test_tracker_noise_white_and_gauss_markov_statistics():
    """20 000 samples at 4 Hz, seed 29: the white σ (2″) is recovered within 5 σ of the sample standard deviation
    (its relative σ is 1/√(2n) = 0.5 %: 2.5 %); the Gauss–Markov process (σ_c = 3″, τ = 2 s) has variance σ_c² and
    lag-1 correlation φ = exp(−0.25/2) = 0.8825 (its σ ≈ √((1 − φ²)/n) = 0.0033 for the AR(1) estimate: 5 σ = 0.017)."""
    t = np.arange(20_000) / 4.0
    d = TrackerNoise(sigma_white_arcsec=2.0).draw_rad(np.random.default_rng(29), t) / ARCSEC
    assert np.all(np.abs(d.std(axis=0) / 2.0 - 1.0) < 0.025)
    x = TrackerNoise(sigma_correlated_arcsec=3.0, correlation_time_s=2.0).draw_rad(np.random.default_rng(29), t) / ARCSEC
    sigma_rel = np.sqrt(1 / 20_000 * (1 + 0.8825**2) / (1 - 0.8825**2))  # the σ of a sample variance of AR(1) data
    assert np.all(np.abs(x.std(axis=0) / 3.0 - 1.0) < 5 * sigma_rel)
    lag1 = np.array([np.corrcoef(x[:-1, a], x[1:, a])[0, 1] for a in range(3)])
    assert np.all(np.abs(lag1 - np.exp(-0.125)) < 0.017)


def test_the_tracker_reports_carry_its_errors(geo):
    """A_meas = exp(Φ(δ)) A at every sample (the Kiev 2012 δ), and the pixel noise has its σ."""
    sim = simulate_strip(geo, LineScanParameters(), np.random.default_rng(14), LAYOUT, TrackerNoise(2.0), sigma_pixel=0.3)
    A = dcm_from_quat(geo.trajectory.tracker_quat)
    A_meas = dcm_from_quat(sim.trajectory_measured.tracker_quat)
    delta = Rotation.from_matrix(np.einsum("nij,nkj->nik", A_meas, A)).as_rotvec()  # A_meas Aᵀ = exp(Φ(δ))
    np.testing.assert_allclose(delta, sim.tracker_delta_rad, rtol=0, atol=1e-15)
    resid = np.concatenate([sim.line_measured - sim.line_true, sim.pixel_measured - sim.pixel_true])
    assert 0.2 < resid.std() < 0.4


def test_pixel_noise_is_independent_on_line_and_pixel(geo):
    """The simulator's pixel noise is isotropic and independent: σ_pixel = 0.5 px on each axis, seed 21, 400 GCPs
    (n = 406 detections; measured σ 0.473, 0.508 px, correlation −0.04). Each axis's sample σ is within 5/√(2n) ≈ 0.17 (relative) of 0.5 and the line-pixel
    correlation within 5/√n ≈ 0.24 of 0 (5σ of their sampling errors); the same draw on both axes gives 1."""
    sim = simulate_strip(geo, LineScanParameters(), np.random.default_rng(21), GcpLayout(n_gcps=400), sigma_pixel=0.5)
    d = np.stack([sim.line_measured - sim.line_true, sim.pixel_measured - sim.pixel_true])
    n = d.shape[1]
    assert n >= 400
    assert np.all(np.abs(d.std(axis=1) / 0.5 - 1.0) < 5 / np.sqrt(2 * n))
    assert abs(np.corrcoef(d)[0, 1]) < 5 / np.sqrt(n)


@pytest.mark.parametrize(
    "name, step",
    [
        ("theta_rad", 1e-6),
        ("line_time_offset_s", 1e-4),
        ("line_period_error", 1e-5),
        ("focal_scale", 1e-5),
        ("chip_offsets_rad", 1e-6),
        ("jitter_amplitude_rad", 1e-6),
    ],
)
def test_the_forward_model_is_smooth_in_each_parameter(geo, name, step):
    """``locate_on_chips`` as an estimator will differentiate it: central differences with steps h and h/2 agree to
    1e-3 of the derivative (a kink, a rounding floor or a Newton stopping early would break this; measured ≤ 2e-8)."""
    sim = simulate_strip(geo, LineScanParameters(), np.random.default_rng(15), GcpLayout(n_gcps=20))
    base = dict(
        theta_rad=np.zeros(3),
        line_time_offset_s=0.0,
        line_period_error=0.0,
        focal_scale=0.0,
        chip_offsets_rad=np.zeros((3, 2)),
        jitter_frequency_hz=[0.65],
        jitter_amplitude_rad=np.zeros((1, 3)),
        jitter_phase_rad=np.full((1, 3), 0.4),
    )

    def model(h):
        p = dict(base)
        v = np.array(p[name], dtype=float)
        v.flat[0] += h
        p[name] = v if v.ndim else float(v)
        line, pixel = locate_on_chips(
            SENSOR, geo.datation, geo.trajectory, sim.gcp_g_m[sim.detection_gcp], sim.detection_chip, LineScanParameters(**p)
        )
        return np.concatenate([line, pixel])

    d1 = (model(step) - model(-step)) / (2 * step)
    d2 = (model(step / 2) - model(-step / 2)) / step
    scale = np.max(np.abs(d1))
    assert scale > 0
    assert np.max(np.abs(d1 - d2)) < 1e-3 * scale


def test_noise_free_strip_identifies_theta_with_timing_focal_scale_and_a_chip_offset(geo):
    """The forward model carries the information issue 29's must-show asks of the estimator: on a noise-free 20° roll
    strip (80 GCPs, 300-3000 m), θ = (20, −30, 40)″, a 2 ms line-time offset, a 1e-4 focal scale and chip 1's look-angle
    offsets (4, −3) µrad are recovered from the detections by Gauss–Newton on ``locate_on_chips`` with a
    central-difference Jacobian. NOT the estimator (that is built on the row model, issue 27): a numpy least-squares
    check that the parameters are identifiable. Measured (200 GCPs, rolls 0° and 20°): θ to ≤ 2e-8″, δt to 7e-12 s,
    κ to 4e-15, the offsets to 7e-16 rad after 3 iterations; the test allows 1e-6″, 1e-9 s, 1e-12, 1e-12 rad.

    It also pins the geometry's weak direction the planner will meet: pitch θy and the line-time offset move the
    image along-track alike (by range × θy and by v_ground × δt), separated only by the range's spread over the
    heights and the field — measured correlation 0.999998 (cond 1.4e3 of the column-scaled Jacobian)."""
    truth = SEVEN_TRUTH
    sim = simulate_strip(geo, _seven(truth), np.random.default_rng(5), GcpLayout(n_gcps=80))
    y = np.concatenate([sim.line_true, sim.pixel_true])
    x = np.zeros(7)
    for _ in range(3):
        r = y - _located(geo, sim, x)
        J = _jacobian(geo, sim, x)
        scale = np.linalg.norm(J, axis=0)
        x = x + np.linalg.lstsq(J / scale, r, rcond=None)[0] / scale
    err = x - truth
    assert np.all(np.abs(err[:3]) < 1e-6 * ARCSEC)
    assert abs(err[3]) < 1e-9 and abs(err[4]) < 1e-12 and np.all(np.abs(err[5:]) < 1e-12)
    cov = np.linalg.inv(J.T @ J)
    assert abs(cov[1, 3] / np.sqrt(cov[1, 1] * cov[3, 3])) > 0.999


def test_a_campaign_draws_each_strip_from_its_own_generator(geo):
    """Strip k draws from the k-th spawned generator: the first strip of a two-strip campaign is the one-strip
    campaign's, and the second differs from it."""
    small = GcpLayout(n_gcps=5)
    two = simulate_campaign([geo, geo], [LineScanParameters()] * 2, np.random.default_rng(8), small, TrackerNoise(1.0))
    one = simulate_campaign([geo], [LineScanParameters()], np.random.default_rng(8), small, TrackerNoise(1.0))
    np.testing.assert_array_equal(two[0].gcp_g_m, one[0].gcp_g_m)
    np.testing.assert_array_equal(two[0].tracker_delta_rad, one[0].tracker_delta_rad)
    assert not np.allclose(two[1].gcp_g_m, two[0].gcp_g_m)
    with pytest.raises(ValueError, match="one truth per strip"):
        simulate_campaign([geo], [], np.random.default_rng(8))


@pytest.mark.slow
def test_strips_at_several_roll_angles_separate_pitch_from_line_time():
    """For the planner: θ, a common line-time offset, the focal scale and chip 1's offsets from 200 GCPs per strip
    and 1 px of pixel noise (unit-weight σ from the central-difference Jacobian, exact GCPs, no tracker noise).
    Measured (3 June-2024 strips at 40° N): one strip σθy 31-38″, σδt 12.4-13.1 ms, corr(θy, δt) 0.999998; rolls
    −30°/0°/+30° together σθy 0.44″, σδt 0.17 ms, corr 0.996; −30°/0° 0.51″; −30°/+30° 2.1″ (the same range on
    both sides: the pitch is told from the line time by the range, so the rolls' |φ| must differ). The test asks
    σθy(campaign) < σθy(best strip) / 20 and |corr| < 0.999."""
    x = SEVEN_TRUTH
    geos = [
        strip_geometry(StripConfig(SENSOR, roll_deg=roll, epoch=epoch))
        for roll, epoch in ((-30.0, "2024-06-01T03:00:00"), (0.0, "2024-06-05T03:00:00"), (30.0, "2024-06-09T03:00:00"))
    ]
    sims = simulate_campaign(geos, [_seven(x)] * 3, np.random.default_rng(5), GcpLayout(n_gcps=200))
    J = [_jacobian(geo, sim, x) for geo, sim in zip(geos, sims, strict=True)]

    def sigma_corr(Jk):
        cov = np.linalg.inv(Jk.T @ Jk)
        return np.sqrt(np.diag(cov)), cov[1, 3] / np.sqrt(cov[1, 1] * cov[3, 3])

    single = min(sigma_corr(Jk)[0][1] for Jk in J)
    sd, corr = sigma_corr(np.vstack(J))
    assert sd[1] < single / 20
    assert abs(corr) < 0.999


def test_a_tracker_sample_error_acts_on_a_detection_as_a_weighted_misalignment(geo):
    """``StripTrajectory.tracker_sample_weights``' first-order law, against the model: moving one tracker sample by
    δ = 0.2″ about each axis (tracker mounted 10°, −5°, 3° from the body, so C_ESᵀ matters) changes the detections at
    lines between that sample and its neighbours by −w_k(t) ∂(line, pixel)/∂θ C_ESᵀ δ, and leaves the others alone.
    The law is first order: the detection's own move ΔL changes its weight by ΔL T / Δt_k (T the line period, Δt_k
    0.25 s between samples), a relative error ≈ 2.4e-3 for 2″ (measured 2.9e-3) and ten times less for 0.2″
    (measured ≤ 3e-4); the test allows 1e-3."""
    from orbits.strip import measured_trajectory

    geo_m = strip_geometry(StripConfig(SENSOR, roll_deg=20.0, n_lines=4000, tracker_mount_rotvec_deg=(10.0, -5.0, 3.0)))
    traj = geo_m.trajectory
    sim = simulate_strip(geo_m, LineScanParameters(), np.random.default_rng(16), GcpLayout(n_gcps=80))
    ground = sim.gcp_g_m[sim.detection_gcp]
    t = geo_m.datation.time_s(sim.line_true)
    k = int(np.median(traj.tracker_sample_weights(t)[0][:, 0]))  # a sample in the middle of the strip

    def model(trajectory, theta):
        line, pixel = locate_on_chips(
            SENSOR, geo_m.datation, trajectory, ground, sim.detection_chip, LineScanParameters(theta_rad=theta)
        )
        return np.stack([line, pixel], -1)

    base = model(traj, np.zeros(3))
    J = np.stack([(model(traj, h * e) - model(traj, -h * e)) / (2 * h) for e, h in zip(np.eye(3), [1e-7] * 3, strict=True)], -1)
    idx, w = traj.tracker_sample_weights(t)
    wk = np.where(idx == k, w, 0.0).sum(axis=-1)
    assert np.count_nonzero(wk) > 3 and np.count_nonzero(wk == 0) > 3
    for axis in range(3):
        delta = np.zeros((traj.tracker_t_s.size, 3))
        delta[k, axis] = 0.2 * ARCSEC
        moved = model(measured_trajectory(traj, delta), np.zeros(3)) - base
        expect = -wk[:, None] * np.einsum("dij,j->di", J, traj.C_ES.T @ delta[k])
        assert np.max(np.abs(moved - expect)) <= 1e-3 * np.max(np.abs(expect))


def test_tracker_noise_covariance_matches_its_draws():
    """``TrackerNoise.covariance_rad2`` against 4000 draws of 12 uneven sample times (white 1″ + Gauss–Markov 2″,
    τ = 0.7 s), seed 30: every entry within 5 σ of its sampling error (σ of an empirical covariance entry
    ≈ √((C_kk C_mm + C_km²)/n) for Gaussian draws), and the matrix is the AR(1) one: its Gauss–Markov part has a
    tridiagonal inverse (off-band entries ≤ 1e-9 of the diagonal)."""
    t = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.1, 0.4, 11)])
    noise = TrackerNoise(sigma_white_arcsec=1.0, sigma_correlated_arcsec=2.0, correlation_time_s=0.7)
    C = noise.covariance_rad2(t)
    rng = np.random.default_rng(30)
    d = np.stack([noise.draw_rad(rng, t)[:, 0] for _ in range(4000)])  # axis x, 4000 independent strips
    emp = d.T @ d / d.shape[0]
    sigma = np.sqrt((np.outer(np.diag(C), np.diag(C)) + C**2) / d.shape[0])
    assert np.all(np.abs(emp - C) < 5 * sigma)
    gm = TrackerNoise(sigma_correlated_arcsec=2.0, correlation_time_s=0.7).covariance_rad2(t)
    P = np.linalg.inv(gm)
    off = np.abs(np.triu(P, 2))
    assert off.max() < 1e-9 * np.abs(np.diag(P)).min()


def test_shipped_pushbroom_scenarios_load():
    """``scenarios/pushbroom-*.toml`` load as ``StripScenario``s (one strip; four strips overriding ``[strip]``), their
    truth from ``[effects]``; the frame loader refuses them naming the right one; a typo is named with its table."""
    from orbits import ScenarioError, load_scenario
    from orbits.strip import is_strip_scenario, load_strip_scenario, strip_scenario_from_dict

    one, camp = load_strip_scenario("pushbroom-strip"), load_strip_scenario("pushbroom-campaign")
    assert len(one.strips) == 1 and one.strips[0].n_lines == 10_000 and one.layout.n_gcps == 300
    assert [c.roll_deg for c in camp.strips] == [-25.0, 0.0, 15.0, 30.0] and camp.strips[2].site_lon_deg == 114.0
    t = camp.truth()
    assert t.line_time_offset_s == 0.002 and t.focal_scale == 3e-5 and t.chip_offsets_rad[1, 0] > 0
    assert is_strip_scenario("pushbroom-strip") and not is_strip_scenario("kiev2012-sensitivity")
    with pytest.raises(ScenarioError, match="load_strip_scenario"):
        load_scenario("pushbroom-strip")
    with pytest.raises(ScenarioError, match=r"\[gcps\].*n_gcp"):
        strip_scenario_from_dict({"kind": "pushbroom", "gcps": {"n_gcp": 3}}, "x.toml")
    with pytest.raises(ScenarioError, match="jitter.frequency_hz"):
        strip_scenario_from_dict({"kind": "pushbroom", "effects": {"jitter": {"amplitude_x_arcsec": 1.0}}}, "x.toml")
