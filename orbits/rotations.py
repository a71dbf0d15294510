"""Rotations: the skew matrix Φ, small-rotation DCMs and quaternion conversions.

Conventions (``docs/architecture.md``, shared CONVENTIONS.md):

* ``C_AB`` maps components in frame A to components in frame B: ``v_B = C_AB @ v_A``.
* ``Φ(v) w = v × w`` (Kiev 2012, "Skew matrix and small rotations").
* Quaternions are scalar-last ``[q1, q2, q3, q4]``; the attitude matrix
  ``A(q) = (q4² − |q_v|²) E + 2 q_v q_vᵀ − 2 q4 Φ(q_v)`` equals
  ``scipy.spatial.transform.Rotation.from_quat(q).as_matrix().T``.

All functions take leading batch axes: vectors ``(..., 3)``, matrices ``(..., 3, 3)``,
quaternions ``(..., 4)``. scipy's ``Rotation`` does the work; we only reshape.

Example
-------
>>> import numpy as np
>>> C = misalignment_dcm(np.radians([0.0, 0.0, 1.0]))   # 1 degree about z_K
>>> bool(np.allclose(C @ C.T, np.eye(3)))
True
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "skew",
    "rotvec_dcm",
    "misalignment_dcm",
    "star_tracker_error_dcm",
    "dcm_from_quat",
    "quat_from_dcm",
    "axis_dcm",
    "ARCSEC",
]

#: one arcsecond in radians
ARCSEC = np.pi / 180.0 / 3600.0


def _as_vectors(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise ValueError(f"Expected {name} to have shape (3,) or (..., 3), got {v.shape}")
    return v


def skew(v) -> np.ndarray:
    """Cross-product matrix Φ(v), ``(..., 3) -> (..., 3, 3)``; ``Φ(v) @ w == cross(v, w)``.

    Kiev 2012: Φ(δ) = [[0, −δ3, δ2], [δ3, 0, −δ1], [−δ2, δ1, 0]].
    """
    v = _as_vectors(v, "v")
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def rotvec_dcm(rotvec) -> np.ndarray:
    """``exp(Φ(v))``: scipy's active rotation matrix for rotation vector ``v`` (rad), batched."""
    v = _as_vectors(rotvec, "rotvec")
    flat = v.reshape(-1, 3)
    return Rotation.from_rotvec(flat).as_matrix().reshape(v.shape[:-1] + (3, 3))


def misalignment_dcm(theta_rad) -> np.ndarray:
    """Exact misalignment DCM ``exp(−Φ(θ))`` ≈ ``E − Φ(θ)`` (Kiev 2012 eq 24).

    ``C_SK,true = misalignment_dcm(θ) @ C_SK,nominal``: θ is a small rotation of the true
    camera frame relative to its nominal mount, in camera axes. Shape ``(..., 3) -> (..., 3, 3)``.
    """
    return rotvec_dcm(-_as_vectors(theta_rad, "theta_rad"))


def star_tracker_error_dcm(delta_rad) -> np.ndarray:
    """Exact star-tracker error DCM ``exp(Φ(δ))`` ≈ ``E + Φ(δ)`` (Kiev 2012 disturbance model).

    The measured attitude is ``A_meas = star_tracker_error_dcm(δ) @ A_true``.
    """
    return rotvec_dcm(delta_rad)


def dcm_from_quat(q) -> np.ndarray:
    """Attitude matrix ``A(q)`` of a scalar-last quaternion, ``(..., 4) -> (..., 3, 3)``.

    ``A(q)`` maps reference components to body components (``v_B = A(q) v_R``).
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise ValueError(f"Expected quaternion with shape (4,) or (..., 4) (scalar last), got {q.shape}")
    flat = q.reshape(-1, 4)
    m = Rotation.from_quat(flat).as_matrix()
    return np.swapaxes(m, -1, -2).reshape(q.shape[:-1] + (3, 3))


def quat_from_dcm(C) -> np.ndarray:
    """Scalar-last quaternion with q4 ≥ 0 whose attitude matrix is ``C``, ``(..., 3, 3) -> (..., 4)``."""
    C = np.asarray(C, dtype=float)
    if C.shape[-2:] != (3, 3):
        raise ValueError(f"Expected DCM with shape (3, 3) or (..., 3, 3), got {C.shape}")
    flat = np.swapaxes(C.reshape(-1, 3, 3), -1, -2)
    q = Rotation.from_matrix(flat).as_quat(canonical=True)
    return q.reshape(C.shape[:-2] + (4,))


def axis_dcm(axis: int, angle_rad) -> np.ndarray:
    """Elementary frame rotation: DCM to a frame turned by ``angle`` about ``axis`` (0, 1, 2).

    Equals ``exp(−Φ(angle · e_axis))``; for axis 2: ``[[c, s, 0], [−s, c, 0], [0, 0, 1]]``.
    """
    angle = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = s
    out[..., j, i] = -s
    return out
