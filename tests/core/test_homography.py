"""Algorithm 1 (Kiev 2012 eqs 4-13): homography fit, eq 11 decomposition, θ from Θ = C′Cᵀ."""

from __future__ import annotations

import copy
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from oracles import dense_grid
from paths import ROOT
from scipy.spatial.transform import Rotation

import orbits
from boresight import simulate
from boresight.core.algorithms.homography import (
    HomographyError,
    PlaneFrame,
    apply_homography,
    decompose_homography,
    estimate_homography,
    fit_homography,
    hartley_normalization,
    plane_frame,
    theta_from_misalignment_dcm,
)
from boresight.errors import ObservabilityError
from boresight.reproductions.kiev2012 import SEMINAR_ALGORITHM1_TABLE, algorithm1_table, algorithm1_variants
from orbits.rotations import ARCSEC, misalignment_dcm, skew

SCENARIO = ROOT / "scenarios" / "kiev2012-algorithm1.toml"

MILLI_ARCSEC = 1e-3  # arcsec: the required recovery accuracy on coplanar noise-free data
ONE_MM = 1e-3  # m


def _scenario_dict():
    with open(SCENARIO, "rb") as fh:
        return tomllib.load(fh)


def _scenario(theta_arcsec=(20.0, -15.0, 40.0), landmarks=None, t_s=None, **over):
    d = copy.deepcopy(_scenario_dict())
    d["misalignment"]["true_arcsec"] = list(theta_arcsec)
    if landmarks is not None:
        d["landmarks"] = landmarks
    if t_s is not None:
        d["passes"][0]["t_s"] = t_s
    for key, value in over.items():
        d[key] = value
    return orbits.scenario_from_dict(d)


COPLANAR_M1_M4 = {  # the seminar's M1..M4 with their heights set to 0, on the site's tangent plane
    "layout": "explicit",
    "enu_km": [[50, 0, 0], [0, 50, 0], [-50, 0, 0], [0, -50, 0]],
    "placement": "tangent_plane",
}
COPLANAR_GRID = {"layout": "grid", "n": 4, "half_width_km": 40.0, "height_m": 0.0, "placement": "tangent_plane"}


# ---------------------------------------------------------------------------- homography fit


def _random_homography(rng):
    H = np.eye(3) + 0.2 * rng.normal(size=(3, 3))
    H[2, :2] *= 1e-2
    return H / H[2, 2]


def test_fit_recovers_known_homography_exactly():
    rng = np.random.default_rng(11)
    H0 = np.stack([_random_homography(rng) for _ in range(5)])  # a batch
    src = rng.uniform(-10.0, 10.0, size=(5, 7, 2))
    dst = apply_homography(H0, src)
    H, cond = fit_homography(src, dst)
    assert H.shape == (5, 3, 3) and cond.shape == (5,)
    np.testing.assert_allclose(H, H0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(H[:, 2, 2], 1.0)  # eq 5's normalisation a9 = 1
    # exactly 4 points: 8 equations, 8 unknowns (eq 12 with i = 4)
    H4, _ = fit_homography(src[:, :4], dst[:, :4])
    np.testing.assert_allclose(H4, H0, rtol=0, atol=1e-10)


def test_fit_broadcasts_and_masks():
    rng = np.random.default_rng(12)
    H0 = _random_homography(rng)
    src = rng.uniform(-10.0, 10.0, size=(6, 2))
    dst = apply_homography(H0, src)
    dst_bad = dst.copy()
    dst_bad[5] += 100.0  # an outlier that the mask removes
    mask = np.array([True] * 5 + [False])
    H, _ = fit_homography(src, dst_bad, mask)
    np.testing.assert_allclose(H, H0, rtol=0, atol=1e-12)
    H_unmasked, _ = fit_homography(src, dst_bad)
    assert np.max(np.abs(H_unmasked - H0)) > 1e-3  # the test can fail: without the mask it is wrong


def test_hartley_normalization_centres_and_scales():
    rng = np.random.default_rng(13)
    p = rng.uniform(1e6, 1.1e6, size=(3, 8, 2))
    T = hartley_normalization(p)
    q = apply_homography(T, p)
    np.testing.assert_allclose(q.mean(axis=-2), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1).mean(axis=-1), np.sqrt(2.0), rtol=1e-12)


