"""Rotations: the skew matrix Φ, small-rotation DCMs and quaternion conversions.

Conventions (``docs/conventions.md``):

* ``C_AB`` maps components in frame A to components in frame B: ``v_B = C_AB @ v_A``.
* ``Φ(v) w = v × w`` (Kiev 2012, "Skew matrix and small rotations").
* Quaternions are scalar-last ``[q1, q2, q3, q4]``; the attitude matrix
  ``A(q) = (q4² − |q_v|²) E + 2 q_v q_vᵀ − 2 q4 Φ(q_v)`` equals
  ``scipy.spatial.transform.Rotation.from_quat(q).as_matrix().T``.

All functions take leading batch axes: vectors ``(..., 3)``, matrices ``(..., 3, 3)``,
quaternions ``(..., 4)``. For DCMs and quaternions scipy's ``Rotation`` does the work; we only
reshape.

SO(3) helpers for the estimators' hot paths (the one place for this math: the estimators, the
disturbance model, the CRLB and the Monte Carlo kernels all use these):

* ``rodrigues_coefficients(φ²)`` — a = sin φ/φ, b = (1 − cos φ)/φ², c = (φ − sin φ)/φ³, with
  their Taylor series below φ² = 1e-8 (where the closed forms lose digits);
* ``rotate(v, s)`` — exp(Φ(v)) s = s + a v × s + b v × (v × s) (Rodrigues), batched, no 3 × 3
  temporaries; ``rotate_soa`` the same on structure-of-arrays components (run axis last);
* ``right_jacobian(θ)`` — J_r(θ) = E − b Φ(θ) + c Φ(θ)², the SO(3) right Jacobian of
  exp(Φ(θ)): d[exp(−Φ(θ)) s0] = Φ(s(θ)) J_r(θ) dθ (derivation in
  ``boresight/core/measurement.py``); written with Φ² = θθᵀ − φ² E;
* ``sym3_inverse(A)`` / ``sym3_inverse_soa(a00, a01, a02, a11, a12, a22)`` — inverse of
  symmetric 3 × 3 matrices by the adjugate (closed form: LAPACK's per-matrix overhead dominates
  for millions of 3 × 3 systems; accurate for the condition numbers ≤ 1e5 met here);
* ``cross(a, b)`` — a × b on the last axis, 3× faster than ``np.cross`` for small trailing axes.

Example
-------
>>> import numpy as np
>>> C = misalignment_dcm(np.radians([0.0, 0.0, 1.0]))   # 1 degree about z_K
>>> bool(np.allclose(C @ C.T, np.eye(3)))
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputValueError

__all__ = [
    "skew",
    "rotvec_dcm",
    "misalignment_dcm",
    "star_tracker_error_dcm",
    "dcm_from_quat",
    "quat_from_dcm",
    "axis_dcm",
    "cross",
    "rodrigues_coefficients",
    "rotate",
    "rotate_soa",
    "right_jacobian",
    "sym3_cofactors",
    "sym3_inverse",
    "sym3_inverse_soa",
    "ARCSEC",
    "SMALL_ANGLE_LIMIT_ARCSEC",
]

#: one arcsecond in radians
ARCSEC = np.pi / 180.0 / 3600.0
#: THE small-angle range of θ (and of star-tracker σ and θ prior σ): 10° = 36 000″. The estimators
#: rotate exactly (Rodrigues) and linearise the disturbances about θ̂, so θ itself is not limited
#: by a linearisation; what assumes a small misalignment is the error model's first-order
#: treatment of the disturbances together with θ, whose neglected term grows as ~θ²/2 (1.5 % at
#: 10°). DECISION: one limit for the scenario's checks (``orbits.scenario_schema``) and the
#: estimate's warning (``boresight.core.result``): a θ beyond it is computed, and flagged as likely
#: a convention slip (a mirrored axis or a swapped frame gives tens of degrees).
SMALL_ANGLE_LIMIT_ARCSEC = 36000.0


def _as_vectors(v: Any, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise InputValueError(f"Expected {name} to have shape (3,) or (..., 3), got {v.shape}")
    result: np.ndarray = v
    return result


def skew(v: Any) -> np.ndarray:
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


def rotvec_dcm(rotvec: Any) -> np.ndarray:
    """``exp(Φ(v))``: scipy's active rotation matrix for rotation vector ``v`` (rad), batched."""
    v = _as_vectors(rotvec, "rotvec")
    flat = v.reshape(-1, 3)
    from scipy.spatial.transform import Rotation  # scipy on first use (start-up)

    result: np.ndarray = Rotation.from_rotvec(flat).as_matrix().reshape(v.shape[:-1] + (3, 3))
    return result


