"""orbits.camera: collinearity projection (Kiev 2012 eq 3) and back-projection (eq 2)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from orbits import Camera, attitude_law, back_project_to_plane, back_project_to_sphere, project, spherical_pass
from orbits.landmarks import grid, to_earth_fixed
from orbits.orbit import CircularOrbit


def _pass(alt_km, t):
    orbit = CircularOrbit(alt_km * 1e3, np.radians(98.0))
    lm = grid(5, 15e3)
    return spherical_pass(orbit, np.radians(44.45), np.radians(9.1167), t, lm)


def test_eq3_projection_by_hand():
    F = 2.0
    C = np.eye(3)
    r_i = np.array([0.0, 0.0, 500e3])
    r_m = np.array([10e3, -5e3, 0.0])
    # eq 3: x = −F [c11 ΔX + c12 ΔY + c13 ΔZ] / [c31 ΔX + c32 ΔY + c33 ΔZ]
    d = r_m - r_i
    x = -F * d[0] / d[2]
    y = -F * d[1] / d[2]
    assert np.allclose(project(C @ d, F), [x, y])
    assert x == pytest.approx(F * 10e3 / 500e3)


@settings(max_examples=40, deadline=None)
@given(st.floats(300, 1200), st.floats(-40, 40), st.sampled_from(["nadir", "site_tracking"]))
def test_round_trip_plane_and_sphere(alt_km, t, law):
    """Noise-free projection → back-projection returns each landmark to ≤ 1e-6 m."""
    g = _pass(alt_km, [t])
    C_IK = attitude_law(g, law)[0]
    F = 2.2
    lm_i = g.landmarks_i_m()[0]
    xy = project((lm_i - g.r_sc_i_m[0]) @ C_IK.T, F)
    # plane: work in the site's topocentric frame T, where each landmark has its own plane height
    C_IT = g.C_GT @ g.C_GI[0].T  # I → T
    C_TK = C_IK @ C_IT.T
    r_t = C_IT @ (g.r_sc_i_m[0] - g.site_i_m()[0])
    back = back_project_to_plane(xy, C_TK, r_t, g.landmarks_t_m[:, 2], F)
    assert np.abs(back - g.landmarks_t_m).max() <= 1e-6
    # sphere: landmarks placed on the sphere
    sph = to_earth_fixed(g.landmarks_t_m * [1, 1, 0], g.site_g_m, g.C_GT, "sphere")
    sph_i = sph @ g.C_GI[0].T
    xy = project((sph_i - g.r_sc_i_m[0]) @ C_IK.T, F)
    back = back_project_to_sphere(xy, C_IK, g.r_sc_i_m[0], np.linalg.norm(g.site_g_m), F)
    assert np.abs(back - sph_i).max() <= 1e-6


def test_visibility_in_front_and_in_field():
    cam = Camera(focal_length_m=2.2, fov_deg=3.4)
    half = np.tan(np.radians(1.7))
    s = np.array([[0, 0, -1.0], [0.99 * half, 0, -1], [1.01 * half, 0, -1], [0, 0, 1.0], [0.99 * half, 0.99 * half, -1]])
    assert cam.visible(s).tolist() == [True, True, False, False, True]


def test_ray_missing_the_sphere_is_named():
    """A camera above the north pole looking up (boresight +z) sees no Earth."""
    looking_up = np.diag([1.0, -1.0, -1.0])  # C_AK: z_K = −z_A, so the boresight −z_K is +z_A
    with pytest.raises(ValueError, match=r"image ray at index \(0,\) misses the sphere of radius 6371000.0 m"):
        back_project_to_sphere(np.array([[0.0, 0.0]]), looking_up, np.array([0, 0, 7e6]), 6.371e6, 1.0)


def test_camera_validation():
    with pytest.raises(ValueError, match=r"focal_length_m must be a positive number, got -2"):
        Camera(-2.0, 3.0)
    with pytest.raises(ValueError, match=r"fov_deg must be in \(0, 180\), got 200"):
        Camera(2.0, 200.0)
