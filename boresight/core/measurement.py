"""The exact measurement model of a landmark image (Kiev 2012 eqs 3, 20, 24) and its linearisation.

Shared by every estimator, the disturbance model (``disturbances``) and the Cramér–Rao bound
(``crlb``): the model lives here, not in an algorithm.

Exact model. The predicted camera-frame vector to landmark m in image n is

    s(θ) = exp(−Φ(θ)) s0,   s0 = C_SK,nom A (r_L − r)                      (eqs 20, 24)

(A the star-tracker attitude, r the GNSS position, r_L the catalogue landmark in I) and the
predicted image point is the collinearity projection (x, y) = −F (s_x, s_y)/s_z (eq 3).

A star row (a target at infinity, ``docs/stars.md``) has the same camera and star-tracker stages
and no position stage: s(θ) = exp(−Φ(θ)) C_SK,nom A u_k, u_k the star's apparent direction in I at
the image (``ObservationSet.row_target_vectors_i``; no GNSS, no catalogue position, no terrain).
The projection is scale-free, so s of either kind projects, and linearises, by the same formulas.

Linearisation (derived here; the slide's eq 21 has slips — ``docs/references.md``, "Known slips").
A small change dθ gives ds = −Φ(dθ) s = Φ(s) dθ, and d(x, y) = P ds with the projection
Jacobian P = −F/s_z [[1, 0, −s_x/s_z], [0, 1, −s_y/s_z]]. So the residual
q = (measured − predicted(θ0)) satisfies q ≈ G (θ − θ0) with G = P Φ(s(θ0)). Writing
s ∝ [x, y, −F] this is

    G = [[−x y/F,      F + x²/F,  y],
         [−F − y²/F,   x y/F,     −x]]                                          (cf. eq 21)

whose first-order part [[0, F, y], [−F, 0, −x]] is the corrected eq 21. We keep the
exact G (no field-angle truncation) so re-linearising about the last θ converges to the
exact least-squares solution.

Away from θ0 = 0 the derivative of exp(−Φ(θ)) s0 with respect to the rotation vector θ carries
the SO(3) right Jacobian: ds = Φ(s) J_r(θ0) dθ with
J_r(θ) = E − (1 − cos φ)/φ² Φ(θ) + (φ − sin φ)/φ³ Φ(θ)², φ = |θ| (``orbits.rotations.right_jacobian``),
so G = P Φ(s) J_r(θ0). J_r differs from E by ~|θ0|/2 (1.5e-3 at 10′): without it the
linearisation would miss a finite-difference Jacobian by that much and Gauss-Newton would
converge linearly instead of quadratically.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbits.camera import project
from orbits.rotations import misalignment_dcm, right_jacobian, skew

__all__ = [
    "observation_rows",
    "measured_rows",
    "predicted_camera_vectors",
    "projection_jacobian",
    "predict",
    "predict_rows",
    "residuals",
    "linearize",
    "linearize_rows",
]


def observation_rows(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """(image_index, target_index) (K,) of every observation, in the canonical (image, target) order."""
    return np.asarray(obs.image_index), np.asarray(obs.target_index)


def measured_rows(obs: Any) -> np.ndarray:
    """The measured focal-plane points of every observation (R, K, 2) m, rows as ``observation_rows``."""
    return np.asarray(obs.xy_m)


def predicted_camera_vectors(obs: Any, theta_rad: Any, rows: Any = None) -> np.ndarray:
    """s(θ) = exp(−Φ(θ)) C_SK,nom A (r_L − r) — for a star row exp(−Φ(θ)) C_SK,nom A u_k (module
    docstring) —, (R, K, 3), for ``rows`` = (image_index, target_index) (K,) (default: every
    observation, ``observation_rows``): gathers of the image and target tables.

    ``theta_rad`` broadcasts against the run axis: shape (3,) or (R, 3).
    """
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    C = misalignment_dcm(theta)[:, None] @ obs.nominal_camera_attitude()  # (R, N, 3, 3)
    img, tgt = observation_rows(obs) if rows is None else (np.asarray(a) for a in rows)
    d = obs.row_target_vectors_i(img, tgt)  # (R, K, 3): r_L − r (landmark) or u_k (star)
    s_rows: np.ndarray = np.einsum("rkij,rkj->rki", C[:, img], d)
    return s_rows


def projection_jacobian(s: Any, focal_length_m: float) -> np.ndarray:
    """P = ∂(x, y)/∂s of (x, y) = −F (s_x, s_y)/s_z, ``(..., 3) -> (..., 2, 3)``."""
    s = np.asarray(s, float)
    sz = s[..., 2]
    P = np.zeros(s.shape[:-1] + (2, 3))
    P[..., 0, 0] = -focal_length_m / sz
    P[..., 1, 1] = -focal_length_m / sz
    P[..., 0, 2] = focal_length_m * s[..., 0] / sz**2
    P[..., 1, 2] = focal_length_m * s[..., 1] / sz**2
    return P


def predict_rows(obs: Any, theta_rad: Any, rows: Any = None) -> np.ndarray:
    """Predicted image points (R, K, 2) of the observations ``rows`` = (image_index, target_index)
    (default: every observation) under the exact model (eq 20), by the one collinearity projection
    ``orbits.camera.project`` (eq 3)."""
    rows = observation_rows(obs) if rows is None else rows
    out: np.ndarray = project(predicted_camera_vectors(obs, theta_rad, rows), obs.focal_length_m)
    return out


def predict(obs: Any, theta_rad: Any) -> np.ndarray:
    """Predicted image points under the exact model (eq 20): (R, K, 2) per observation."""
    return predict_rows(obs, theta_rad)


def residuals(obs: Any, theta_rad: Any) -> np.ndarray:
    """Focal-plane residuals measured − predicted at θ, (R, K, 2) m per observation."""
    q: np.ndarray = measured_rows(obs) - predict_rows(obs, theta_rad)
    return q


def linearize(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and Jacobian about ``theta_rad``: ``q ≈ G (θ − θ0)``.

    Returns ``G`` (R, K, 2, 3) in metres per radian and ``q`` (R, K, 2) in metres (measured −
    predicted), one row per observation (``linearize_rows``).
    """
    return linearize_rows(obs, theta_rad, observation_rows(obs), measured_rows(obs))


def linearize_rows(obs: Any, theta_rad: Any, rows: Any, xy_m: Any) -> tuple[np.ndarray, np.ndarray]:
    """``linearize`` on the row model: G (R, K, 2, 3) m/rad and q (R, K, 2) m for the observations
    ``rows`` = (image_index, target_index) (K,) measured at ``xy_m`` (R, K, 2)."""
    s = predicted_camera_vectors(obs, theta_rad, rows)
    q = np.asarray(xy_m, float) - project(s, obs.focal_length_m)  # = xy_m − predict_rows
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    G: np.ndarray = projection_jacobian(s, obs.focal_length_m) @ skew(s) @ right_jacobian(theta)[:, None]
    return G, q
