"""Algorithm 1 — projective (homography) solution per image (Kiev 2012 eqs 4-13).

The landmarks are treated as points of a plane. For every image the 8-parameter homography
(eq 5) from a *reference image* of that plane to the measured image is fitted to ≥ 4 landmarks
(eq 12, a normalised DLT), decomposed into the camera attitude C′ and position relative to the
plane (eqs 9-11), and compared with the star tracker's camera attitude C (eq 13, Θ = C′Cᵀ).

Frames (``docs/architecture.md``):

* P — the *plane frame*: origin on the landmark plane, z_P its upward normal, so the landmarks
  are R_M = {X_M, Y_M, 0} (eq 6). ``plane_frame`` builds it from the catalogue (below).
* K — camera; the homography's DCM c_ij of eq 9 is C_PK (P → K); the position r_I of eq 11 is
  the projection centre in P.
* Reference camera (eqs 6-7): at {0, 0, Z*} in P with C = E3, it sees x* = F X_M / Z*,
  y* = F Y_M / Z*. Any Z* > 0 gives the same answer (``z_ref_m``).

Misalignment (eq 13 with eq 24's sign, ``docs/conventions.md``): with C = C_SK,nom A the star tracker's
camera attitude at θ = 0 and C′ = C_PK C_IP the homography's,

    Θ = C′ Cᵀ = exp(−Φ(θ)) ≈ E − Φ(θ),   θ = −rotvec(Θ)   (exact, via scipy ``Rotation``).

Algorithm 1 uses neither GNSS nor any prior θ: the position comes from the homography (eq 11)
and there is nothing to iterate. With coplanar landmarks and noise-free data it is exact.

The plane frame. Real landmarks (and the seminar's M1..M4, heights 50, 100, −20, −80 m) are not
coplanar; the planar model then meets a deterministic error (the Kiev 2012 Algorithm 1 table's
r_p = 0 column). ``plane_frame`` offers:

* ``"best_fit"`` (default) — centroid + the least-squares plane normal (smallest right singular
  vector of the centred catalogue), oriented away from the Earth's centre;
* ``"horizontal"`` — through the centroid, normal along the centroid's geocentric radius
  (heights relative to the local horizontal are ignored, as the seminar's eq 6 does with the
  site's east/north coordinates);
* an explicit ``PlaneFrame`` (e.g. the site's topocentric frame T: ``PlaneFrame(site_g_m, C_GT)``).

In-plane axes: x_P is the geographic east at the plane origin projected on the plane, y_P = z_P ×
x_P. The result does not depend on this choice (the homography is equivariant under in-plane
rotations); it only makes X_M, Y_M readable.

Example
-------
>>> import numpy as np
>>> from boresight import simulate
>>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0), runs=1)
>>> res = estimate_homography(obs, plane="best_fit")
>>> res.theta_per_image_rad.shape, res.mu_arcsec.shape
((1, 10, 3), (1, 10))
>>> np.round(res.mu_arcsec[0, :3], 1).tolist()   # M1..M4 are ±2.5 m off their best-fit plane
[16.2, 32.3, 48.3]
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from boresight.core.gls.structure import images_by_row_count
from boresight.errors import HomographyError, InputValueError, ObservabilityError
from orbits.rotations import ARCSEC

if TYPE_CHECKING:
    from boresight.core.result import Estimate

__all__ = [
    "HomographyError",
    "PlaneFrame",
    "plane_frame",
    "hartley_normalization",
    "fit_homography",
    "apply_homography",
    "decompose_homography",
    "theta_from_misalignment_dcm",
    "HomographyResult",
    "estimate_homography",
    "estimate_alg1",
    "planar_model_error",
]


# ---------------------------------------------------------------------------- plane frame


@dataclass(frozen=True)
class PlaneFrame:
    """Landmark plane frame P: ``origin_g_m`` (..., 3) in G and ``C_GP`` (..., 3, 3) (G → P).

    Rows of ``C_GP`` are x_P, y_P, z_P in Earth-fixed axes; z_P is the plane normal (up).
    """

    origin_g_m: np.ndarray
    C_GP: np.ndarray

    def __post_init__(self) -> None:
        o = np.asarray(self.origin_g_m, float)
        C = np.asarray(self.C_GP, float)
        if o.shape[-1:] != (3,):
            raise InputValueError(f"PlaneFrame.origin_g_m: expected shape (..., 3), got {o.shape}")
        if C.shape[-2:] != (3, 3):
            raise InputValueError(f"PlaneFrame.C_GP: expected shape (..., 3, 3), got {C.shape}")
        err = np.max(np.abs(C @ np.swapaxes(C, -1, -2) - np.eye(3)))
        if not err < 1e-9:
            raise InputValueError(f"PlaneFrame.C_GP must be orthonormal, got |C Cᵀ − E|max = {err:.3g}")
        object.__setattr__(self, "origin_g_m", o)
        object.__setattr__(self, "C_GP", C)

    def to_plane(self, r_g_m: Any) -> np.ndarray:
        """Points in G ``(..., M, 3)`` → P coordinates ``(..., M, 3)`` (z = distance off the plane)."""
        d = np.asarray(r_g_m, float) - self.origin_g_m[..., None, :]
        out: np.ndarray = np.einsum("...ij,...mj->...mi", self.C_GP, d)
        return out


def _unit(v: Any) -> np.ndarray:
    unit: np.ndarray = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return unit


def _east_axes(origin_g: Any, normal_g: Any) -> np.ndarray:
    """Rows x_P (east projected on the plane), y_P = z × x, z_P = normal; (..., 3, 3)."""
    pole = np.broadcast_to([0.0, 0.0, 1.0], origin_g.shape)
    east = np.cross(pole, origin_g)
    # DECISION: at a pole "east" is undefined; fall back to the G x-axis (any in-plane axis works).
    small = np.linalg.norm(east, axis=-1, keepdims=True) < 1e-9 * np.linalg.norm(origin_g, axis=-1, keepdims=True)
    east = np.where(small, np.broadcast_to([1.0, 0.0, 0.0], east.shape), east)
    x = _unit(east - np.sum(east * normal_g, axis=-1, keepdims=True) * normal_g)
    y = np.cross(normal_g, x)
    return np.stack([x, y, normal_g], axis=-2)


def plane_frame(landmark_g_m: Any, method: str = "best_fit", mask: Any = None) -> PlaneFrame:
    """Plane frame P of a landmark catalogue ``(..., M, 3)`` (Earth-fixed, m) for eq 6.

    ``method``: ``"best_fit"`` — centroid and least-squares normal (SVD of the centred points);
    ``"horizontal"`` — centroid and the geocentric radial direction at the centroid.
    ``mask`` ``(..., M)`` selects the landmarks used (default all). Returns a ``PlaneFrame`` with
    leading axes ``...``.

    >>> import numpy as np
    >>> pts = np.array([[7e6, 0, 0], [7e6, 1e3, 0], [7e6, 0, 1e3], [7e6, 1e3, 1e3]])
    >>> P = plane_frame(pts)
    >>> (np.round(P.C_GP[2], 12) + 0.0).tolist(), (np.round(P.to_plane(pts)[:, 2], 9) + 0.0).tolist()
    ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0])
    """
    r = np.asarray(landmark_g_m, float)
    if r.ndim < 2 or r.shape[-1] != 3:
        raise InputValueError(f"landmark_g_m: expected shape (..., M, 3), got {r.shape}")
    w = np.ones(r.shape[:-1]) if mask is None else np.broadcast_to(np.asarray(mask, bool), r.shape[:-1]).astype(float)
    n_used = w.sum(-1)
    if np.any(n_used < 3):
        raise InputValueError(f"plane_frame needs ≥ 3 landmarks, got {int(n_used.min())}")
    c = np.einsum("...m,...mi->...i", w, r) / n_used[..., None]
    if method == "best_fit":
        d = (r - c[..., None, :]) * w[..., None]
        # DECISION: least-squares (orthogonal-distance) plane = smallest right singular vector;
        # it minimises the out-of-plane heights the planar model ignores (±2.5 m for M1..M4).
        normal = np.linalg.svd(d, full_matrices=False)[2][..., 2, :]
        normal = normal * np.where(np.sum(normal * c, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    elif method == "horizontal":
        normal = _unit(c)
    else:
        raise InputValueError(f"plane method must be 'best_fit', 'horizontal' or a PlaneFrame, got {method!r}")
    return PlaneFrame(c, _east_axes(c, normal))


# ---------------------------------------------------------------------------- homography (eqs 4-12)


def hartley_normalization(points: Any, mask: Any = None) -> np.ndarray:
    """Similarity T ``(..., 3, 3)`` that moves the centroid of ``points`` ``(..., M, 2)`` to the
    origin and scales their mean distance from it to √2 (Hartley 1997, "In defense of the
    eight-point algorithm"). Masked-out points (``mask`` False) are ignored.

    >>> import numpy as np
    >>> T = hartley_normalization(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]))
    >>> np.round(T, 6).tolist()
    [[1.0, 0.0, -1.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]]
    """
    p = np.asarray(points, float)
    w = np.ones(p.shape[:-1]) if mask is None else np.broadcast_to(np.asarray(mask, bool), p.shape[:-1]).astype(float)
    n = np.maximum(w.sum(-1), 1.0)
    c = np.einsum("...m,...mi->...i", w, p) / n[..., None]
    dist = np.linalg.norm(p - c[..., None, :], axis=-1)
    mean_dist = np.einsum("...m,...m->...", w, dist) / n
    s = np.sqrt(2.0) / np.where(mean_dist > 0, mean_dist, 1.0)
    T = np.zeros(p.shape[:-2] + (3, 3))
    T[..., 0, 0] = s
    T[..., 1, 1] = s
    T[..., 0, 2] = -s * c[..., 0]
    T[..., 1, 2] = -s * c[..., 1]
    T[..., 2, 2] = 1.0
    return T


def _h(T: Any, p: Any) -> np.ndarray:
    """Apply a 3×3 projective map to (..., M, 2) points."""
    ph = np.concatenate([p, np.ones(p.shape[:-1] + (1,))], axis=-1)
    out = np.einsum("...ij,...mj->...mi", T, ph)
    xy: np.ndarray = out[..., :2] / out[..., 2:3]
    return xy


def apply_homography(H: Any, points: Any) -> np.ndarray:
    """Eq 5/8: x = (a1 x* + a2 y* + a3)/(a7 x* + a8 y* + 1), y likewise; ``(..., 3, 3)``, ``(..., M, 2)``.

    >>> import numpy as np
    >>> H = np.array([[2.0, 0, 1], [0, 2, 0], [0, 0, 1]])
    >>> apply_homography(H, np.array([[1.0, 1.0]])).tolist()
    [[3.0, 2.0]]
    """
    return _h(np.asarray(H, float), np.asarray(points, float))


def fit_homography(src: Any, dst: Any, mask: Any = None, normalize: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """DLT fit of the 8-parameter homography src → dst (Kiev 2012 eqs 5, 12), batched.

    ``src``, ``dst`` ``(..., M, 2)``; ``mask`` ``(..., M)`` (False rows are dropped). Each
    correspondence gives the two rows of eq 12 written homogeneously,
    a1 x* + a2 y* + a3 − x (a7 x* + a8 y* + a9) = 0 (and the y row); the solution is the right
    singular vector of the smallest singular value, de-normalised and scaled to a9 = 1 (eq 5).
    With ``normalize`` (default) both point sets are first conditioned by
    ``hartley_normalization`` and H = T_dst⁻¹ Ĥ T_src.

    Returns ``H`` ``(..., 3, 3)`` (H[..., 2, 2] = 1) and the condition number ``(...,)`` of the
    (normalised) DLT matrix, σ1/σ8 — ∞ with fewer than 4 points, huge for collinear ones.

    >>> import numpy as np
    >>> H0 = np.array([[1.1, 0.2, 3.0], [-0.1, 0.9, -2.0], [1e-3, -2e-3, 1.0]])
    >>> src = np.array([[0.0, 0.0], [10, 0], [0, 10], [10, 10], [5, 3]])
    >>> H, cond = fit_homography(src, apply_homography(H0, src))
    >>> bool(np.allclose(H, H0, rtol=0, atol=1e-12)), bool(cond < 1e3)
    (True, True)
    """
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    if src.shape[-1:] != (2,) or src.ndim < 2:
        raise InputValueError(f"src: expected shape (..., M, 2), got {src.shape}")
    shape = np.broadcast_shapes(src.shape, dst.shape)
    src = np.broadcast_to(src, shape)
    dst = np.broadcast_to(dst, shape)
    m = np.ones(shape[:-1], bool) if mask is None else np.broadcast_to(np.asarray(mask, bool), shape[:-1])
    if normalize:
        Ts = hartley_normalization(src, m)
        Td = hartley_normalization(dst, m)
        u, v = _h(Ts, src), _h(Td, dst)
    else:
        u, v = src, dst
    X, Y = u[..., 0], u[..., 1]
    x, y = v[..., 0], v[..., 1]
    one, zero = np.ones_like(X), np.zeros_like(X)
    row_x = np.stack([X, Y, one, zero, zero, zero, -x * X, -x * Y, -x], axis=-1)
    row_y = np.stack([zero, zero, zero, X, Y, one, -y * X, -y * Y, -y], axis=-1)
    A = np.concatenate([row_x, row_y], axis=-2) * np.concatenate([m, m], axis=-1)[..., None]
    if A.shape[-2] < 9:  # keep Vh square (9×9) so the null vector is always returned
        A = np.concatenate([A, np.zeros(A.shape[:-2] + (9 - A.shape[-2], 9))], axis=-2)
    _, s, vh = np.linalg.svd(A, full_matrices=False)
    with np.errstate(divide="ignore"):
        cond = s[..., 0] / s[..., 7]
    cond = np.where(m.sum(-1) < 4, np.inf, cond)  # < 4 points: rank ≤ 6 < 8, singular by count
    Hn = vh[..., 8, :].reshape(shape[:-2] + (3, 3))
    H = np.linalg.solve(Td, Hn @ Ts) if normalize else Hn
    with np.errstate(divide="ignore", invalid="ignore"):
        H = H / H[..., 2:3, 2:3]
    return H, cond


def decompose_homography(H: Any, focal_length_m: float, z_ref_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera attitude C_PK and position in P from a reference→image homography (Kiev 2012 eq 11).

    ``H`` ``(..., 3, 3)`` in eq 5's form (a1..a8 row-wise, a9 = 1), reference camera at height
    ``z_ref_m`` (Z*). Eq 11:

        q = √(a1² + a4² + F²a7²) = √(a2² + a5² + F²a8²),
        c_{·1} = [a1, a4, −F a7]/q,  c_{·2} = [a2, a5, −F a8]/q,  c_{·3} = c_{·1} × c_{·2},
        r_E = [−Z* a3/(qF), −Z* a6/(qF), Z*/q],  r_P = Cᵀ r_E.

    Returns ``C_PK`` ``(..., 3, 3)`` (a proper rotation) and ``r_p_m`` ``(..., 3)``.

    >>> import numpy as np
    >>> H = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]])   # the reference camera itself
    >>> C, r = decompose_homography(H, 1.0, 400e3)
    >>> np.round(C, 12).tolist() == np.eye(3).tolist(), r.tolist()
    (True, [0.0, 0.0, 400000.0])
    """
    H = np.asarray(H, float)
    F = float(focal_length_m)
    a1, a2, a3 = H[..., 0, 0], H[..., 0, 1], H[..., 0, 2]
    a4, a5, a6 = H[..., 1, 0], H[..., 1, 1], H[..., 1, 2]
    a7, a8 = H[..., 2, 0], H[..., 2, 1]
    q1 = np.sqrt(a1**2 + a4**2 + F**2 * a7**2)
    q2 = np.sqrt(a2**2 + a5**2 + F**2 * a8**2)
    # DECISION: the two expressions for q (eq 11) differ when the data are not exactly planar or
    # are noisy; use their geometric mean (symmetric in the two columns).
    q = np.sqrt(q1 * q2)
    col1 = np.stack([a1, a4, -F * a7], axis=-1) / q[..., None]
    col2 = np.stack([a2, a5, -F * a8], axis=-1) / q[..., None]
    C = np.stack([col1, col2, np.cross(col1, col2)], axis=-1)
    # DECISION: eq 11's C is orthonormal only for exact data; project it on the nearest rotation
    # (polar decomposition via SVD) so Θ = C′Cᵀ is a rotation and θ is well defined.
    U, _, Vt = np.linalg.svd(C)
    C = U @ Vt
    r_e = np.stack([-z_ref_m * a3 / (q * F), -z_ref_m * a6 / (q * F), z_ref_m / q], axis=-1)
    r_p = np.einsum("...ji,...j->...i", C, r_e)
    return C, r_p