def misalignment_dcm(theta_rad: Any) -> np.ndarray:
    """Exact misalignment DCM ``exp(−Φ(θ))`` ≈ ``E − Φ(θ)`` (Kiev 2012 eq 24).

    ``C_SK,true = misalignment_dcm(θ) @ C_SK,nominal``: θ is a small rotation of the true
    camera frame relative to its nominal mount, in camera axes. Shape ``(..., 3) -> (..., 3, 3)``.
    """
    return rotvec_dcm(-_as_vectors(theta_rad, "theta_rad"))


def star_tracker_error_dcm(delta_rad: Any) -> np.ndarray:
    """Exact star-tracker error DCM ``exp(Φ(δ))`` ≈ ``E + Φ(δ)`` (Kiev 2012 disturbance model).

    The measured attitude is ``A_meas = star_tracker_error_dcm(δ) @ A_true``.
    """
    return rotvec_dcm(delta_rad)


def dcm_from_quat(q: Any) -> np.ndarray:
    """Attitude matrix ``A(q)`` of a scalar-last quaternion, ``(..., 4) -> (..., 3, 3)``.

    ``A(q)`` maps reference components to body components (``v_B = A(q) v_R``).
    """
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise InputValueError(f"Expected quaternion with shape (4,) or (..., 4) (scalar last), got {q.shape}")
    flat = q.reshape(-1, 4)
    from scipy.spatial.transform import Rotation  # scipy on first use (start-up)

    m = Rotation.from_quat(flat).as_matrix()
    result: np.ndarray = np.swapaxes(m, -1, -2).reshape(q.shape[:-1] + (3, 3))
    return result


def quat_from_dcm(C: Any) -> np.ndarray:
    """Scalar-last quaternion with q4 ≥ 0 whose attitude matrix is ``C``, ``(..., 3, 3) -> (..., 4)``."""
    C = np.asarray(C, dtype=float)
    if C.shape[-2:] != (3, 3):
        raise InputValueError(f"Expected DCM with shape (3, 3) or (..., 3, 3), got {C.shape}")
    flat = np.swapaxes(C.reshape(-1, 3, 3), -1, -2)
    from scipy.spatial.transform import Rotation  # scipy on first use (start-up)

    q = Rotation.from_matrix(flat).as_quat(canonical=True)
    result: np.ndarray = q.reshape(C.shape[:-2] + (4,))
    return result


def axis_dcm(axis: int, angle_rad: Any) -> np.ndarray:
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


# ---------------------------------------------------------------------------- SO(3) helpers (hot paths)

#: below this φ² the Rodrigues coefficients use their Taylor series
SERIES_PHI2 = 1e-8


