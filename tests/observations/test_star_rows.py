"""Star rows in the row model: a star is a target at infinity (docs/stars.md, docs/architecture.md).

The set's star targets carry their astrometry; each star row's direction is the one apparent-place
function's (``orbits.star_apparent``) at its image; the measurement model predicts it through the
same camera and star-tracker stages as a landmark, with no GNSS or catalogue-position stage.
"""

from dataclasses import replace

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from builders import synthetic_sky
from star_camera import CAMERA, THETA

import boresight
from boresight.core.disturbances import DisturbanceModel, error_jacobians
from boresight.core.measurement import predict_rows
from boresight.observations.model import ObservationError
from boresight.observations.stars import star_observations
from orbits.orbit import CircularOrbit
from orbits.rotations import ARCSEC, quat_from_dcm
from orbits.star_apparent import apparent_directions, observer_states
from orbits.star_frames import KIND_STAR, CentroidNoise, StarDetector, inertial_hold, simulate_star_frames

EPOCH = "2026-03-01T12:00:00"


def star_set(seed=3, frames=24, sigma_m=0.0):
    """Noise-free (or centroid-σ ``sigma_m``) inertial-hold frames of a synthetic sky from a 600 km
    orbit, the star tracker exact: (ObservationSet of star rows, sky, frames)."""
    rng = np.random.default_rng(seed)
    sky = synthetic_sky(rng)
    orbit = CircularOrbit(600e3, np.radians(97.8))
    t_s = np.arange(frames) * 10.0
    r, v = orbit.state(np.linspace(0.0, 0.05, frames))
    up = r / np.linalg.norm(r, axis=1, keepdims=True)  # holds near the zenith: clear of the Earth
    C_IE = inertial_hold(np.degrees(np.arctan2(up[:, 1], up[:, 0])) + 2 * np.arange(frames), np.degrees(np.arcsin(up[:, 2])))
    det = StarDetector(centroid=CentroidNoise(0.0, 6.0, sigma_m), sigma_magnitude=0.0, sun_exclusion_deg=0.0)
    fr = simulate_star_frames(sky, CAMERA, Time(EPOCH, scale="utc") + t_s * u.s, r, v, C_IE, THETA, det, rng)
    f, d = np.nonzero(fr.mask & (fr.kind == KIND_STAR))
    obs = star_observations(
        sky,
        f,
        fr.hip[f, d],
        fr.xy_m[f, d][None],
        t_s=t_s,
        q_is=quat_from_dcm(C_IE)[None],
        r_sc_i_m=r[None],
        v_sc_i_m_s=v[None],
        focal_length_m=CAMERA.focal_length_m,
        epoch_utc=EPOCH,
        fov_deg=CAMERA.fov_deg,
        truth={"theta_rad": THETA[None]},
    )
    return obs, sky, fr


@pytest.fixture(scope="module")
def stars():
    return star_set()


def test_star_targets_carry_their_astrometry(stars):
    obs, sky, fr = stars
    assert set(obs.target_kind.tolist()) == {"star"}
    assert np.all(np.isnan(obs.landmark_g_m))
    assert len(obs.stars) == obs.n_targets
    assert np.array_equal(np.char.add("HIP ", obs.stars.hip.astype(str)), obs.landmark_ids)
    assert np.all(np.bincount(obs.image_index, minlength=obs.n_images) > 0)
    assert obs.n_observations > 100


def test_row_directions_are_the_one_apparent_place_function(stars):
    """Each row's direction is ``apparent_directions`` at its image's time, position and velocity (exactly)."""
    obs, sky, _ = stars
    u_rows = obs.row_star_directions_i()
    times = Time(EPOCH, scale="utc") + obs.t_s * u.s
    ref = apparent_directions(
        sky,
        observer_states(times, obs.r_sc_i_m[0], obs.v_sc_i_m_s[0]),
        sky.index_of(obs.stars.hip[obs.target_index]),
        obs.image_index,
    )
    assert np.max(np.abs(u_rows - ref)) < 1e-15
    # the aberration is in them: without the velocity the directions move by ~5″ (orbital) + 20″ (annual)
    still = apparent_directions(
        sky,
        observer_states(times, obs.r_sc_i_m[0], 0 * obs.v_sc_i_m_s[0]),
        sky.index_of(obs.stars.hip[obs.target_index]),
        obs.image_index,
    )
    moved = np.degrees(np.arccos(np.clip(np.sum(u_rows * still, -1), -1, 1))) * 3600
    assert 3.0 < moved.min() and moved.max() < 6.0


