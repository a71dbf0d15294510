"""Turntable / platform axis coupling error during calibration (Tang 2015 eq 34).

When an inertially stabilised platform is calibrated on a turntable with an autocollimator, and
the turntable elevation is set to theta_TE = -theta_PE = alpha != 0, a turntable rotation Omega
about its azimuth axis followed by the platform's -Omega about its own (now inclined) azimuth
axis does not cancel: by Tang 2015 eq 33 a rotation 2 theta about an axis inclined at alpha to
the mirror's vertical axis M_V has the component 2 asin(sin theta cos alpha) about M_V, so the
azimuth readout carries

    eta = Omega - 2 asin(sin(Omega / 2) cos alpha)                      (Tang 2015 eq 34)

Eq 33 comes from equating the quaternion of the rotation, cos theta + n sin theta with
n = j cos alpha + k sin alpha, with Q_0 = cos theta + k sin gamma + j sin delta (eq 31): 2 delta
is twice the asin of the quaternion's component along M_V. :func:`coupling_error_from_rotation_rad`
computes exactly that from a scipy ``Rotation``. The paper notes after eq 33 that 2 delta is not
exactly the spin about M_V; the swing-twist angle :func:`twist_angle_rad` is, and the two differ
at third order (documented in ``docs/pointing.md``).

Example
-------
>>> import astropy.units as u
>>> round(float(coupling_error(40 * u.deg, 20 * u.deg).to_value(u.deg)), 4)
2.5055
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from boresight.errors import InputValueError

__all__ = [
    "coupling_error_rad",
    "coupling_error",
    "coupling_error_from_rotation_rad",
    "twist_angle_rad",
    "compensate_azimuth_rad",
]


def _check(name, x):
    a = np.asarray(x, dtype=float)
    bad = ~np.isfinite(a)
    if np.any(bad):
        raise InputValueError(f"{name}: non-finite value {a[bad].ravel()[0]}")
    return a


def coupling_error_rad(omega_rad, alpha_rad):
    """eta of Tang 2015 eq 34 in radians; ``omega_rad`` and ``alpha_rad`` broadcast.

    Valid for |Omega| < pi (eq 33 assumes 0 <= theta < pi/2 with 2 theta = Omega).

    >>> float(coupling_error_rad(0.3, 0.0))
    0.0
    """
    om = _check("omega_rad", omega_rad)
    al = _check("alpha_rad", alpha_rad)
    if np.any(np.abs(om) >= np.pi):
        raise InputValueError(f"omega_rad: expected |Omega| < pi, got {om[np.abs(om) >= np.pi].ravel()[0]}")
    return om - 2.0 * np.arcsin(np.sin(om / 2.0) * np.cos(al))  # Tang 2015 eq 34


def coupling_error(omega, alpha):
    """Quantity front end of :func:`coupling_error_rad`: angles in, ``astropy`` angle (deg) out."""
    import astropy.units as u

    om = u.Quantity(omega).to_value(u.rad)
    al = u.Quantity(alpha).to_value(u.rad)
    return (coupling_error_rad(om, al) * u.rad).to(u.deg)


def _rotation(omega_rad, alpha_rad) -> tuple[Rotation, tuple[int, ...]]:
    om, al = np.broadcast_arrays(_check("omega_rad", omega_rad), _check("alpha_rad", alpha_rad))
    shape = om.shape
    om, al = om.ravel(), al.ravel()
    # The platform azimuth axis: the vertical M_V = z tilted by alpha about the mirror's
    # horizontal axis x (Tang 2015 Fig. 6). Rotation by Omega about it.
    axis = Rotation.from_rotvec(np.column_stack([al, 0 * al, 0 * al])).apply([0.0, 0.0, 1.0])
    return Rotation.from_rotvec(axis * om[:, None]), shape


def coupling_error_from_rotation_rad(omega_rad, alpha_rad):
    """eta from an exact scipy ``Rotation`` of Omega about an axis inclined at alpha to M_V.

    eta = Omega - 2 asin(q_z), q_z the M_V component of the rotation's quaternion
    (scipy order, scalar last); this is the definition of 2 delta in Tang 2015 eqs 31-33.
    Shape: the broadcast shape of the inputs.
    """
    rot, shape = _rotation(omega_rad, alpha_rad)
    q = rot.as_quat()  # [x, y, z, w], w = cos(Omega/2) >= 0 for |Omega| < pi
    om = np.broadcast_to(np.asarray(omega_rad, float), shape).ravel()
    return (om - 2.0 * np.arcsin(q[:, 2])).reshape(shape)


def twist_angle_rad(omega_rad, alpha_rad):
    """Swing-twist angle about M_V of the rotation Omega about the inclined axis, radians.

    The rotation is factored as R = R_swing R_twist with R_twist about M_V = z and R_swing
    about an axis perpendicular to z; twist = 2 atan2(q_z, q_w) = 2 atan(tan(Omega/2) cos alpha).
    """
    rot, shape = _rotation(omega_rad, alpha_rad)
    q = rot.as_quat()
    return (2.0 * np.arctan2(q[:, 2], q[:, 3])).reshape(shape)


def compensate_azimuth_rad(readout_rad, omega_rad, alpha_rad):
    """Remove the coupling error from an autocollimator azimuth readout: readout - eta (eq 34).

    ``readout_rad``, ``omega_rad`` (turntable azimuth Omega) and ``alpha_rad`` (elevation)
    broadcast; Tang 2015 section "Experimental results" applies eq 34 with the elevation as alpha
    and the rotated azimuth as Omega.
    """
    return _check("readout_rad", readout_rad) - coupling_error_rad(omega_rad, alpha_rad)
