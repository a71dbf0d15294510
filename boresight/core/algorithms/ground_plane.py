"""Algorithm 2 — ground-plane residuals (Kiev 2012 eqs 14-18), derived for eq 24's sign of θ.

Ground plane. DECISION: each landmark gets its own local plane — the plane through the
catalogue landmark r_L perpendicular to the geocentric radial direction u = r_L/|r_L| (the
landmark's "up" on the seminar's spherical Earth; within 0.2° of the geodetic vertical on
WGS84). Residuals are expressed in that plane's east/north axes (metres). Any plane through
r_L gives zero residual at the true θ; a local plane keeps the intersection well conditioned for
every landmark of a wide field and makes "east/north metres on the ground" meaningful. The
slide's single plane Z = Z_n of one topocentric frame is the special case of a flat field.

Exact model (eq 14 with eq 15 in eq 24's sign). The measured image point gives the camera-frame
direction s′ = [x′, y′, −F] (eq 3); under a misalignment θ it is, in the nominal camera frame,
u(θ) = exp(Φ(θ)) s′ (since C_SK,true = exp(−Φ(θ)) C_SK,nom, eq 24; eq 15's Θᵀ ≈ E − Φ(θ) is the
opposite sign, see docs/estimators.md), and in inertial axes d(θ) = C_IK,nomᵀ u(θ),
C_IK,nom = C_SK,nom A. The ray from the GNSS position r meets the landmark's plane at

    P(θ) = r + λ d,   λ = nᵀ(r_L − r) / nᵀ d                                    (eq 14)

Residual (measured − predicted, eq 17's q_n): q = T (r_L − P(θ0)) with T the 2×3 east/north
rows; at the true θ (no noise) P = r_L. Linearisation (derived here, not copied from eq 16):
du = −Φ(u) J_l(θ) dθ with J_l(θ) = J_r(−θ) (``orbits.rotations.right_jacobian``), and
dP = λ (E − d nᵀ/nᵀd) dd, so

    q ≈ G (θ − θ0),   G = T λ (E − d nᵀ/(nᵀd)) C_IK,nomᵀ (−Φ(u)) J_l(θ0)          (cf. eqs 16-17)

At θ0 = 0, nadir view and a flat plane this reduces to eq 17's G with the columns of θ
negated (eq 15's sign): G ≈ (H/F)·[[0, F, y′], [−F, 0, −x′]] rotated into east/north.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.measurement import measured_rows, observation_rows
from boresight.errors import InputValueError
from orbits.rotations import misalignment_dcm, right_jacobian, skew

__all__ = ["local_frames", "back_project", "predict", "linearize", "residual_map"]


def landmark_plane_axes(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each landmark's plane in Earth-fixed axes: geocentric up (R, M, 3) and the east/north rows
    (R, M, 2, 3) of its local frame (east ⟂ polar axis). A set with star targets (at infinity: no position, no
    plane) is refused (``UnsupportedComputationError``), not fitted through NaN planes; so is a set whose landmark rows
    carry light time and aberration (``ObservationSet.landmark_sight``: the planes here are geometric)."""
    kinds = getattr(obs, "target_kinds", None)
    n_star = 0 if kinds is None else int(np.sum(kinds() == "star"))
    if n_star:
        from boresight.errors import UnsupportedComputationError

        raise UnsupportedComputationError(
            f"ground_plane (Kiev 2012 Algorithm 2) intersects each ray with its landmark's plane; the set has {n_star} star "
            "target(s), at infinity (no position, no plane): use image_plane or unit_vector"
        )
    if getattr(obs, "landmark_sight", "geometric") != "geometric":
        from boresight.errors import UnsupportedComputationError

        raise UnsupportedComputationError(
            f"ground_plane (Kiev 2012 Algorithm 2) intersects each ray with its landmark's geometric plane; the set's "
            f"landmark rows carry {obs.landmark_sight!r} (ObservationSet.landmark_sight), which it does not model: "
            "use image_plane or unit_vector"
        )
    r_g = obs.landmark_g_m  # (R, M, 3)
    up = r_g / np.linalg.norm(r_g, axis=-1, keepdims=True)
    east = np.cross([0.0, 0.0, 1.0], up)
    # DECISION: at a pole (east undefined) fall back to the x axis; no Kiev site is there.
    ne = np.linalg.norm(east, axis=-1, keepdims=True)
    east = np.where(ne > 1e-9, east / np.where(ne > 1e-9, ne, 1.0), [1.0, 0.0, 0.0])
    north = np.cross(up, east)
    return up, np.stack([east, north], axis=-2)


