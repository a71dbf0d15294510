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

from orbits.rotations import misalignment_dcm, right_jacobian, skew

__all__ = ["local_frames", "back_project", "predict", "linearize", "residual_map"]


def landmark_plane_axes(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each landmark's plane in Earth-fixed axes: geocentric up (R, M, 3) and the east/north rows
    (R, M, 2, 3) of its local frame (east ⟂ polar axis)."""
    r_g = obs.landmark_g_m  # (R, M, 3)
    up = r_g / np.linalg.norm(r_g, axis=-1, keepdims=True)
    east = np.cross([0.0, 0.0, 1.0], up)
    # DECISION: at a pole (east undefined) fall back to the x axis; no Kiev site is there.
    ne = np.linalg.norm(east, axis=-1, keepdims=True)
    east = np.where(ne > 1e-9, east / np.where(ne > 1e-9, ne, 1.0), [1.0, 0.0, 0.0])
    north = np.cross(up, east)
    return up, np.stack([east, north], axis=-2)


def local_frames(obs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each landmark's plane in inertial axes at each image: normal n (R, N, M, 3) and the
    east/north rows T (R, N, M, 2, 3) of its local frame (``landmark_plane_axes`` turned by C_GI)."""
    up, T_g = landmark_plane_axes(obs)
    n_i = np.einsum("nij,rmj->rnmi", obs.C_GI, up)
    T_i = np.einsum("nij,rmkj->rnmki", obs.C_GI, T_g)
    return n_i, T_i


def _rays(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    F = obs.focal_length_m
    mask = obs.mask[None, :, :, None]
    s_meas = np.concatenate([obs.xy_m, np.full(obs.xy_m.shape[:-1] + (1,), -F)], axis=-1)
    s_meas = np.where(mask, s_meas, [0.0, 0.0, -F])
    u = np.einsum("rji,rnmj->rnmi", misalignment_dcm(theta), s_meas)  # exp(Φ(θ)) s′ = exp(−Φ(θ))ᵀ s′
    C_KI = np.swapaxes(obs.nominal_camera_attitude(), -1, -2)  # (R, N, 3, 3)
    d = np.einsum("rnij,rnmj->rnmi", C_KI, u)
    return theta, u, d, C_KI


def back_project(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact model (eq 14): ground points P (R, N, M, 3) in inertial axes where the measured rays
    meet each landmark's local plane, with the ray scale λ (R, N, M) and direction d (R, N, M, 3).

    Masked entries, and rays that do not meet the plane in front of the camera, give P = r_L
    and λ = 0 for masked ones; a ray parallel to the plane raises ``ValueError``.
    """
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    _, _, d, _ = _rays(obs, theta_rad)
    n, _ = local_frames(obs)
    r_l = obs.landmarks_i_m()
    rel = r_l - obs.r_sc_i_m[:, :, None, :]
    nd = np.einsum("...i,...i->...", n, d)
    valid = obs.mask[None]
    if np.any(valid & (np.abs(nd) < 1e-12 * np.linalg.norm(d, axis=-1))):
        idx = tuple(int(i) for i in np.argwhere(valid & (np.abs(nd) < 1e-12 * np.linalg.norm(d, axis=-1)))[0])
        raise ValueError(
            f"ground_plane.back_project: the ray of observation {idx} (run, image, landmark) is parallel to the ground plane"
        )
    lam = np.where(valid, np.einsum("...i,...i->...", n, rel) / np.where(valid, nd, 1.0), 0.0)
    P = np.where(valid[..., None], obs.r_sc_i_m[:, :, None, :] + lam[..., None] * d, r_l)
    return P, lam, d


def predict(obs: Any, theta_rad: Any) -> np.ndarray:
    """Back-projected ground points (R, N, M, 3) in inertial axes (the exact model of eq 14)."""
    return back_project(obs, theta_rad)[0]


def _plane_projector(n: Any, d: Any, lam: Any) -> np.ndarray:
    nd = np.einsum("...i,...i->...", n, d)
    nd = np.where(nd == 0, 1.0, nd)
    proj: np.ndarray = lam[..., None, None] * (np.eye(3) - d[..., :, None] * n[..., None, :] / nd[..., None, None])
    return proj


def linearize(obs: Any, theta_rad: Any) -> tuple[np.ndarray, np.ndarray]:
    """Residuals and Jacobian about ``theta_rad``: ``q ≈ G (θ − θ0)`` (Kiev 2012 eq 17, eq 24's sign).

    ``theta_rad`` (3,) or (R, 3). Returns G (R, N, M, 2, 3) in metres (east/north on the
    landmark's plane) per radian and q (R, N, M, 2) = T (r_L − P(θ0)) in metres; zero where masked.
    """
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    theta, u, d, C_KI = _rays(obs, theta_rad)
    P, lam, _ = back_project(obs, theta)
    n, T = local_frames(obs)
    r_l = obs.landmarks_i_m()
    m = obs.mask[None, :, :, None]
    q = np.where(m, np.einsum("...ki,...i->...k", T, r_l - P), 0.0)
    J_l = right_jacobian(-theta)  # J_l(θ) = J_r(−θ)
    du = -skew(u) @ J_l[:, None, None]  # (R, N, M, 3, 3)
    dd = np.einsum("rnij,rnmjk->rnmik", C_KI, du)
    G = T @ _plane_projector(n, d, lam) @ dd
    return np.where(m[..., None], G, 0.0), q


def residual_map(obs: Any, theta_rad: Any) -> np.ndarray:
    """L = ∂q/∂(image residual), (R, N, M, 2, 2): q ≈ L q_image to first order.

    The back-projection of the *predicted* image point lands exactly on r_L, so
    q = T (P(x_pred) − P(x_meas)) ≈ −T ∂P/∂x · (x_meas − x_pred): L = −T λ (E − d nᵀ/nᵀd) C_IK,nomᵀ
    exp(Φ(θ)) E₃₂, with E₃₂ the first two columns of E. Every error source (pixel, star tracker,
    GNSS, catalogue) reaches q through this map, which is how the disturbance model weights
    Algorithm 2 (``boresight.estimate``).
    """
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    theta, _, d, C_KI = _rays(obs, theta_rad)
    _, lam, _ = back_project(obs, theta)
    n, T = local_frames(obs)
    R_th = np.swapaxes(misalignment_dcm(theta), -1, -2)[:, :, :2]  # exp(Φ(θ)) E₃₂, (R, 3, 2)
    dP = _plane_projector(n, d, lam) @ np.einsum("rnij,rjk->rnik", C_KI, R_th)[:, :, None]
    L = -(T @ dP)
    return np.where(obs.mask[None, :, :, None, None], L, 0.0)