def theta_from_misalignment_dcm(Theta: Any) -> np.ndarray:
    """θ (rad) from Θ = C′Cᵀ = exp(−Φ(θ)) (Kiev 2012 eqs 13, 24), exactly: θ = −rotvec(Θ).

    ``Theta`` ``(..., 3, 3)`` → ``(..., 3)``.

    >>> import numpy as np
    >>> from orbits.rotations import misalignment_dcm
    >>> th = np.array([20.0, -15.0, 40.0]) * ARCSEC
    >>> bool(np.allclose(theta_from_misalignment_dcm(misalignment_dcm(th)), th, rtol=0, atol=1e-15))
    True
    """
    T = np.asarray(Theta, float)
    flat = T.reshape(-1, 3, 3)
    # scipy's as_matrix() is the active rotation; Θ = Rotation.from_rotvec(−θ).as_matrix().
    theta: np.ndarray = -Rotation.from_matrix(flat).as_rotvec().reshape(T.shape[:-2] + (3,))
    return theta


# ---------------------------------------------------------------------------- Algorithm 1


@dataclass(frozen=True)
class HomographyResult:
    """Algorithm 1 output. R runs, N images.

    ``theta_rad`` (R, 3) — combined θ (mean of the valid images' θ);
    ``theta_per_image_rad`` (R, N, 3) — θ from each image (eq 13), NaN for a skipped image;
    ``H`` (R, N, 3, 3) — reference → image homography (eq 5 form, a9 = 1);
    ``C_IK`` (R, N, 3, 3) — camera attitude C′ from the homography (inertial → camera);
    ``r_sc_i_m`` (R, N, 3) — projection centre from the homography (eq 11), inertial;
    ``mu_arcsec`` (R, N) — angle of the rotation C′ C_IK,trueᵀ between the estimated and the true
    camera attitude (NaN without ``obs.truth``);
    ``dr_m`` (R, N) — |r_sc,est − r_sc,true| (NaN without truth);
    ``dr_gnss_m`` (R, N) — |r_sc,est − r_GNSS| (always available; GNSS is *not* used by Alg 1);
    ``residuals_m`` (R, K, 2) — each row's measured − homography-mapped reference point (focal
    plane, m; the row model's canonical order; 0 on the rows of a skipped image; identically 0
    with exactly 4 landmarks);
    ``condition`` (R, N) — σ1/σ8 of the normalised DLT matrix; ``valid`` (R, N);
    ``plane`` — the ``PlaneFrame`` of each image (leading axes R, N; one plane per pass);
    ``height_m`` (R, K) — each row's landmark's distance off its image's plane, the part the
    planar model ignores.
    """

    theta_rad: np.ndarray
    theta_per_image_rad: np.ndarray
    H: np.ndarray
    C_IK: np.ndarray
    r_sc_i_m: np.ndarray
    mu_arcsec: np.ndarray
    dr_m: np.ndarray
    dr_gnss_m: np.ndarray
    residuals_m: np.ndarray
    condition: np.ndarray
    valid: np.ndarray
    plane: PlaneFrame
    height_m: np.ndarray

    @property
    def theta_arcsec(self) -> np.ndarray:
        """Combined θ in arcseconds, (R, 3)."""
        return self.theta_rad / ARCSEC

    @property
    def theta_per_image_arcsec(self) -> np.ndarray:
        """Per-image θ in arcseconds, (R, N, 3)."""
        return self.theta_per_image_rad / ARCSEC