def cross(a: Any, b: Any) -> np.ndarray:
    """a × b over the last axis (broadcasting); ``np.cross`` is 3× slower on small trailing axes.

    >>> cross(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])).tolist()
    [0.0, 0.0, 1.0]
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def rodrigues_coefficients(phi2: Any) -> tuple[Any, Any, Any]:
    """(a, b, c) = (sin φ/φ, (1 − cos φ)/φ², (φ − sin φ)/φ³) of φ² (any shape), elementwise.

    exp(Φ(v)) = E + a Φ(v) + b Φ(v)² and J_r(θ) = E − b Φ(θ) + c Φ(θ)². Below φ² = 1e-8 the
    series 1 − φ²/6, 1/2 − φ²/24, 1/6 − φ²/120 (truncation error < 1e-17).

    >>> a, b, c = rodrigues_coefficients(np.array([0.0, 1e-4]))
    >>> float(a[0]), float(b[0]), float(c[0])
    (1.0, 0.5, 0.16666666666666666)
    >>> phi = 1e-2
    >>> bool(np.allclose([a[1], b[1], c[1]], [np.sin(phi) / phi, (1 - np.cos(phi)) / phi**2, (phi - np.sin(phi)) / phi**3], rtol=1e-12))
    True
    """
    phi2 = np.asarray(phi2, float)
    small = phi2 < SERIES_PHI2
    if not small.any():  # the usual case: skip the series branch (same values as np.where picks)
        phi = np.sqrt(phi2)
        sin, cos = np.sin(phi), np.cos(phi)
        return sin / phi, (1.0 - cos) / (phi * phi), (phi - sin) / (phi * phi * phi)
    phi = np.sqrt(np.where(small, 1.0, phi2))
    sin, cos = np.sin(phi), np.cos(phi)
    a = np.where(small, 1.0 - phi2 / 6.0, sin / phi)
    b = np.where(small, 0.5 - phi2 / 24.0, (1.0 - cos) / (phi * phi))
    c = np.where(small, 1.0 / 6.0 - phi2 / 120.0, (phi - sin) / (phi * phi * phi))
    return a, b, c


def rotate(rotvec: Any, s: Any) -> np.ndarray:
    """exp(Φ(v)) s by Rodrigues' formula; ``rotvec`` (R, 3), ``s`` (R, ..., 3) → (R, ..., 3).

    The misalignment of eq 24 turns a vector by ``rotate(−θ, s0)`` = exp(−Φ(θ)) s0. Equals
    ``rotvec_dcm(v) @ s`` to round-off, without scipy ``Rotation`` objects or (R, 3, 3)
    temporaries.

    >>> v, s = np.array([[0.0, 0.0, np.pi / 2]]), np.array([[1.0, 0.0, 0.0]])
    >>> bool(np.allclose(rotate(v, s), rotvec_dcm(v) @ s[0], atol=1e-15))
    True
    """
    v = np.asarray(rotvec, float)
    s = np.asarray(s, float)
    a, b, _ = rodrigues_coefficients((v * v).sum(-1))
    shape = (v.shape[0],) + (1,) * (s.ndim - 2) + (3,)
    vv = v.reshape(shape)
    c1 = cross(vv, s)
    result: np.ndarray = s + a.reshape(shape[:-1] + (1,)) * c1 + b.reshape(shape[:-1] + (1,)) * cross(vv, c1)
    return result


def rotate_soa(theta: Any, sx0: Any, sy0: Any, sz0: Any) -> tuple[Any, Any, Any, Any, Any, Any]:
    """exp(−Φ(θ)) s0 component by component (structure of arrays, run axis last).

    ``theta`` (3, R); ``sx0, sy0, sz0`` (…, R). exp(−Φ(θ)) = E + a Φ(v) + b (v vᵀ − φ² E) with
    v = −θ. Returns ``sx, sy, sz, phi2, b, c``: the rotated components and, for the right
    Jacobian at θ (``right_jacobian``), φ² and its coefficients b, c.

    >>> th = np.array([[1e-3], [-2e-3], [5e-4]])
    >>> out = rotate_soa(th, np.array([1.0]), np.array([2.0]), np.array([3.0]))
    >>> bool(np.allclose(np.concatenate(out[:3]), rotate(-th.T, np.array([[1.0, 2.0, 3.0]]))[0], atol=1e-15))
    True
    """
    t0, t1, t2 = theta
    phi2 = t0 * t0 + t1 * t1 + t2 * t2
    a, b, c = rodrigues_coefficients(phi2)
    v0, v1, v2 = -t0, -t1, -t2
    c00, c11, c22 = 1.0 + b * (v0 * v0 - phi2), 1.0 + b * (v1 * v1 - phi2), 1.0 + b * (v2 * v2 - phi2)
    c01, c10 = b * v0 * v1 - a * v2, b * v0 * v1 + a * v2
    c02, c20 = b * v0 * v2 + a * v1, b * v0 * v2 - a * v1
    c12, c21 = b * v1 * v2 - a * v0, b * v1 * v2 + a * v0
    sx = c00 * sx0 + c01 * sy0 + c02 * sz0
    sy = c10 * sx0 + c11 * sy0 + c12 * sz0
    sz = c20 * sx0 + c21 * sy0 + c22 * sz0
    return sx, sy, sz, phi2, b, c


def right_jacobian(theta_rad: Any) -> np.ndarray:
    """J_r(θ) = E − b Φ(θ) + c Φ(θ)² = (1 − cφ²) E − b Φ(θ) + c θθᵀ, ``(..., 3) -> (..., 3, 3)``.

    The SO(3) right Jacobian of exp(Φ(θ)), with b = (1 − cos φ)/φ², c = (φ − sin φ)/φ³
    (``rodrigues_coefficients``); d[exp(−Φ(θ)) s0] = Φ(s(θ)) J_r(θ) dθ. E at θ = 0.

    >>> bool(np.allclose(right_jacobian(np.zeros(3)), np.eye(3)))
    True
    >>> t = np.array([1e-3, -2e-3, 5e-4]); P = skew(t); phi = np.linalg.norm(t)
    >>> ref = np.eye(3) - (1 - np.cos(phi)) / phi**2 * P + (phi - np.sin(phi)) / phi**3 * P @ P
    >>> bool(np.allclose(right_jacobian(t), ref, rtol=0, atol=1e-15))
    True
    """
    theta = _as_vectors(theta_rad, "theta_rad")
    phi2 = np.einsum("...i,...i->...", theta, theta)
    _, a, b = rodrigues_coefficients(phi2)
    t0, t1, t2 = theta[..., 0], theta[..., 1], theta[..., 2]
    d = 1.0 - b * phi2
    at0, at1, at2 = a * t0, a * t1, a * t2
    J = b[..., None, None] * theta[..., :, None] * theta[..., None, :]
    J[..., 0, 0] += d
    J[..., 1, 1] += d
    J[..., 2, 2] += d
    J[..., 0, 1] += at2
    J[..., 0, 2] -= at1
    J[..., 1, 0] -= at2
    J[..., 1, 2] += at0
    J[..., 2, 0] += at1
    J[..., 2, 1] -= at0
    result: np.ndarray = J
    return result


def sym3_cofactors(a00: Any, a01: Any, a02: Any, a11: Any, a12: Any, a22: Any) -> tuple[Any, Any]:
    """Cofactors (c00, c01, c02, c11, c12, c22) and determinant of symmetric 3 × 3 matrices."""
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    return (c00, c01, c02, c11, c12, c22), det


def sym3_inverse(A: Any) -> np.ndarray:
    """Inverse of symmetric 3 × 3 matrices (R, 3, 3) by the adjugate (cofactors / determinant).

    DECISION: closed form instead of ``np.linalg.inv``/``solve``: LAPACK's per-matrix call
    overhead made the batched inverse 30 % of the Monte Carlo Kalman kernel; the information
    matrices here have condition numbers ≤ 1e5, far from where the adjugate loses accuracy.

    >>> A = np.array([[[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]]])
    >>> bool(np.allclose(sym3_inverse(A), np.linalg.inv(A), rtol=1e-14, atol=0))
    True
    """
    (c00, c01, c02, c11, c12, c22), det = sym3_cofactors(A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 1, 1], A[:, 1, 2], A[:, 2, 2])
    out = np.stack([c00, c01, c02, c01, c11, c12, c02, c12, c22], axis=-1).reshape(-1, 3, 3)
    result: np.ndarray = out / det[:, None, None]
    return result


def sym3_inverse_soa(a00: Any, a01: Any, a02: Any, a11: Any, a12: Any, a22: Any) -> list[Any]:
    """Inverse of symmetric 3 × 3 matrices given as 6 component arrays; returns the 6 components.

    Structure-of-arrays form of ``sym3_inverse`` (cofactors times 1/determinant).
    """
    cof, det = sym3_cofactors(a00, a01, a02, a11, a12, a22)
    idet = 1.0 / det
    return [c * idet for c in cof]