def _pose_points(offset_m, half_width_m, rng, F=1.0):
    """Six landmarks on z = 0 of a plane frame whose origin is ``offset_m`` from them, imaged from 400 km."""
    src = rng.uniform(-half_width_m, half_width_m, size=(6, 2)) + offset_m
    C0 = Rotation.from_rotvec([0.05, -0.03, 0.7]).as_matrix().T  # plane → camera, a tilted look down
    r0 = np.array([offset_m + 1e4, offset_m - 2e4, 4e5])
    s = (np.c_[src, np.zeros(6)] - r0) @ C0.T
    return src, -F * s[:, :2] / s[:, 2:3], C0, r0


def test_normalisation_matters_on_a_badly_scaled_configuration():
    # A 10 km landmark patch 1000 km from the plane-frame origin, image coordinates ~1e-2 m:
    # the raw DLT matrix mixes entries of 1e6 m, 1e4 m·m and 1 — condition number ~1e11.
    src, dst, C0, r0 = _pose_points(1e6, 5e3, np.random.default_rng(3))
    out = {}
    for normalize in (True, False):
        H, cond = fit_homography(src, dst, normalize=normalize)
        C, r = decompose_homography(H, 1.0, 1.0)
        mu = np.linalg.norm(Rotation.from_matrix(C @ C0.T).as_rotvec()) / ARCSEC
        out[normalize] = (float(cond), mu, np.linalg.norm(r - r0))
    cond_n, mu_n, dr_n = out[True]
    cond_r, mu_r, dr_r = out[False]
    assert cond_n < 100 and cond_r > 1e9
    assert mu_n < MILLI_ARCSEC and dr_n < ONE_MM  # normalised: exact to rounding
    assert mu_r > 0.1 and dr_r > 0.1  # raw: the same exact data lose > 0.1″ and > 0.1 m


def test_decompose_recovers_pose_from_an_exact_homography():
    src, dst, C0, r0 = _pose_points(0.0, 5e4, np.random.default_rng(4))
    H, _ = fit_homography(src, dst)
    for z_ref in (1.0, 4e5):  # eq 11 is independent of the reference height Z*
        ref = src / z_ref  # x* = F X / Z*, F = 1
        Hz, _ = fit_homography(ref, dst)
        C, r = decompose_homography(Hz, 1.0, z_ref)
        np.testing.assert_allclose(C, C0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r, r0, rtol=1e-10)


def test_theta_from_misalignment_dcm_uses_eq24_sign():
    th = np.array([[20.0, -15.0, 40.0], [600.0, 600.0, 600.0]]) * ARCSEC
    Theta = misalignment_dcm(th)
    np.testing.assert_allclose(theta_from_misalignment_dcm(Theta), th, rtol=0, atol=1e-15)
    # Θ ≈ E − Φ(θ) (Kiev 2012 eq 24): the first-order matrix has the same sign
    np.testing.assert_allclose(Theta[0], np.eye(3) - skew(th[0]), rtol=0, atol=1e-7)  # |θ|²/2 = 3e-8
    assert np.all(np.sign(theta_from_misalignment_dcm(np.eye(3) - skew(th[0]))) == np.sign(th[0]))


# ---------------------------------------------------------------------------- plane frame


def test_plane_frame_best_fit_and_horizontal():
    sc = orbits.load_scenario(SCENARIO)
    geoms, _ = orbits.campaign_geometry(sc)
    lm = geoms[0].landmarks_g_m
    P = plane_frame(lm, "best_fit")
    h = P.to_plane(lm)[:, 2]
    # M1..M4 heights 50, 100, −20, −80 m over ±50 km: the least-squares plane leaves ±2.5 m
    np.testing.assert_allclose(h, [2.5, -2.5, 2.5, -2.5], atol=1e-3)
    Ph = plane_frame(lm, "horizontal")
    np.testing.assert_allclose(Ph.to_plane(lm)[:, 2], np.array([50, 100, -20, -80]) - 12.5, atol=0.5)
    # x_P is east at the site: the in-plane axes follow the site's east/north
    np.testing.assert_allclose(Ph.C_GP[0], geoms[0].C_GT[0], atol=1e-5)
    with pytest.raises(ValueError, match="plane method must be"):
        plane_frame(lm, "tilted")
    with pytest.raises(ValueError, match="orthonormal"):
        PlaneFrame(np.zeros(3), 2 * np.eye(3))


