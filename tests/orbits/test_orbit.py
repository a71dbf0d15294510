"""orbits.orbit and orbits.geometry: the seminar's passage over a site (Kiev 2012 eqs 25-27)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from orbits import CircularOrbit, attitude_law, spherical_pass
from orbits.earth import OMEGA_EARTH_RAD_S, R_EARTH_M, enu_dcm, geocentric_unit
from orbits.landmarks import kiev_m1_m4

orbits_ = st.builds(
    lambda h, i, raan: CircularOrbit(h * 1e3, np.radians(i), np.radians(raan)),
    st.floats(300, 1500),
    st.floats(20, 160),
    st.floats(0, 360),
)


@settings(max_examples=100, deadline=None)
@given(orbits_, st.floats(-1, 1), st.sampled_from(["ascending", "descending"]))
def test_eq25_passage_puts_the_spacecraft_over_the_site(orbit, frac, direction):
    reach = min(orbit.inclination_rad, np.pi - orbit.inclination_rad)
    lat = frac * reach * 0.999
    p = orbit.passage(lat, direction)
    e_c = orbit.unit_position(p.u_rad)
    e_t = geocentric_unit(lat, p.site_ra_rad)
    assert np.abs(e_c - e_t).max() < 1e-12
    # ascending: moving north; descending: moving south
    v = orbit.unit_velocity(p.u_rad)
    assert (v[2] > 0) == (direction == "ascending") or abs(v[2]) < 1e-12


def test_unreachable_site_is_a_clear_error():
    orbit = CircularOrbit(400e3, np.radians(51.6))
    with pytest.raises(ValueError, match=r"latitude 60\.0000° is not reached by an orbit of inclination 51\.6000°"):
        orbit.passage(np.radians(60.0))


def test_bad_orbit_parameters_are_named():
    with pytest.raises(ValueError, match=r"altitude_m must be > 0, got -1"):
        CircularOrbit(-1.0, 1.0)
    with pytest.raises(ValueError, match=r"inclination_rad must be in \(0, π\)"):
        CircularOrbit(400e3, 4.0)


def test_eq26_motion_and_earth_rotation():
    orbit = CircularOrbit(400e3, np.radians(98.0))
    t = np.array([-10.0, 0.0, 10.0])
    g = spherical_pass(orbit, np.radians(44.45), np.radians(9.1167), t, kiev_m1_m4())
    # orbital motion at ω_o
    ang = np.arccos(np.clip(np.sum(g.r_sc_i_m[0] * g.r_sc_i_m[2]) / np.linalg.norm(g.r_sc_i_m[0]) ** 2, -1, 1))
    assert ang == pytest.approx(20 * orbit.mean_motion_rad_s, rel=1e-10)
    # the site turns about the pole at ω3
    s = g.site_i_m()
    ra = np.arctan2(s[:, 1], s[:, 0])
    assert np.diff(ra) == pytest.approx([10 * OMEGA_EARTH_RAD_S] * 2, rel=1e-10)
    # eq 27's C_IT (in Z-polar axes) maps the site's up direction to [0, 0, 1]
    C_IT = enu_dcm(np.radians(44.45), ra)
    assert np.allclose(np.einsum("nij,nj->ni", C_IT, s / R_EARTH_M), [0, 0, 1], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(orbits_, st.floats(-0.9, 0.9), st.floats(-180, 180), st.sampled_from(["nadir", "site_tracking"]), st.floats(-30, 30))
def test_every_dcm_is_orthonormal(orbit, frac, lon, law, yaw):
    reach = min(orbit.inclination_rad, np.pi - orbit.inclination_rad)
    g = spherical_pass(orbit, frac * reach, np.radians(lon), np.linspace(-60, 60, 7), kiev_m1_m4())
    C_IE = attitude_law(g, law, np.radians(yaw))
    for C in (g.C_GI, C_IE, g.C_GT[None]):
        err = np.abs(C @ np.swapaxes(C, -1, -2) - np.eye(3)).max()
        assert err < 1e-12
        assert np.allclose(np.linalg.det(C), 1.0, atol=1e-12)


def test_attitude_laws_point_where_they_say():
    orbit = CircularOrbit(680e3, np.radians(98.0))
    g = spherical_pass(orbit, np.radians(44.45), np.radians(9.1167), np.linspace(-30, 30, 5), kiev_m1_m4())
    nadir = attitude_law(g, "nadir")
    boresight = -nadir[:, 2, :]
    assert np.allclose(boresight, -g.r_sc_i_m / np.linalg.norm(g.r_sc_i_m, axis=-1, keepdims=True), atol=1e-15)
    track = attitude_law(g, "site_tracking")
    los = g.site_i_m() - g.r_sc_i_m
    assert np.allclose(-track[:, 2, :], los / np.linalg.norm(los, axis=-1, keepdims=True), atol=1e-15)
    # at the passage the two laws coincide
    assert np.allclose(nadir[2], track[2], atol=1e-12)