def local_frames(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each observed landmark's plane in inertial axes at its image: normal n (R, K, 3) and the
    east/north rows T (R, K, 2, 3) of its local frame (``landmark_plane_axes`` turned by C_GI), one
    per observation."""
    return _row_frames(obs)


def _row_frames(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    up, T_g = landmark_plane_axes(obs)
    img, tgt = observation_rows(obs)
    C = obs.C_GI[img]
    return np.einsum("kij,rkj->rki", C, up[:, tgt]), np.einsum("kij,rklj->rkli", C, T_g[:, tgt])


def _rays(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """θ (R, 3), u = exp(Φ(θ)) s′ (R, K, 3), the inertial ray d (R, K, 3) and C_KI per observation (R, K, 3, 3)."""
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    xy = measured_rows(obs)
    s_meas = np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -obs.focal_length_m)], axis=-1)
    u = np.einsum("rji,rkj->rki", misalignment_dcm(theta), s_meas)  # exp(Φ(θ)) s′ = exp(−Φ(θ))ᵀ s′
    img, _ = observation_rows(obs)
    C_KI = np.swapaxes(obs.nominal_camera_attitude(), -1, -2)[:, img]  # (R, K, 3, 3)
    d = np.einsum("rkij,rkj->rki", C_KI, u)
    return theta, u, d, C_KI


def _back_project_rows(obs: Any, d: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P (R, K, 3), λ (R, K) and r_L (R, K, 3) of the rays d meeting the landmarks' planes (normals n)."""
    img, tgt = observation_rows(obs)
    r_l = np.einsum("kij,rkj->rki", obs.C_GI[img], obs.landmark_g_m[:, tgt])
    r = obs.r_sc_i_m[:, img]
    nd = np.einsum("...i,...i->...", n, d)
    parallel = np.abs(nd) < 1e-12 * np.linalg.norm(d, axis=-1)
    if np.any(parallel):
        r_, k = (int(v) for v in np.argwhere(parallel)[0])
        raise InputValueError(
            f"ground_plane.back_project: the ray of run {r_}, image {int(img[k])}, landmark "
            f"{str(obs.landmark_ids[tgt[k]])!r} is parallel to the ground plane"
        )
    lam = np.einsum("...i,...i->...", n, r_l - r) / nd
    return r + lam[..., None] * d, lam, r_l


def back_project(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact model (eq 14): ground points P (R, K, 3) in inertial axes where the measured rays meet
    each landmark's local plane, with the ray scale λ (R, K) and direction d (R, K, 3), one per
    observation. A ray parallel to the plane raises ``InputValueError`` (a ``ValueError``) naming its run, image and landmark.
    """
    _, _, d, _ = _rays(obs, theta_rad)
    n, _ = _row_frames(obs)
    P, lam, _ = _back_project_rows(obs, d, n)
    return P, lam, d


def predict(obs: Any, theta_rad: Any) -> np.ndarray:
    """Back-projected ground points in inertial axes (the exact model of eq 14), (R, K, 3)."""
    return back_project(obs, theta_rad)[0]


def _plane_projector(n: Any, d: Any, lam: Any) -> np.ndarray:
    nd = np.einsum("...i,...i->...", n, d)
    nd = np.where(nd == 0, 1.0, nd)
    proj: np.ndarray = lam[..., None, None] * (np.eye(3) - d[..., :, None] * n[..., None, :] / nd[..., None, None])
    return proj


def linearize(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and Jacobian about ``theta_rad``: ``q ≈ G (θ − θ0)`` (Kiev 2012 eq 17, eq 24's sign).

    ``theta_rad`` (3,) or (R, 3). Returns G (R, K, 2, 3) in metres (east/north on the landmark's
    plane) per radian and q (R, K, 2) = T (r_L − P(θ0)) in metres, one row per observation.
    """
    theta, u, d, C_KI = _rays(obs, theta_rad)
    n, T = _row_frames(obs)
    P, lam, r_l = _back_project_rows(obs, d, n)
    q = np.einsum("...ki,...i->...k", T, r_l - P)
    J_l = right_jacobian(-theta)  # J_l(θ) = J_r(−θ)
    du = -skew(u) @ J_l[:, None]  # (R, K, 3, 3)
    G: np.ndarray = T @ _plane_projector(n, d, lam) @ (C_KI @ du)
    return G, q


def residual_map(obs: Any, theta_rad: Any) -> np.ndarray:
    """L = ∂q/∂(image residual), (R, K, 2, 2) per observation: q ≈ L q_image to first order.

    The back-projection of the *predicted* image point lands exactly on r_L, so
    q = T (P(x_pred) − P(x_meas)) ≈ −T ∂P/∂x · (x_meas − x_pred): L = −T λ (E − d nᵀ/nᵀd) C_IK,nomᵀ
    exp(Φ(θ)) E₃₂, with E₃₂ the first two columns of E. Every error source (pixel, star tracker,
    GNSS, catalogue) reaches q through this map, which is how the disturbance model weights
    Algorithm 2 (``boresight.estimate``).
    """
    theta, _, d, C_KI = _rays(obs, theta_rad)
    n, T = _row_frames(obs)
    _, lam, _ = _back_project_rows(obs, d, n)
    R_th = np.swapaxes(misalignment_dcm(theta), -1, -2)[:, None, :, :2]  # exp(Φ(θ)) E₃₂, (R, 1, 3, 2)
    L: np.ndarray = -(T @ (_plane_projector(n, d, lam) @ (C_KI @ R_th)))
    return L