# ---------------------------------------------------------------------------- Algorithm 1 on simulated passes


@pytest.mark.parametrize("theta_arcsec", [(20.0, -15.0, 40.0), (600.0, 600.0, 600.0), (-600.0, 600.0, -600.0)])
@pytest.mark.parametrize("layout", [COPLANAR_M1_M4, COPLANAR_GRID], ids=["M1-M4-flat", "grid4x4"])
def test_coplanar_noise_free_recovers_theta(theta_arcsec, layout):
    obs = simulate(_scenario(theta_arcsec, layout), np.random.default_rng(0), runs=1)
    assert obs.is_complete
    res = estimate_homography(obs)
    assert res.valid.all()
    np.testing.assert_allclose(
        res.theta_per_image_arcsec[0], np.broadcast_to(theta_arcsec, (obs.n_images, 3)), rtol=0, atol=MILLI_ARCSEC
    )
    np.testing.assert_allclose(res.theta_arcsec[0], theta_arcsec, rtol=0, atol=MILLI_ARCSEC)
    # the homography's own pose is exact too: μ (attitude) and δr (position from eq 11, no GNSS)
    assert np.max(res.mu_arcsec) < MILLI_ARCSEC
    assert np.max(res.dr_m) < ONE_MM


def test_plane_choice_and_z_ref_do_not_matter_for_coplanar_landmarks():
    obs = simulate(_scenario(landmarks=COPLANAR_GRID), np.random.default_rng(0), runs=1)
    sc = orbits.load_scenario(SCENARIO)
    geoms, _ = orbits.campaign_geometry(sc)
    ref = estimate_homography(obs).theta_per_image_rad
    for kw in (dict(plane="horizontal"), dict(plane=PlaneFrame(geoms[0].site_g_m, geoms[0].C_GT)), dict(z_ref_m=4e5)):
        np.testing.assert_allclose(estimate_homography(obs, **kw).theta_per_image_rad, ref, rtol=0, atol=MILLI_ARCSEC * ARCSEC)