def test_the_measurement_model_predicts_star_rows_exactly(stars):
    """s = exp(−Φ(θ)) C_SK,nom A u_k projected: the simulator's noise-free points to round-off."""
    obs, _, _ = stars
    xy = predict_rows(obs, THETA, (obs.image_index, obs.target_index))
    assert np.max(np.abs(xy - obs.xy_m)) < 1e-14  # m (1e-9 pixel)


def test_noise_free_star_rows_recover_theta_to_1e_6_arcsec(stars):
    obs, _, _ = stars
    est = boresight.estimate(obs, "image_plane")
    assert np.max(np.abs(est.theta.to_value(u.arcsec) - THETA / ARCSEC)) < 1e-6


def test_star_rows_have_star_tracker_columns_and_no_position_stage(stars):
    """GNSS and the landmark catalogue do not act on a star row; the star tracker does, as the finite
    difference of the exact model says: rotating A by δ moves the prediction by −J δ."""
    obs, _, _ = stars
    rows = (obs.image_index, obs.target_index)
    J = error_jacobians(obs, THETA, rows=rows)
    assert np.all(J["gnss"] == 0) and np.all(J["catalogue"] == 0)
    from orbits.rotations import dcm_from_quat, quat_from_dcm, star_tracker_error_dcm

    h = 1e-7
    for k in range(3):
        delta = np.zeros(3)
        delta[k] = h
        moved = replace(obs, q_is=quat_from_dcm(star_tracker_error_dcm(delta) @ dcm_from_quat(obs.q_is)))
        dq = -(predict_rows(moved, THETA, rows) - predict_rows(obs, THETA, rows)) / h  # residual change per rad
        assert np.max(np.abs(dq - J["star_tracker"][..., k])) < 1e-6 * np.max(np.abs(J["star_tracker"]))


def test_star_rows_gls_with_a_tracker_error_per_image(stars):
    """With the star tracker per image every frame's stars share its nuisance: σθ per axis is about
    σ_tracker / √(frames) (the pixel σ is far smaller); the GNSS σ given changes nothing (no position stage)."""
    obs, _, _ = stars
    noise = {"pixel": {"sigma_m": 1e-7}, "star_tracker": {"sigma_arcsec": [4.0, 4.0, 4.0], "error_mode": "per_image"}}
    est = boresight.estimate(replace(obs, noise=noise), "image_plane", weighting="gls")
    est_g = boresight.estimate(
        replace(obs, noise=dict(noise, gnss={"sigma_m": 50.0, "error_mode": "per_image"})), "image_plane", weighting="gls"
    )
    sigma = est.sigma.to_value(u.arcsec)
    assert np.allclose(sigma[:2], 4.0 / np.sqrt(obs.n_images), rtol=0.05)
    assert np.allclose(est_g.sigma.to_value(u.arcsec), sigma, rtol=1e-9)
    assert DisturbanceModel.from_noise(noise).sigma_gnss_m == 0


def test_target_subsets_keep_the_astrometry_aligned(stars):
    obs, _, _ = stars
    sub = obs.targets(np.arange(obs.n_targets) % 3 == 1)
    assert np.array_equal(np.char.add("HIP ", sub.stars.hip.astype(str)), sub.landmark_ids)
    assert np.max(np.abs(predict_rows(sub, THETA, (sub.image_index, sub.target_index)) - sub.xy_m)) < 1e-14


def test_star_sets_are_refused_by_name(stars):
    obs, _, _ = stars
    with pytest.raises(ObservationError, match=r"stars: \d+ entries for \d+ target\(s\) of kind 'star'"):
        replace(obs, stars=obs.stars.subset(np.arange(3)))
    with pytest.raises(ObservationError, match="must be an orbits.star_catalogue.StarCatalogue"):
        replace(obs, stars=None)
    with pytest.raises(ObservationError, match="inertial frame GCRS"):
        replace(obs, frames={"inertial": "spherical-seminar", "earth_fixed": "spherical-seminar"})
    with pytest.raises(ObservationError, match="unknown kind 'planet'"):
        replace(obs, target_kind=np.full(obs.n_targets, "planet"))
    few = replace(obs, v_sc_i_m_s=None).images(np.arange(2))
    with pytest.raises(ObservationError, match="star rows need the spacecraft velocity"):
        few.row_star_directions_i()


