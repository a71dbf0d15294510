"""The unit-vector algorithm (Kiev 2012 eqs 29-31), derived for eq 24's sign of θ.

Exact model (eq 29). The measured unit vector to landmark i in camera axes is
e_iK = s′/|s′|, s′ = [x′, y′, −F]; the predicted one is

    e*_iK(θ) = exp(−Φ(θ)) C_SK,nom A e_iI,   e_iI = (r_L − r)/|r_L − r|            (eqs 24, 29)

Linearisation (derived here). d e* = Φ(e*) J_r(θ0) dθ (``orbits.rotations.right_jacobian``),
so the residual e_iK − e*_iK(θ0) ≈ Φ(e*) J_r(θ0) (θ − θ0). At θ0 = 0 this is
e_iK − e*_iK = e*_iK × θ ≈ e_iK × θ = Φ(e_iK) θ — eq 30 as printed, which is therefore
consistent with eq 24's sign (the slide states its right side loosely, ``docs/references.md``: the exact statement is
the one above, with e* in place of e to first order). Eq 31's normal equations
Γ θ = g, Γ = Σ Φ²(e), g = −Σ Φ(e) e* are eq 18's B θ = y multiplied by −1:
Φ(e)ᵀΦ(e) = −Φ²(e) and Φ(e)ᵀ(e − e*) = Φ(e) e*.

DECISION: the 3-vector residual lies (to first order) in the plane ⟂ e*, so its 3×3
covariance is singular. We express it in a 2-D orthonormal tangent basis T (rows t1, t2 ⟂ e*):
q = T (e − e*), G = T Φ(e*) J_r. Because Φ(e*) has its columns ⟂ e*, GᵀG is unchanged
(−Σ Φ²(e*) as in eq 31) while weighted forms get a regular 2×2 covariance per landmark.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.measurement import measured_rows, observation_rows
from orbits.rotations import misalignment_dcm, right_jacobian, skew

__all__ = ["predict", "tangent_basis", "linearize", "residual_map", "measured_unit_vectors"]


def _measured_rows(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """s′ = [x′, y′, −F] per observation (R, K, 3) and its length |s′| (R, K)."""
    xy = measured_rows(obs)
    s = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -obs.focal_length_m)], axis=-1)
    return s, np.linalg.norm(s, axis=-1)


def measured_unit_vectors(obs: Any) -> np.ndarray:
    """e_iK = s′/|s′|, s′ = [x′, y′, −F], (R, K, 3) per observation."""
    s, ns = _measured_rows(obs)
    e: np.ndarray = s / ns[..., None]
    return e


def _predict_rows(obs: Any, theta_rad: Any) -> np.ndarray:
    """e*_iK(θ) per observation (R, K, 3): the image's camera attitude applied to the unit line of
    sight from the GNSS position to the catalogue landmark, or to a star's apparent direction
    (``ObservationSet.row_target_vectors_i``; gathers, no images × targets array)."""
    img, tgt = observation_rows(obs)
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    C = misalignment_dcm(theta)[:, None] @ obs.nominal_camera_attitude()  # (R, N, 3, 3)
    d = obs.row_target_vectors_i(img, tgt)  # r_L − r (a landmark) or the apparent direction u_k (a star)
    e_i = d / np.linalg.norm(d, axis=-1, keepdims=True)  # eq 29's e_iI
    out: np.ndarray = np.einsum("rkij,rkj->rki", C[:, img], e_i)
    return out


def predict(obs: Any, theta_rad: Any) -> np.ndarray:
    """e*_iK(θ) = exp(−Φ(θ)) C_SK,nom A e_iI (eq 29), (R, K, 3) per observation."""
    return _predict_rows(obs, theta_rad)


def tangent_basis(e: Any) -> np.ndarray:
    """Rows t1, t2 of an orthonormal basis ⟂ e, ``(..., 3) -> (..., 2, 3)``.

    t1 is the camera x axis made orthogonal to e, t2 = e × t1 (well defined for any direction
    within 90° of the boresight).

    >>> T = tangent_basis(np.array([0.0, 0.0, -1.0]))
    >>> T.tolist()
    [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
    """
    e = np.asarray(e, float)
    x = np.zeros_like(e)
    x[..., 0] = 1.0
    t1 = x - e[..., 0:1] * e
    t1 = t1 / np.linalg.norm(t1, axis=-1, keepdims=True)
    t2 = np.cross(e, t1)
    return np.stack([t1, t2], axis=-2)


def linearize(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and Jacobian about ``theta_rad``: ``q ≈ G (θ − θ0)`` (Kiev 2012 eq 30, eq 24's sign).

    ``theta_rad`` (3,) or (R, 3). Returns G (R, K, 2, 3) (dimensionless, rad/rad) and
    q = T (e − e*(θ0)) (R, K, 2) in radians per observation, T = ``tangent_basis(e*(θ0))``.
    """
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    e_star = _predict_rows(obs, theta)
    T = tangent_basis(e_star)
    s, ns = _measured_rows(obs)
    q = np.einsum("...ki,...i->...k", T, s / ns[..., None] - e_star)
    G: np.ndarray = T @ skew(e_star) @ right_jacobian(theta)[:, None]
    return G, q


def residual_map(obs: Any, theta_rad: Any) -> np.ndarray:
    """L = ∂q/∂(image residual), (R, K, 2, 2) per observation: q ≈ L q_image to first order.

    e* is exactly the unit vector of the predicted image point, so q = T (e(x_meas) − e(x_pred))
    ≈ T ∂e/∂x (x_meas − x_pred), ∂e/∂x = (E − e eᵀ) E₃₂ / |s′|.
    """
    T = tangent_basis(_predict_rows(obs, theta_rad))
    s, ns = _measured_rows(obs)
    e = s / ns[..., None]
    de = (np.eye(3) - e[..., :, None] * e[..., None, :])[..., :, :2] / ns[..., None, None]
    L: np.ndarray = T @ de
    return L