def test_batched_equals_run_by_run():
    sc = replace(_scenario(), sigma_catalogue_m=2.0, sigma_pixel_m=2e-6)
    obs = simulate(sc, np.random.default_rng(5), runs=4)
    res = estimate_homography(obs)
    assert res.theta_rad.shape == (4, 3) and res.mu_arcsec.shape == (4, 10)
    for k in range(obs.runs):
        one = estimate_homography(obs.run(k))
        np.testing.assert_allclose(one.theta_per_image_rad[0], res.theta_per_image_rad[k], rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(one.mu_arcsec[0], res.mu_arcsec[k], rtol=1e-9)
    np.testing.assert_allclose(res.theta_rad, res.theta_per_image_rad.mean(axis=1), rtol=1e-12)
    assert np.ptp(res.theta_rad[:, 0]) > 1.0 * ARCSEC  # the runs really differ


def test_non_coplanar_landmarks_give_a_deterministic_error():
    # The seminar's M1..M4 (heights 50, 100, −20, −80 m), noise-free, images at t = 0..50 s.
    obs = simulate(_scenario(t_s={"start": 0.0, "stop": 50.0, "step": 5.0}), np.random.default_rng(0), runs=2)
    res = estimate_homography(obs)
    np.testing.assert_allclose(res.mu_arcsec[0], res.mu_arcsec[1], rtol=1e-12)  # deterministic
    assert res.mu_arcsec[0, 0] < 1.0  # at the nadir passage the ±2.5 m twist hardly shows
    assert np.all(res.mu_arcsec[0, 1:] > 10.0)  # off nadir it does: ~3.2″ per second of the pass
    # Dropping the heights in the site's tangent plane (eq 6 literally) tilts the reference plane by
    # the landmarks' slope, atan(|∇h|) = atan(√(0.7² + 1.8²)·1e-3) = 398″: μ at t = 0 is that tilt.
    sc = orbits.load_scenario(SCENARIO)
    geoms, _ = orbits.campaign_geometry(sc)
    site = estimate_homography(obs, plane=PlaneFrame(geoms[0].site_g_m, geoms[0].C_GT))
    tilt_arcsec = np.arctan(np.hypot(0.7e-3, 1.8e-3)) / ARCSEC
    np.testing.assert_allclose(site.mu_arcsec[0, 0], tilt_arcsec, rtol=0.01)


# ---------------------------------------------------------------------------- bad input


def test_fewer_than_four_landmarks_raises_naming_the_image():
    obs = simulate(_scenario(), np.random.default_rng(0), runs=1)
    mask = dense_grid(obs).mask.copy()
    mask[3, 0] = False  # image 3 keeps only M2, M3, M4
    bad = replace(dense_grid(obs), mask=mask).to_rows()
    with pytest.raises(HomographyError, match=r"image 3 \(t = 20 s\).*only 3 landmarks.*condition number inf") as info:
        estimate_homography(bad)
    assert isinstance(info.value, ObservabilityError) and isinstance(info.value, ValueError)
    assert info.value.image == 3 and info.value.run == 0 and info.value.condition_number == np.inf
    res = estimate_homography(bad, on_degenerate="skip")
    assert not res.valid[0, 3] and res.valid[0, np.arange(10) != 3].all()
    assert np.all(np.isnan(res.theta_per_image_rad[0, 3])) and np.all(np.isfinite(res.theta_rad))


def test_collinear_landmarks_raise_with_the_condition_number():
    layout = {"layout": "explicit", "enu_km": [[50, 0, 0], [0, 0, 0], [-50, 0, 0], [0, 50, 0]], "placement": "tangent_plane"}
    obs = simulate(_scenario(landmarks=layout), np.random.default_rng(0), runs=1)
    with pytest.raises(HomographyError, match=r"image 0 .*collinear.*condition number [0-9.]+e\+[0-9]+") as info:
        estimate_homography(obs)
    assert info.value.condition_number > 1e10


def test_bad_arguments_name_the_value():
    obs = simulate(_scenario(), np.random.default_rng(0), runs=1)
    with pytest.raises(ValueError, match="on_degenerate must be 'raise' or 'skip', got 'ignore'"):
        estimate_homography(obs, on_degenerate="ignore")
    with pytest.raises(ValueError, match="z_ref_m must be a positive number, got -1"):
        estimate_homography(obs, z_ref_m=-1.0)
    with pytest.raises(ValueError, match="plane must be"):
        estimate_homography(obs, plane=3)


# ---------------------------------------------------------------------------- the seminar's table


def test_algorithm1_table_columns_and_determinism():
    t = algorithm1_table(SCENARIO, r_p_values=(0.0, 1.0), runs=50, seed=7)
    np.testing.assert_allclose(t["t_s"], SEMINAR_ALGORITHM1_TABLE["t_s"])
    np.testing.assert_allclose(t["seminar_mu_arcsec_rp0"], SEMINAR_ALGORITHM1_TABLE["mu_arcsec_rp0"])
    np.testing.assert_allclose(t["mu_arcsec_std_rp0"], 0.0, atol=1e-9)  # r_p = 0 is deterministic
    assert np.all(t["mu_arcsec_std_rp1"] > 1.0)  # r_p = 1 m is not
    # the r_p = 0 column grows ~linearly off nadir with the best-fit plane (docs/reproduction.md)
    np.testing.assert_allclose(t["mu_arcsec_mean_rp0"][[0, -1]], [16.2, 164.0], atol=0.5)
    again = algorithm1_table(SCENARIO, r_p_values=(0.0, 1.0), runs=50, seed=7)
    np.testing.assert_array_equal(t["mu_arcsec_mean_rp1"], again["mu_arcsec_mean_rp1"])


def test_attitude_law_and_placement_do_not_change_the_exact_fit_error():
    # With exactly 4 landmarks the homography is an exact fit: turning the camera about its
    # centre (nadir vs site-tracking) cannot change C′'s error (docs/reproduction.md).
    v = algorithm1_variants(SCENARIO, planes=("best_fit",))
    assert len(v) == 4 * 10

    def mu(att, pl):
        return np.asarray(v[(v["attitude"] == att) & (v["placement"] == pl)]["mu_arcsec"])

    np.testing.assert_allclose(mu("nadir", "tangent_plane"), mu("site_tracking", "tangent_plane"), rtol=0, atol=1e-6)
    np.testing.assert_allclose(mu("site_tracking", "sphere"), mu("site_tracking", "tangent_plane"), rtol=0, atol=0.2)
    assert mu("site_tracking", "tangent_plane")[-1] > 100.0


def test_two_pass_campaign_uses_one_plane_per_pass():
    # Two passes over sites ~1600 km apart: one best-fit plane through both landmark sets would be
    # meaningless; Algorithm 1 fits one plane per pass and stays exact for coplanar landmarks.
    d = copy.deepcopy(_scenario_dict())
    d["landmarks"] = COPLANAR_GRID
    second = dict(d["passes"][0], site_lat_deg=30.0, site_lon_deg=20.0, direction="descending")
    d["passes"] = [d["passes"][0], second]
    obs = simulate(orbits.scenario_from_dict(d), np.random.default_rng(0), runs=2)
    assert set(obs.pass_index.tolist()) == {0, 1}
    res = estimate_homography(obs)
    np.testing.assert_allclose(res.theta_arcsec, [[20.0, -15.0, 40.0]] * 2, rtol=0, atol=MILLI_ARCSEC)
    assert np.nanmax(np.abs(res.height_m)) < 1e-6
    assert not np.allclose(res.plane.origin_g_m[0, 0], res.plane.origin_g_m[0, -1])


def test_registered_in_boresight_estimate():
    from boresight import estimate

    obs = simulate(_scenario((600.0, -600.0, 600.0), COPLANAR_GRID), np.random.default_rng(0), runs=3)
    for name in ("homography", "alg1"):
        est = estimate(obs, algorithm=name)
        assert est.algorithm == "homography" and est.theta.shape == (3, 3)
        np.testing.assert_allclose(est.theta.to_value("arcsec"), [[600.0, -600.0, 600.0]] * 3, rtol=0, atol=MILLI_ARCSEC)
        assert np.all(est.dof == 10 * (2 * 16 - 8)) and np.all(est.chi2 < 1e-20)
        assert np.all(np.diagonal(est.covariance.to_value("arcsec2"), axis1=-2, axis2=-1) < 1e-6)
    with pytest.raises(ValueError, match="only weighting='unit' is available, got 'gls'"):
        estimate(obs, algorithm="alg1", weighting="gls")
    with pytest.raises(ValueError, match="takes no prior"):
        estimate(obs, algorithm="alg1", prior_sigma_arcsec=10.0)
    # options reach estimate_homography
    bad = replace(dense_grid(obs), mask=np.where(np.arange(16) < 3, True, False)[None, :].repeat(obs.n_images, 0)).to_rows()
    with pytest.raises(HomographyError, match="only 3 landmarks"):
        estimate(bad, algorithm="alg1")
    with pytest.raises(HomographyError):
        estimate(bad, algorithm="alg1", on_degenerate="skip")  # every image skipped: nothing left


def test_a_pass_with_too_few_landmarks_is_named_or_skipped():
    obs = simulate(_scenario(), np.random.default_rng(0), runs=1)
    mask = dense_grid(obs).mask.copy()
    mask[:, 2:] = False  # only M1, M2 anywhere: no plane, no homography
    with pytest.raises(HomographyError, match=r"image 0 \(t = 5 s\) of run 0: only 2 landmarks"):
        estimate_homography(replace(dense_grid(obs), mask=mask).to_rows())
    with pytest.raises(HomographyError, match="no image of run 0 gives a homography"):
        estimate_homography(replace(dense_grid(obs), mask=mask).to_rows(), on_degenerate="skip")
