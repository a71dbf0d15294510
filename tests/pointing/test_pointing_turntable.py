"""Tang 2015 eq 34: turntable / platform coupling error against an exact scipy Rotation."""

from __future__ import annotations

import astropy.units as u
import numpy as np
import pytest

from boresight.pointing.turntable import (
    compensate_azimuth_rad,
    coupling_error,
    coupling_error_from_rotation_rad,
    coupling_error_rad,
    twist_angle_rad,
)

# The paper's simulated range (Tang 2015, Fig. 7): Omega in [-40, 40] deg, alpha in [-20, 20] deg.
OMEGA, ALPHA = np.meshgrid(np.radians(np.linspace(-40, 40, 161)), np.radians(np.linspace(-20, 20, 81)))


def test_eq34_matches_exact_rotation_to_1e12_rad():
    # 1e-12 rad: a few hundred ulps of the angles involved (~0.7 rad); eq 33 is an identity
    # for the quaternion component, so anything above rounding would be a bug.
    err = np.abs(coupling_error_rad(OMEGA, ALPHA) - coupling_error_from_rotation_rad(OMEGA, ALPHA))
    assert err.max() < 1e-12


def test_eq34_properties():
    eta = coupling_error_rad(OMEGA, ALPHA)
    np.testing.assert_allclose(coupling_error_rad(OMEGA, 0.0), 0.0, atol=1e-15)
    np.testing.assert_allclose(coupling_error_rad(-OMEGA, ALPHA), -eta, atol=1e-15)  # odd in Omega
    np.testing.assert_allclose(coupling_error_rad(OMEGA, -ALPHA), eta, atol=1e-15)  # even in alpha
    # small angles: eta ~ Omega alpha^2 / 2
    om, al = 1e-3, 2e-3
    assert coupling_error_rad(om, al) == pytest.approx(om * al**2 / 2, rel=1e-5)
    # the paper's Fig. 7 corner: 2.5055 deg at (40, 20) deg
    assert coupling_error(40 * u.deg, 20 * u.deg).to_value(u.deg) == pytest.approx(2.50553, abs=1e-5)


def test_eq34_is_not_the_swing_twist_angle():
    # What the paper neglects after eq 33: the true spin about M_V is the swing-twist angle;
    # it differs from eq 34 by up to 0.27 deg at the corner of the range (11 % of eta).
    diff = np.degrees(np.abs(OMEGA - twist_angle_rad(OMEGA, ALPHA) - coupling_error_rad(OMEGA, ALPHA)))
    assert 0.26 < diff.max() < 0.28
    om, al = 0.01, 0.02
    assert om - twist_angle_rad(om, al) == pytest.approx(coupling_error_rad(om, al), rel=1e-4)


def test_compensation_removes_eta():
    rng = np.random.default_rng(np.random.SeedSequence(34))
    true_err = rng.normal(0, 1e-3, OMEGA.shape)
    readout = true_err + coupling_error_rad(OMEGA, ALPHA)
    np.testing.assert_allclose(compensate_azimuth_rad(readout, OMEGA, ALPHA), true_err, atol=1e-15)


def test_bad_input():
    with pytest.raises(ValueError, match=r"omega_rad: expected \|Omega\| < pi, got 4.0"):
        coupling_error_rad(4.0, 0.1)
    with pytest.raises(ValueError, match=r"alpha_rad: non-finite value nan"):
        coupling_error_rad(0.1, np.nan)
