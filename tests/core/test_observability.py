"""Observability: the estimators refuse (ObservabilityError) rather than return a garbage θ.

A hand-built geometry: camera 680 km above a flat patch at the north pole of a spherical
Earth, looking straight down (C_IK = E, boresight −z), F = 2.2 m, landmarks given by their
(east, north, height) offsets in metres.
"""

import dataclasses

import numpy as np
import pytest
from oracles import from_grid

from boresight import DisturbanceModel, ObservabilityError, estimate
from boresight.core.algorithms.image_plane import predicted_camera_vectors
from boresight.core.gls.normal_equations import NormalEquations
from boresight.errors import axis_name
from orbits import ARCSEC

RE, H, F = 6371e3, 680e3, 2.2
ALGS = ("image_plane", "ground_plane", "unit_vector")


def observations(offsets_m, theta_arcsec=(20.0, -15.0, 40.0), mask=None):
    """One image of landmarks at ``offsets_m`` (M, 3) from the point under the camera."""
    lm = np.asarray(offsets_m, float).reshape(-1, 3) + [0.0, 0.0, RE]
    M = lm.shape[0]
    obs = from_grid(
        t_s=np.zeros(1),
        pass_index=np.zeros(1, int),
        q_is=np.array([[[0.0, 0.0, 0.0, 1.0]]]),
        r_sc_i_m=np.array([[[0.0, 0.0, RE + H]]]),
        C_GI=np.eye(3)[None],
        landmark_ids=np.array([f"L{i}" for i in range(M)]),
        landmark_g_m=lm[None],
        xy_m=np.zeros((1, 1, M, 2)),
        mask=np.ones((1, M), bool) if mask is None else np.asarray(mask)[None],
        focal_length_m=F,
    )
    s = predicted_camera_vectors(obs, np.asarray(theta_arcsec) * ARCSEC)  # every observed landmark's point
    return dataclasses.replace(obs, xy_m=-F * s[..., :2] / s[..., 2:3])


CROSS = [[13e3, 0, 0], [0, 13e3, 0], [-13e3, 0, 0], [0, -13e3, 0]]


@pytest.mark.parametrize("alg", ALGS)
def test_good_geometry_is_accepted_with_a_moderate_condition_number(alg):
    est = estimate(observations(CROSS), algorithm=alg)
    assert np.allclose(est.theta.to_value("arcsec"), [20, -15, 40], atol=1e-3)
    assert 1e2 < est.condition_number < 1e5  # (F/lever arm)² ≈ 2.7e3 for the image-plane form


@pytest.mark.parametrize("alg", ALGS)
def test_one_landmark_is_too_few(alg):
    with pytest.raises(
        ObservabilityError, match=r"too few observations — run 0 has 2 residual components \(\+0 prior\) for 3 unknowns"
    ) as exc:
        estimate(observations([[5e3, 2e3, 0.0]]), algorithm=alg)
    assert exc.value.run == 0 and exc.value.weak_axis is not None


def test_no_observation_at_all():
    with pytest.raises(ObservabilityError, match="has 0 residual components"):
        estimate(observations(CROSS, mask=[False] * 4))


@pytest.mark.parametrize("alg", ALGS)
def test_all_landmarks_at_the_boresight_lose_theta_z(alg):
    """Landmarks on the boresight (at different heights, so they are distinct points): every
    one images at the principal point and a rotation about the boresight moves none of them."""
    pts = [[0, 0, 0.0], [0, 0, 200.0], [0, 0, 1500.0]]
    with pytest.raises(
        ObservabilityError, match=r"weak axis θz \(about the boresight\), condition number (inf|\d\.\d+e\+\d\d) > 1e\+08"
    ) as exc:
        estimate(observations(pts, theta_arcsec=(20.0, -15.0, 0.0)), algorithm=alg)
    assert abs(exc.value.weak_axis[2]) > 0.999 and exc.value.condition_number > 1e8


@pytest.mark.parametrize("alg", ALGS)
def test_landmarks_collinear_with_the_camera_lose_the_rotation_about_that_line(alg):
    """Landmarks on one line through the projection centre (one line of sight off the
    boresight): they all image at one point; the rotation about that line is unobservable."""
    d = np.array([6e3, 8e3, -H])  # direction from the camera, ~0.84° off the boresight
    pts = [np.array([0.0, 0.0, H]) + t * d for t in (1.0, 0.999, 0.997)]
    with pytest.raises(ObservabilityError, match=r"weak axis direction \[0\.01, 0\.01, 1\.00\] in θ|weak axis θz") as exc:
        estimate(observations(pts), algorithm=alg)
    w = exc.value.weak_axis
    assert abs(abs(w @ (d / np.linalg.norm(d))) - 1) < 1e-6


def test_weak_axis_naming_for_an_oblique_line_of_sight():
    """Same degeneracy, 37° off the boresight: the message names the direction itself."""
    d = np.array([300e3, 400e3, -H])
    pts = [np.array([0.0, 0.0, H]) + t * d for t in (1.0, 0.998, 0.995)]
    with pytest.raises(ObservabilityError, match=r"weak axis direction \[-0\.36, -0\.47, 0\.81\] in θ, condition number inf"):
        estimate(observations(pts))


@pytest.mark.parametrize("alg", ALGS)
def test_collinear_ground_landmarks_off_the_camera_are_observable(alg):
    """Collinear on the ground is *not* degenerate when the position is known: two non-parallel
    lines of sight fix a rotation (Wahba). Only Algorithm 1 (a homography) needs four points
    with no three collinear."""
    pts = [[-13e3, 5e3, 0], [0, 5e3, 0], [13e3, 5e3, 0]]
    est = estimate(observations(pts), algorithm=alg)
    assert np.allclose(est.theta.to_value("arcsec"), [20, -15, 40], atol=1e-3)
    assert est.condition_number < 1e6


def test_a_prior_makes_a_weak_axis_prior_limited_instead():
    pts = [[0, 0, 0.0], [0, 0, 200.0], [0, 0, 1500.0]]
    model = DisturbanceModel(sigma_pixel_m=3e-6)
    est = estimate(observations(pts, theta_arcsec=(20.0, -15.0, 0.0)), weighting="gls", model=model, prior_sigma_arcsec=600.0)
    assert np.isclose(est.sigma.to_value("arcsec")[2], 600.0, rtol=1e-6)  # nothing learnt about θz
    assert est.sigma.to_value("arcsec")[0] < 1.0


def test_flat_per_image_pointing_nuisance_leaves_theta_unobservable():
    """A per-image pointing error fitted freely (no prior) is the same rotation as θ."""
    obs = observations(CROSS)
    from boresight.core.algorithms.image_plane import linearize

    G, q = linearize(obs, np.zeros(3))
    ne = NormalEquations()
    ne.update(G.reshape(1, 1, 8, 3), q.reshape(1, 1, 8), nuisance=G.reshape(1, 1, 8, 3))
    with pytest.raises(ObservabilityError, match="θ is not observable: weak axis"):
        ne.solve()


def test_axis_names():
    assert axis_name([0, 0, -1]) == "θz (about the boresight)"
    assert axis_name([1, 0, 0.01]) == "θx"
    assert axis_name([0.7, 0.7, 0]) == "direction [0.71, 0.71, 0.00] in θ"