def _resolve_plane(obs: Any, plane: Any) -> PlaneFrame:
    """The plane frame of each image, leading axes (R, N).

    DECISION: one plane per pass of a campaign (the landmarks of different passes lie around
    different sites), fitted to the landmarks observed anywhere in that pass.
    """
    R, N = obs.runs, obs.n_images
    if isinstance(plane, PlaneFrame):  # (3,), (R, 3) or (R, N, 3) origins and matching C_GP
        o, C = plane.origin_g_m, plane.C_GP
        if o.ndim == 2:
            o, C = o[:, None], C[:, None]
        try:
            return PlaneFrame(np.broadcast_to(o, (R, N, 3)), np.broadcast_to(C, (R, N, 3, 3)))
        except ValueError:
            raise InputValueError(
                f"plane: a PlaneFrame with origin shape (3,), ({R}, 3) or ({R}, {N}, 3) was expected, got {plane.origin_g_m.shape}"
            ) from None
    if not isinstance(plane, str):
        raise InputValueError(f"plane must be 'best_fit', 'horizontal' or a PlaneFrame, got {plane!r}")
    passes, which = np.unique(obs.pass_index, return_inverse=True)
    o = np.empty((R, passes.size, 3))
    C = np.empty((R, passes.size, 3, 3))
    row_pass = which.reshape(-1)[obs.image_index]
    for k in range(passes.size):  # a handful of passes; runs stay vectorised
        seen = np.unique(obs.target_index[row_pass == k])  # the targets the pass's rows see, in target order
        if seen.size < 3:  # no plane; every image of the pass has < 4 landmarks and is flagged below
            o[:, k], C[:, k] = 0.0, np.eye(3)
            continue
        Pk = plane_frame(obs.landmark_g_m[:, seen], plane)
        o[:, k], C[:, k] = Pk.origin_g_m, Pk.C_GP
    return PlaneFrame(o[:, which.reshape(-1)], C[:, which.reshape(-1)])


