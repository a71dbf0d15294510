"""Attitude laws: the body frame E (≡ the nominal camera frame) in inertial axes.

The camera looks along −z_E. Both laws take positions/velocities with a leading image
axis and return C_IE ``(N, 3, 3)`` (rows = body axes in I).

* ``nadir``: z_E radial (up), x_E along the velocity component ⟂ z_E, y_E = z_E × x_E — the
  orbital frame O of Kiev 2012 eq 23 (so C_OE = E).
* ``site_tracking``: −z_E on a target point (the boresight follows a ground point), x_E along the
  velocity component ⟂ z_E.

A ``yaw_rad`` turns the body about z_E after the law (C_IE ← axis_dcm(2, yaw) C_IE).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .rotations import axis_dcm

__all__ = ["frame_from_z_and_x", "nadir", "site_tracking"]


def _unit(v: Any) -> np.ndarray:
    result: np.ndarray = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return result


def frame_from_z_and_x(z: Any, x_hint: Any) -> np.ndarray:
    """DCM whose third row is unit(z) and first row is x_hint made ⟂ z, ``(..., 3) -> (..., 3, 3)``."""
    z = _unit(np.asarray(z, dtype=float))
    x = np.asarray(x_hint, dtype=float)
    x = _unit(x - np.sum(x * z, axis=-1, keepdims=True) * z)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-2)


def nadir(r_i_m: Any, v_i_m_s: Any, yaw_rad: float = 0.0) -> np.ndarray:
    """Nadir pointing (orbital frame) with optional yaw; C_IE ``(..., 3, 3)``."""
    C = frame_from_z_and_x(r_i_m, v_i_m_s)
    return axis_dcm(2, yaw_rad) @ C if yaw_rad else C


def site_tracking(r_i_m: Any, v_i_m_s: Any, target_i_m: Any, yaw_rad: float = 0.0) -> np.ndarray:
    """Boresight (−z_E) on ``target_i_m``; C_IE ``(..., 3, 3)``."""
    los = np.asarray(target_i_m, dtype=float) - np.asarray(r_i_m, dtype=float)
    C = frame_from_z_and_x(-los, v_i_m_s)
    return axis_dcm(2, yaw_rad) @ C if yaw_rad else C
