"""Star identification: centroids without identities → catalogue stars, under the star tracker's prior.

A user's star frames come as centroids (x, y on the focal plane, optionally a magnitude) with no
identities; the star tracker gives each frame a prior camera attitude
``C_IK,prior = C_SK,nom A`` (``docs/architecture.md``, the measurement chain), wrong by the
misalignment θ and the tracker's error δ. Identification must find which catalogue star each
centroid is, report what it cannot match, and never accept a wrong identity silently.

The algorithm (``identify_stars``), per frame, with k = ``GATE_SIGMAS`` = 5 (a 2-D Gaussian error
leaves a 5σ circle with probability e^(−12.5) = 3.7e-6):

1. **Prior gate.** Each centroid becomes a camera direction d = [x, y, −F]/‖·‖ and, through the
   prior, an inertial direction. Candidates are the catalogue stars (apparent directions at the
   frame's epoch, ``orbits.star_apparent``) within k √(σ_prior² + σ_c²) of it, σ_c the centroid σ
   as an angle (``sigma_centroid_m / F``), found with scipy's ``cKDTree`` on unit vectors
   (``orbits.star_frames.candidate_pairs``); with magnitudes, also abs(m − Hp) ≤ ``mag_gate``.
2. **Consensus (rotation-invariant voting).** A rotation keeps angles: two hypotheses
   (centroid i ↔ star a) and (j ↔ b) agree when abs(∠(d_i, d_j) − ∠(e_a, e_b)) ≤ k √(σ_c,i² + σ_c,j²)
   + ``scale_tolerance`` ∠(d_i, d_j) (an allowance for an uncalibrated focal scale). Starting from
   the hypothesis with the most agreeing partners, hypotheses are added (by votes) when they agree
   with every one already taken (a greedy clique: each centroid and each star used once).
3. **Rotation fit and residual test.** With at least ``min_stars`` in the clique, the camera
   attitude is fitted to them (Wahba's problem by SVD, scipy ``Rotation.align_vectors``, weights
   1/σ_c²); a star whose residual exceeds k σ_c is dropped and the fit repeated; the fitted
   rotation from the prior, δ, must pass δᵀ (σ_prior² E + Σ_fit)⁻¹ δ ≤ 27.95 (χ² with 3 degrees of
   freedom at the same 3.7e-6 tail; Σ_fit = (Σ w (E − d dᵀ))⁻¹, the fit's first-order covariance,
   so a roll poorly fixed by two close stars is not held against the prior). Frames with fewer
   stars are left *unverified* in this pass.
4. **Final gate.** Under the fitted attitude every centroid is matched to the nearest catalogue
   star within k √(σ_c² + σ_fit²) (σ_fit² = (tr Σ_fit − dᵀ Σ_fit d)/2, the fit's error at d); a second catalogue star within twice that
   radius, or within the blend radius (``blend_radius_m``, default three pixels: two stars closer
   than that make one biased centroid), makes it *ambiguous*, two centroids claiming one star are both *conflicts*; neither is
   accepted.
5. **Second pass with a refined prior.** θ is common to every frame: the fitted offsets
   δ_f = rotvec(C_fit C_priorᵀ) of the verified frames give a robust offset (median per axis) and
   spread (1.4826 × MAD per axis, inflated by 1 + 2/√N for N frames, floored at ``sigma_floor_rad``).
   If at least ``min_frames_for_refinement`` frames were verified, the frames left unverified are
   run again through steps 1-4 with the prior corrected by that offset, σ_prior = the spread (a
   few arcseconds) and at least ``min_stars_refined`` stars.

DECISION: ``min_stars_refined`` = 2 — a lone centroid is never accepted by default (status
*unverified*). Geometry cannot check one match: under the refined gate g (≈ 30″) a false
detection lands by chance on a catalogue star with probability n ρ π g² per frame (ρ ≈ 1 star
per square degree at Hp ≤ 8, n detections): 2e-4 per false detection, and at 20 false
detections per frame a wrong lone match did occur (1 in 1 200 frames, ``docs/stars.md``). With
1 the user accepts that risk for the stars alone in their frame (0.5 % of them at the default
limit in a 3.4° field).

DECISION: the identification loops over frames in Python (the voting and the fit are small,
data-dependent problems); the catalogue look-up and the apparent directions are done for all
frames at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from orbits.camera import Camera, direction_from_image
from orbits.star_apparent import apparent_directions, observer_states
from orbits.star_catalogue import StarCatalogue, StarCatalogueError
from orbits.star_frames import candidate_pairs

__all__ = [
    "identify_stars",
    "StarIdentification",
    "STATUS_NAMES",
    "IDENTIFIED",
    "UNMATCHED",
    "AMBIGUOUS",
    "CONFLICT",
    "INCONSISTENT",
    "UNVERIFIED",
    "GATE_SIGMAS",
]

IDENTIFIED, UNMATCHED, AMBIGUOUS, CONFLICT, INCONSISTENT, UNVERIFIED = 0, 1, 2, 3, 4, 5
STATUS_NAMES = ("identified", "unmatched", "ambiguous", "conflict", "inconsistent", "unverified")
GATE_SIGMAS = 5.0
#: the same tail probability, e^(−12.5) = 3.7e-6, for a 3-vector (χ² with 3 degrees of freedom)
_CHI2_3_GATE = 27.95  # scipy.stats.chi2.isf(exp(-12.5), 3)
_EMPTY = -1


@dataclass(frozen=True)
class StarIdentification:
    """Per detection ``(F, D)``: ``hip`` (the identified star's HIP id, −1 otherwise), ``status``
    (``STATUS_NAMES``), ``residual_rad`` (angle to the star under the fitted attitude, NaN if none);
    per frame: ``C_IK_fit`` (F, 3, 3) (NaN where not verified), ``pass_number`` (0 not verified, 1, 2);
    ``offset_rad`` (3,) and ``offset_sigma_rad`` (3,) of the refined prior (NaN if not refined)."""

    hip: np.ndarray
    status: np.ndarray
    residual_rad: np.ndarray
    C_IK_fit: np.ndarray
    pass_number: np.ndarray
    offset_rad: np.ndarray
    offset_sigma_rad: np.ndarray

    def counts(self, mask: Any) -> dict[str, int]:
        """How many valid detections (``mask``) ended in each status."""
        s = self.status[np.asarray(mask, bool)]
        return {name: int(np.sum(s == i)) for i, name in enumerate(STATUS_NAMES)}


def _angle(a: Any, b: Any) -> np.ndarray:
    result: np.ndarray = np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))
    return result


def _fit(d: np.ndarray, e: np.ndarray, w: np.ndarray) -> np.ndarray:
    """C_IK minimising Σ w ‖d − C e‖² (Wahba; scipy's SVD solution): the matrix mapping I to K."""
    from scipy.spatial.transform import Rotation

    rot, _ = Rotation.align_vectors(d, e, weights=w)
    result: np.ndarray = rot.as_matrix()
    return result


def _clique(d: np.ndarray, e: np.ndarray, hi: np.ndarray, ha: np.ndarray, sc: np.ndarray, scale_tol: float) -> np.ndarray:
    """Step 2: hypotheses (centroid hi ↔ star ha) mutually consistent in pair angles, greedy by votes."""
    n = hi.size
    ang_d = _angle(d[hi][:, None], d[hi][None, :])
    ang_e = _angle(e[:, None], e[None, :])
    tol = GATE_SIGMAS * np.hypot(sc[hi][:, None], sc[hi][None, :]) + scale_tol * ang_d
    ok = (np.abs(ang_d - ang_e) <= tol) & (hi[:, None] != hi[None, :]) & (ha[:, None] != ha[None, :])
    votes = np.array([np.unique(hi[ok[h]]).size for h in range(n)])
    taken: list[int] = []
    for h in np.argsort(-votes, kind="stable"):
        if votes[h] == 0:
            break
        if all(ok[h, g] for g in taken):
            taken.append(int(h))
    return np.array(taken, dtype=np.int64)


def _final_gate(
    d: np.ndarray,
    cand_i: np.ndarray,
    cand_e: np.ndarray,
    cand_star: np.ndarray,
    C: np.ndarray,
    gate: np.ndarray,
    n_det: int,
    blend_rad: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step 4: nearest candidate within the gate; ambiguous if another within max(2 × gate, blend); conflicts."""
    star = np.full(n_det, _EMPTY)
    status = np.full(n_det, UNMATCHED)
    resid = np.full(n_det, np.nan)
    ang = _angle(d[cand_i], cand_e @ C.T)
    for i in range(n_det):
        sel = np.flatnonzero(cand_i == i)
        if sel.size == 0:
            continue
        a = ang[sel]
        best = sel[np.argmin(a)]
        if a.min() > gate[i]:
            continue
        if np.sum(a <= max(2.0 * gate[i], blend_rad)) > 1:
            status[i] = AMBIGUOUS
            continue
        star[i], status[i], resid[i] = cand_star[best], IDENTIFIED, a.min()
    claimed, n_claims = np.unique(star[star != _EMPTY], return_counts=True)
    for s in claimed[n_claims > 1]:
        clash = star == s
        star[clash], status[clash], resid[clash] = _EMPTY, CONFLICT, np.nan
    return star, status, resid


def _frame(
    d: np.ndarray,
    sc: np.ndarray,
    cand_i: np.ndarray,
    cand_star: np.ndarray,
    cand_e: np.ndarray,
    C_prior: np.ndarray,
    sigma_prior: float,
    min_stars: int,
    scale_tol: float,
    blend_rad: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Steps 1-4 for one frame: (star row per centroid, status, residual, fitted C_IK or None)."""
    n_det = d.shape[0]
    gate1 = GATE_SIGMAS * np.hypot(sigma_prior, sc)
    inside = _angle(d[cand_i], cand_e @ C_prior.T) <= gate1[cand_i]
    hi, ha, he = cand_i[inside], cand_star[inside], cand_e[inside]
    status = np.full(n_det, UNVERIFIED)
    if hi.size == 0:
        return np.full(n_det, _EMPTY), np.full(n_det, UNMATCHED), np.full(n_det, np.nan), None
    status[np.setdiff1d(np.arange(n_det), hi)] = UNMATCHED
    if min_stars <= 1 and np.unique(hi).size == 1 and hi.size == 1:
        C = C_prior  # a lone centroid under a tight prior: step 4 decides, with the prior's σ in the gate
        sc = np.hypot(sc, sigma_prior)
    else:
        taken = _clique(d, he, hi, ha, sc, scale_tol)
        if taken.size < max(min_stars, 2):
            return np.full(n_det, _EMPTY), status, np.full(n_det, np.nan), None
        hi_t, he_t = hi[taken], he[taken]
        while True:
            C = _fit(d[hi_t], he_t, 1.0 / sc[hi_t] ** 2)
            r = _angle(d[hi_t], he_t @ C.T)
            worst = int(np.argmax(r / sc[hi_t]))
            if r[worst] <= GATE_SIGMAS * sc[hi_t][worst]:
                break
            hi_t, he_t = np.delete(hi_t, worst), np.delete(he_t, worst, axis=0)
            if hi_t.size < max(min_stars, 2):
                return np.full(n_det, _EMPTY), status, np.full(n_det, np.nan), None
        from scipy.spatial.transform import Rotation

        # the fit's covariance (first order): H = Σ w (E − d dᵀ), Σ_fit = H⁻¹ (rotation in K axes)
        dd = d[hi_t]
        H = np.einsum("k,kij->ij", 1.0 / sc[hi_t] ** 2, np.eye(3) - dd[:, :, None] * dd[:, None, :])
        cov_fit = np.linalg.inv(H)
        delta = Rotation.from_matrix(C @ C_prior.T).as_rotvec()
        if delta @ np.linalg.solve(sigma_prior**2 * np.eye(3) + cov_fit, delta) > _CHI2_3_GATE:
            status[hi_t] = INCONSISTENT
            return np.full(n_det, _EMPTY), status, np.full(n_det, np.nan), None
        # each centroid's predicted position error from the fit: (tr Σ_fit − dᵀ Σ_fit d) / 2 per axis
        var_fit = (np.trace(cov_fit) - np.einsum("ki,ij,kj->k", d, cov_fit, d)) / 2.0
        sc = np.sqrt(sc**2 + var_fit)
    star, status, resid = _final_gate(d, hi, he, ha, C, GATE_SIGMAS * sc, n_det, blend_rad)
    return star, status, resid, C


def identify_stars(
    catalogue: StarCatalogue,
    camera: Camera,
    times: Any,
    r_gcrs_m: Any,
    v_gcrs_m_s: Any,
    xy_m: Any,
    mask: Any,
    C_IK_prior: Any,
    sigma_prior_rad: float,
    sigma_centroid_m: Any,
    magnitude: Any = None,
    mag_gate: float = 1.0,
    min_stars: int = 3,
    min_stars_refined: int = 2,
    scale_tolerance: float = 1e-4,
    min_frames_for_refinement: int = 5,
    sigma_floor_rad: float = 1e-6,
    blend_radius_m: float | None = None,
) -> StarIdentification:
    """Identify the centroids ``xy_m`` (F, D, 2) (valid where ``mask``) of F frames (module docstring).

    ``times``, ``r_gcrs_m``, ``v_gcrs_m_s`` give each frame's epoch and the spacecraft's GCRS state;
    ``C_IK_prior`` (F, 3, 3) the prior camera attitude (``C_SK,nom A``) with isotropic σ
    ``sigma_prior_rad`` per axis (θ's prior σ and the tracker's, combined); ``sigma_centroid_m``
    the centroid σ (scalar or (F, D)); ``magnitude`` (F, D) optional measured magnitudes (Hp);
    ``blend_radius_m`` the separation below which two stars blend into one centroid (default three
    pixels, ``3 × camera.pixel_pitch_m``, or 0 without a pitch).
    """
    from astropy.time import Time

    xy = np.asarray(xy_m, float)
    F, D = xy.shape[:2]
    m = np.asarray(mask, bool)
    if xy.shape != (F, D, 2) or m.shape != (F, D):
        raise StarCatalogueError(f"identify_stars: xy_m must be (F, D, 2) and mask (F, D), got {xy.shape} and {m.shape}")
    if not (np.isfinite(sigma_prior_rad) and sigma_prior_rad > 0):
        raise StarCatalogueError(f"identify_stars: sigma_prior_rad must be a positive number, got {sigma_prior_rad!r}")
    if blend_radius_m is None:
        blend_radius_m = 3.0 * camera.pixel_pitch_m if camera.pixel_pitch_m else 0.0
    blend_rad = float(blend_radius_m) / camera.focal_length_m
    sc_all = np.broadcast_to(np.asarray(sigma_centroid_m, float), (F, D)) / camera.focal_length_m
    C_prior = np.broadcast_to(np.asarray(C_IK_prior, float), (F, 3, 3))
    t = Time(times).reshape(-1)
    observer = observer_states(t, r_gcrs_m, v_gcrs_m_s)
    d_all = direction_from_image(np.where(m[..., None], xy, 0.0), camera.focal_length_m)
    d_all = d_all / np.linalg.norm(d_all, axis=-1, keepdims=True)

    def candidates(
        sigma_prior: float, frames: np.ndarray, C_use: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        fd = np.argwhere(m[frames])
        f_of = frames[fd[:, 0]]
        # the centroids' inertial directions under the prior in use (the refined one in the second pass: its look-up
        # radius is sized for the refined σ, so it must be centred on the refined directions)
        u = np.einsum("kji,kj->ki", C_use[f_of], d_all[f_of, fd[:, 1]])
        radius = GATE_SIGMAS * np.hypot(sigma_prior, float(np.max(sc_all[m]))) * 2.0
        q, star = candidate_pairs(catalogue, u, radius, float(np.max(observer.tdb_jd1 + observer.tdb_jd2)))
        f, det = f_of[q], fd[q, 1]
        if magnitude is not None:
            keep = np.abs(np.asarray(magnitude, float)[f, det] - catalogue.magnitude_hp[star]) <= mag_gate
            f, det, star = f[keep], det[keep], star[keep]
        return f, det, star, apparent_directions(catalogue, observer, star, f)

    hip = np.full((F, D), -1, dtype=np.int64)
    status = np.full((F, D), UNMATCHED)
    resid = np.full((F, D), np.nan)
    C_fit = np.full((F, 3, 3), np.nan)
    pass_number = np.zeros(F, dtype=np.int64)

    def run(frames: np.ndarray, C_use: np.ndarray, sigma_prior: float, min_n: int, number: int) -> None:
        f, det, star, e = candidates(sigma_prior, frames, C_use)
        order = np.argsort(f, kind="stable")
        f, det, star, e = f[order], det[order], star[order], e[order]
        bounds = np.searchsorted(f, frames), np.searchsorted(f, frames, side="right")
        for k, fi in enumerate(frames):
            valid = np.flatnonzero(m[fi])
            sl = slice(bounds[0][k], bounds[1][k])
            pos = np.searchsorted(valid, det[sl])  # candidate's centroid as an index into valid
            row, st, rs, C = _frame(
                d_all[fi, valid],
                sc_all[fi, valid],
                pos,
                star[sl],
                e[sl],
                C_use[fi],
                sigma_prior,
                min_n,
                scale_tolerance,
                blend_rad,
            )
            status[fi, valid] = st
            if C is None:
                continue
            ok = row != _EMPTY
            hip[fi, valid[ok]] = catalogue.hip[row[ok]]
            resid[fi, valid] = rs
            C_fit[fi], pass_number[fi] = C, number

    run(np.arange(F), C_prior, float(sigma_prior_rad), min_stars, 1)
    offset, spread = np.full(3, np.nan), np.full(3, np.nan)
    done = np.flatnonzero(pass_number == 1)
    if done.size >= min_frames_for_refinement:
        from scipy.spatial.transform import Rotation

        dlt = Rotation.from_matrix(np.einsum("fij,fkj->fik", C_fit[done], C_prior[done])).as_rotvec()
        offset = np.median(dlt, axis=0)
        spread = 1.4826 * np.median(np.abs(dlt - offset), axis=0) * (1.0 + 2.0 / np.sqrt(done.size))
        sigma2 = max(float(np.max(spread)), sigma_floor_rad)
        rest = np.flatnonzero((pass_number == 0) & m.any(axis=1))
        if rest.size:
            C_ref = Rotation.from_rotvec(offset).as_matrix() @ C_prior
            run(rest, C_ref, sigma2, min_stars_refined, 2)
    return StarIdentification(hip, status, resid, C_fit, pass_number, offset, spread)