def estimate_homography(
    obs: Any,
    *,
    plane: str = "best_fit",
    z_ref_m: float | None = None,
    normalize: bool = True,
    cond_max: float = 1e10,
    on_degenerate: str = "raise",
) -> HomographyResult:
    """Kiev 2012 Algorithm 1 on an ``ObservationSet``, batched over runs and images (each image's DLT
    on its own rows, images with equal numbers of rows at once).

    For each run r and image n: landmarks → plane coordinates (eq 6) → reference image
    x* = F X/Z*, y* = F Y/Z* (eq 7) → homography to the measured image (eq 12, normalised DLT)
    → C′ and r (eq 11) → Θ = C′ Cᵀ with C = C_SK,nom A from the star tracker (eq 13) →
    θ = −rotvec(Θ) (eq 24's sign). The combined θ is the mean over the valid images.

    ``plane``: ``"best_fit"`` | ``"horizontal"`` | a ``PlaneFrame`` (see the module docstring).
    ``z_ref_m``: Z* of eq 6 (default F, so x* = X_M; the result does not depend on it).
    ``normalize``: Hartley conditioning of the DLT (keep it on; off only for comparisons).
    ``cond_max``: an image whose DLT condition number exceeds it, or with < 4 landmarks, is
    degenerate; ``on_degenerate="raise"`` raises ``HomographyError`` naming it, ``"skip"``
    leaves NaN for it and drops it from the combined θ (a run with no usable image still raises).

    >>> import numpy as np
    >>> from boresight import simulate
    >>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0), runs=3)
    >>> res = estimate_homography(obs)
    >>> res.theta_rad.shape, res.C_IK.shape
    ((3, 3), (3, 10, 3, 3))
    """
    if on_degenerate not in ("raise", "skip"):
        raise InputValueError(f"on_degenerate must be 'raise' or 'skip', got {on_degenerate!r}")
    if getattr(obs, "landmark_sight", "geometric") != "geometric":
        from boresight.errors import UnsupportedComputationError

        raise UnsupportedComputationError(
            f"homography (Kiev 2012 Algorithm 1) maps the geometric landmark plane to the image; the set's landmark rows "
            f"carry {obs.landmark_sight!r} (ObservationSet.landmark_sight), which it does not model: use image_plane or "
            "unit_vector"
        )
    F = float(obs.focal_length_m)
    z_ref = F if z_ref_m is None else float(z_ref_m)
    if not (np.isfinite(z_ref) and z_ref > 0):
        raise InputValueError(f"z_ref_m must be a positive number, got {z_ref_m!r}")
    R, N = obs.runs, obs.n_images
    img, tgt = np.asarray(obs.image_index), np.asarray(obs.target_index)

    P = _resolve_plane(obs, plane)  # leading axes (R, N)
    # each row's landmark in its image's plane frame (eq 6), (R, K, 3), and its reference point (eq 7)
    lm_p = np.einsum("rkij,rkj->rki", P.C_GP[:, img], obs.landmark_g_m[:, tgt] - P.origin_g_m[:, img])
    ref = F * lm_p[..., :2] / z_ref  # (R, K, 2)
    # the DLT of each image on its own rows (the slice row_start[n]:row_start[n+1]), images with equal
    # m_n at once: no padding to the largest image
    H = np.empty((R, N, 3, 3))
    cond = np.empty((R, N))
    start = obs.row_start
    for m, ims in images_by_row_count(obs):
        rows = start[ims][:, None] + np.arange(m)  # (u, m)
        H[:, ims], cond[:, ims] = fit_homography(ref[:, rows], obs.xy_m[:, rows], normalize=normalize)

    n_obs = np.asarray(obs.rows_per_image)  # (N,)
    bad = (n_obs[None, :] < 4) | ~(cond <= cond_max)
    if bad.any() and on_degenerate == "raise":
        r, n = (int(i) for i in np.argwhere(bad)[0])
        why = f"only {int(n_obs[n])} landmarks (need ≥ 4)" if n_obs[n] < 4 else "landmarks (nearly) collinear or degenerate"
        raise HomographyError(
            f"Algorithm 1: image {n} (t = {float(obs.t_s[n]):g} s) of run {r}: {why}; "
            f"DLT condition number {float(cond[r, n]):.3g} (limit cond_max = {cond_max:.3g}); "
            f"{int(bad.sum())} of {R * N} run-images degenerate",
            image=n,
            condition_number=float(cond[r, n]),
            run=r,
        )
    valid = ~bad
    if not valid.any(axis=-1).all():
        r = int(np.argmin(valid.any(axis=-1)))
        raise HomographyError(
            f"Algorithm 1: no image of run {r} gives a homography (all {N} images have < 4 landmarks or a "
            f"degenerate layout; best DLT condition number {float(np.min(cond[r])):.3g})",
            condition_number=float(np.min(cond[r])),
            run=r,
        )
    H = np.where(valid[..., None, None], H, np.eye(3))

    # each row's residual against its image's homography, (R, K, 2); 0 on the rows of a skipped image
    mapped = _h(H[:, img], ref[:, :, None, :])[:, :, 0]
    residuals = np.where(valid[:, img, None], obs.xy_m - mapped, 0.0)
    C_PK, r_p = decompose_homography(H, F, z_ref)  # eq 11, (R, N, 3, 3), (R, N, 3)
    C_PI = np.einsum("nij,rnkj->rnik", obs.C_GI, P.C_GP)  # C_GI C_GPᵀ: P → I, (R, N, 3, 3)
    C_IK = C_PK @ np.swapaxes(C_PI, -1, -2)  # C′ (inertial → camera)
    r_est = np.einsum("rnij,rnj->rni", C_PI, r_p) + np.einsum("nij,rnj->rni", obs.C_GI, P.origin_g_m)

    C_nom = obs.nominal_camera_attitude()  # C = C_SK,nom A, (R, N, 3, 3)
    Theta = C_IK @ np.swapaxes(C_nom, -1, -2)  # eq 13
    theta_n = theta_from_misalignment_dcm(Theta)

    nan = np.full((R, N), np.nan)
    mu, dr = nan.copy(), nan.copy()
    truth = obs.truth or {}
    if {"theta_rad", "C_IS"} <= truth.keys():
        from orbits.rotations import misalignment_dcm

        C_true = misalignment_dcm(np.asarray(truth["theta_rad"]))[:, None] @ (obs.C_SK_nominal @ np.asarray(truth["C_IS"]))[None]
        dC = (C_IK @ np.swapaxes(C_true, -1, -2)).reshape(-1, 3, 3)
        mu = np.linalg.norm(Rotation.from_matrix(dC).as_rotvec(), axis=-1).reshape(R, N) / ARCSEC
    if "r_sc_i_m" in truth:
        dr = np.linalg.norm(r_est - np.asarray(truth["r_sc_i_m"]), axis=-1)
    dr_gnss = np.linalg.norm(r_est - obs.r_sc_i_m, axis=-1)

    v = valid[..., None]
    theta_n = np.where(v, theta_n, np.nan)
    # DECISION: unweighted mean of the per-image θ. Each image is an independent exact-fit
    # solution and Algorithm 1 carries no noise model to weight them with; for the small angles
    # here the mean of rotation vectors equals the chordal rotation mean to < 1e-8 rad.
    n_valid = valid.sum(-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        theta = np.where(v, theta_n, 0.0).sum(1) / n_valid
    theta = np.where(n_valid > 0, theta, np.nan)
    return HomographyResult(
        theta_rad=theta,
        theta_per_image_rad=theta_n,
        H=np.where(v[..., None], H, np.nan),
        C_IK=np.where(v[..., None], C_IK, np.nan),
        r_sc_i_m=np.where(v, r_est, np.nan),
        mu_arcsec=np.where(valid, mu, np.nan),
        dr_m=np.where(valid, dr, np.nan),
        dr_gnss_m=np.where(valid, dr_gnss, np.nan),
        residuals_m=residuals,
        condition=cond,
        valid=valid,
        plane=P,
        height_m=lm_p[..., 2],
    )


# ---------------------------------------------------------------------------- boresight.estimate


def estimate_alg1(
    obs: Any, *, weighting: str = "unit", iterate: bool = True, model: Any = None, prior_sigma_arcsec: Any = None, **options: Any
) -> Estimate:
    """``boresight.estimate(obs, algorithm="homography")`` (alias ``"alg1"``): an ``Estimate``.

    ``options`` go to ``estimate_homography`` (``plane``, ``z_ref_m``, ``normalize``,
    ``cond_max``, ``on_degenerate``). Algorithm 1 is a closed-form per-image solution with no
    noise model: only ``weighting="unit"`` (the plain mean over images) is accepted, ``iterate``
    is ignored (nothing to iterate), and ``model`` / ``prior_sigma_arcsec`` are refused.
    ``covariance`` is the empirical covariance of the mean of the per-image θ (sample covariance
    over the valid images / their number; NaN with fewer than 2 images); ``residuals`` are the
    homography fit's (focal plane, m), ``chi2`` their sum of squares, ``dof`` Σ(2 M_n − 8),
    ``condition_number`` the worst image's DLT condition number; ``algorithm_result`` holds the
    full ``HomographyResult`` (per-image θ, μ, δr, …).

    >>> import numpy as np
    >>> from boresight import simulate, estimate
    >>> obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(0))
    >>> est = estimate(obs, algorithm="alg1")
    >>> est.algorithm, est.theta.shape, est.algorithm_result.mu_arcsec.shape
    ('homography', (3,), (1, 10))
    """
    from astropy import units as u

    from boresight.core.result import Estimate

    if weighting != "unit":
        raise InputValueError(
            f"estimate: algorithm 'homography' has no noise model, so only weighting='unit' is available, got {weighting!r}"
        )
    if model is not None:
        raise InputValueError("estimate: algorithm 'homography' does not use a disturbance model; pass model=None")
    if prior_sigma_arcsec is not None:
        raise InputValueError(f"estimate: algorithm 'homography' takes no prior, got prior_sigma_arcsec={prior_sigma_arcsec!r}")
    res = estimate_homography(obs, **options)
    R = obs.runs
    n = res.valid.sum(-1)  # (R,)
    d = np.where(res.valid[..., None], res.theta_per_image_rad - res.theta_rad[:, None], 0.0)
    # DECISION: no noise model, so the covariance is the scatter of the per-image θ about their
    # mean (standard error of the mean): honest about what the images agree on, blind to errors
    # common to all images (e.g. a deterministic non-coplanarity error that varies slowly).
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = np.einsum("rni,rnj->rij", d, d) / ((n - 1) * n)[:, None, None]
    cov = np.where((n >= 2)[:, None, None], cov, np.nan)
    n_obs = np.asarray(obs.rows_per_image)
    dof = np.where(res.valid, 2 * n_obs[None, :] - 8, 0).sum(-1)
    chi2 = np.sum(res.residuals_m**2, axis=(1, 2))
    # DECISION: the planar model's deterministic error (non-coplanar landmarks) is estimated and
    # put into the covariance, so σ contains it, and it is reported as a warning with its size.
    bias = planar_model_error(obs, res.theta_rad, **options)  # (R, 3) rad
    warnings = []
    if np.all(np.isfinite(bias)):
        cov = cov + np.einsum("ri,rj->rij", bias, bias)
        b = np.abs(bias).max(axis=0) / ARCSEC
        if b.max() > 1e-3:
            warnings.append(
                f"Algorithm 1's planar model: deterministic error ≈ {np.array2string(b, precision=2)}″ per axis (max over runs) "
                "on these landmarks, which are not coplanar; it is included in σ (covariance + b bᵀ). A least-squares algorithm has no such error"
            )
    else:
        warnings.append(
            "Algorithm 1's planar-model error could not be estimated (the homography of the exact data failed); σ does not contain it"
        )
    if np.any(~np.isfinite(cov)):
        warnings.append(
            "σ is undefined (NaN) for runs with fewer than 2 usable images: Algorithm 1's σ is the scatter of the per-image θ"
        )

    def squeeze(a: Any) -> Any:
        return a[0] if R == 1 else a

    return Estimate(
        theta=squeeze(res.theta_rad / ARCSEC) * u.arcsec,
        covariance=squeeze(cov / ARCSEC**2) * u.arcsec**2,
        residuals=squeeze(res.residuals_m),
        chi2=squeeze(chi2),
        dof=squeeze(dof),
        condition_number=squeeze(np.nanmax(np.where(res.valid, res.condition, np.nan), axis=-1)),
        iterations=1,
        converged=squeeze(np.ones(R, bool)),
        algorithm="homography",
        weighting="unit",
        residual_unit="m (focal plane)",
        warnings=tuple(warnings),
        planar_model_error_arcsec=squeeze(bias / ARCSEC),
        algorithm_result=res,
    )


def planar_model_error(obs: Any, theta_rad: Any, **options: Any) -> np.ndarray:
    """The deterministic error of Algorithm 1 on ``obs``'s geometry, (R, 3) rad.

    Algorithm 1 is applied to exact, noise-free image points synthesised from the full 3-D model
    (``boresight.core.measurement.predict``) at ``theta_rad``; the difference from ``theta_rad`` is
    its error on non-coplanar landmarks (zero for coplanar ones, up to round-off). The error is a
    smooth function of θ, so evaluated at θ̂ it predicts the error of θ̂ itself
    (``tests/project/test_reliability.py``: on the shipped noise-free Algorithm 1 scenario it predicts the
    actual ~80″ error to a few per cent).
    """
    from boresight.core.measurement import predict_rows

    theta_rad = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    if not np.all(np.isfinite(theta_rad)):
        return np.full((obs.runs, 3), np.nan)
    xy = predict_rows(obs, theta_rad, (obs.image_index, obs.target_index))
    try:
        # synthetic points: the field-of-view check is for measured data, not for a prediction
        exact = replace(obs, xy_m=xy, check_geometry=False)
        syn = estimate_homography(exact, **options)
    except (ObservabilityError, ValueError):
        return np.full((obs.runs, 3), np.nan)
    bias: np.ndarray = syn.theta_rad - theta_rad
    return bias


# estimate(algorithm=...) finds this module through boresight.core.registry (no self-registration).