def test_a_star_behind_the_camera_is_refused(stars):
    """The shared geometry check tests a star row on its direction (no position)."""
    obs, _, _ = stars
    from orbits.rotations import dcm_from_quat

    flipped = quat_from_dcm(np.diag([1.0, -1.0, -1.0]) @ dcm_from_quat(obs.q_is))
    with pytest.raises(ObservationError, match="behind the camera"):
        replace(obs, q_is=flipped)


def test_star_rows_round_trip_through_the_file(stars, tmp_path):
    """Format 1.2: the star rows, their astrometry and the predictions come back from ECSV (and Parquet
    when pyarrow is there); a landmark-only file is still written as 1.1."""
    obs, _, _ = stars
    for name in ("stars.ecsv", "stars.parquet"):
        if name.endswith("parquet"):
            pytest.importorskip("pyarrow")
        path = obs.write(tmp_path / name)
        back = boresight.ObservationSet.read(path)
        assert np.array_equal(back.landmark_ids, obs.landmark_ids) and np.array_equal(back.target_kind, obs.target_kind)
        for k in ("hip", "ra_rad", "dec_rad", "parallax_mas", "pm_ra_cosdec_mas_yr", "pm_dec_mas_yr", "magnitude_hp"):
            assert np.allclose(getattr(back.stars, k), getattr(obs.stars, k), rtol=1e-15, atol=0), k
        assert back.stars.epoch_jd_tt == obs.stars.epoch_jd_tt
        assert np.max(np.abs(back.row_star_directions_i() - obs.row_star_directions_i())) < 1e-15
        est = boresight.estimate(back, "image_plane")
        assert np.max(np.abs(est.theta.to_value(u.arcsec) - THETA / ARCSEC)) < 1e-6
    assert "format_version: '1.2'" in (tmp_path / "stars.ecsv").read_text()


def test_a_landmark_file_stays_format_1_1(tmp_path, small_obs=None):
    from builders import campaign_as_flown

    obs, _ = campaign_as_flown()
    text = obs.write(tmp_path / "lm.ecsv").read_text()
    assert "format_version: '1.1'" in text and "kind" not in text.split("\n# - {name: X")[0].split("datatype:")[-1]


def test_the_reader_names_a_bad_star_row(stars, tmp_path):
    from astropy.table import Table

    obs, _, _ = stars
    obs.write(tmp_path / "s.ecsv")
    for col, value, message in (
        ("parallax", np.nan, r"column 'parallax' row 2: non-finite value"),
        ("mag", 9.99, r"column 'mag' row \d+: star 'HIP \d+' has differing values on its rows"),
        ("kind", "planet", r"column 'kind' row 2: 'planet' is not a target kind"),
    ):
        t = Table.read(tmp_path / "s.ecsv", format="ascii.ecsv")
        if col == "kind":
            t[col] = t[col].astype("U8")
        t[col][2] = value
        t.write(tmp_path / "bad.ecsv", format="ascii.ecsv", overwrite=True)
        with pytest.raises(boresight.ObservationFileError, match=message):
            boresight.ObservationSet.read(tmp_path / "bad.ecsv")


@pytest.mark.parametrize("slip", ["x_mirrored", "quaternion_conjugated", "quaternion_scalar_first"])
def test_the_convention_doctor_names_a_slip_in_star_rows(slip):
    """A star file with a convention slip: the doctor tests star rows on their directions and names it."""
    from boresight.observations.doctor import diagnose_conventions

    obs, _, _ = star_set(seed=5, sigma_m=1.3e-6)
    if slip == "x_mirrored":
        bad = replace(obs, xy_m=obs.xy_m * [-1.0, 1.0], fov_deg=None)
    elif slip == "quaternion_conjugated":
        bad = replace(obs, q_is=obs.q_is * [-1.0, -1.0, -1.0, 1.0], check_geometry=False)
    else:
        bad = replace(obs, q_is=np.roll(obs.q_is, 1, axis=-1), check_geometry=False)
    assert diagnose_conventions(obs).passed
    dg = diagnose_conventions(bad)
    assert dg.verdict == slip, (dg.verdict, dg.message)
