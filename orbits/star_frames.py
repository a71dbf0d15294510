"""Star frames: what a camera pointed at the sky detects — catalogue stars, false detections, hot pixels.

The camera's true attitude follows the project's measurement chain (``docs/architecture.md``,
"The measurement chain"; Kiev 2012 eqs 23-24): ``C_IK = exp(−Φ(θ)) C_SK,nom C_ES C_IE`` with
``C_SK,nom = C_ESᵀ``. A star is a direction, not a position: its camera vector is
``s_K = C_IK e`` with e its apparent (proper) GCRS direction from the spacecraft
(``orbits.star_apparent``), and its image point is the one projection ``orbits.camera.project``
(eq 3), through the detector's distortion for a calibrated camera (``render_image_points``).

A star is detected when it is inside the square field (``Camera.visible``), not behind the
Earth or its atmosphere (the line of sight keeps ``EARTH_LIMB_MARGIN_M`` = 100 km above the
spherical Earth; below that, refraction and extinction), at or brighter than the detection
limit, and drawn as detected with probability ``detection_probability``; a frame whose
boresight is within ``sun_exclusion_deg`` of the Sun detects no star.

Centroid noise by magnitude (``CentroidNoise``): for a star imaged on a fixed PSF, the centroid
error is σ ≈ w / SNR (w the PSF width; Liebe, "Accuracy performance of star trackers — a
tutorial", IEEE TAES 38(2), 2002, eq 6). Photon-limited, SNR ∝ √flux ∝ 10^(−0.2 m), so
σ(m) = √(σ_floor² + (σ_ref · 10^(0.2 (m − m_ref)))²): ``sigma_reference_m`` at the reference magnitude,
growing 1.58× per magnitude, and a floor ``sigma_floor_m`` for what does not average down
(pixel-phase error, PSF model). The noise is isotropic, per detection, in metres on the focal
plane (as the landmark pixel noise σK). A background-limited camera would follow 10^(0.4 m);
the law is stated, not fitted.

False detections (cosmic-ray hits, debris, stray light) are a Poisson number per frame
(mean ``false_per_frame``), uniform over the field, with magnitudes uniform between
``mag_limit_hp − 3`` and ``mag_limit_hp``. Hot pixels are fixed detector positions
(``hot_pixels_xy_m``) detected in every frame at ``hot_pixel_magnitude`` with no noise.

Draw order (one ``numpy.random.Generator`` from the caller): detection draws (one uniform per
candidate star, in frame-major order), centroid noise (2 normals per detected star), magnitude
noise (1 normal per detected star), the number of false detections per frame, their positions
(2 uniforms each), their magnitudes, and the shuffle of each frame's detections.

Output: padded per-frame arrays ``(F, D)`` — the star's HIP id (``FALSE_ID`` = −1 for a false
detection or hot pixel), measured xy (m), measured magnitude, a validity mask, the kind of each
detection and, for checks, the noise-free image point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .attitude import frame_from_z_and_x
from .camera import Camera, project, render_image_points
from .earth import R_EARTH_M
from .rotations import misalignment_dcm
from .star_apparent import apparent_directions, observer_states
from .star_catalogue import DEFAULT_MAG_LIMIT_HP, StarCatalogue, StarCatalogueError

__all__ = [
    "CentroidNoise",
    "StarDetector",
    "StarFrames",
    "simulate_star_frames",
    "camera_attitude",
    "inertial_hold",
    "slew",
    "zenith_pointing",
    "in_earth_shadow",
    "candidate_pairs",
    "FALSE_ID",
    "KIND_STAR",
    "KIND_FALSE",
    "KIND_HOT_PIXEL",
    "EARTH_LIMB_MARGIN_M",
]

FALSE_ID = -1
KIND_STAR, KIND_FALSE, KIND_HOT_PIXEL = 0, 1, 2
#: a line of sight must pass this far above the spherical Earth (atmosphere: refraction, extinction)
EARTH_LIMB_MARGIN_M = 100e3
#: the apparent-place terms a star's catalogue direction can be off by at any epoch (aberration
#: 20.5″ + 5.3″, Sun deflection near the limb excluded), for the k-d tree pre-selection
_APPARENT_MARGIN_RAD = np.radians(30.0 / 3600.0)


@dataclass(frozen=True)
class CentroidNoise:
    """σ(m) = √(σ_floor² + (σ_ref 10^(0.2 (m − m_ref)))²), metres on the focal plane (module docstring)."""

    sigma_reference_m: float = 1.3e-6
    reference_mag: float = 6.0
    sigma_floor_m: float = 0.3e-6

    def __post_init__(self) -> None:
        for name in ("sigma_reference_m", "reference_mag", "sigma_floor_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not np.isfinite(v) or (name != "reference_mag" and v < 0):
                raise StarCatalogueError(
                    f"CentroidNoise.{name} must be a finite number{' ≥ 0' if name != 'reference_mag' else ''}, got {v!r}"
                )

    def sigma_m(self, magnitude: Any) -> np.ndarray:
        m = np.asarray(magnitude, dtype=float)
        result: np.ndarray = np.hypot(self.sigma_floor_m, self.sigma_reference_m * 10.0 ** (0.2 * (m - self.reference_mag)))
        return result


@dataclass(frozen=True)
class StarDetector:
    """What the camera detects: limit (Hp), detection probability, centroid and magnitude noise,
    false detections per frame, hot pixels (positions in m on the focal plane) and their magnitude,
    and the Sun exclusion angle: a frame whose boresight is within ``sun_exclusion_deg`` of the Sun
    detects no star (stray light floods it). DECISION: 30°, a star tracker's baffle; an
    Earth-imaging camera without a star baffle needs more (set it)."""

    mag_limit_hp: float = DEFAULT_MAG_LIMIT_HP
    detection_probability: float = 1.0
    centroid: CentroidNoise = field(default_factory=CentroidNoise)
    sigma_magnitude: float = 0.1
    false_per_frame: float = 0.0
    hot_pixels_xy_m: Any = ()
    hot_pixel_magnitude: float = 5.0
    sun_exclusion_deg: float = 30.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.detection_probability <= 1.0:
            raise StarCatalogueError(f"StarDetector.detection_probability must be in [0, 1], got {self.detection_probability!r}")
        for name in ("sigma_magnitude", "false_per_frame", "sun_exclusion_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise StarCatalogueError(f"StarDetector.{name} must be a finite number ≥ 0, got {v!r}")
        hot = np.asarray(self.hot_pixels_xy_m, dtype=float).reshape(-1, 2)
        object.__setattr__(self, "hot_pixels_xy_m", hot)


@dataclass(frozen=True)
class StarFrames:
    """F frames padded to D detections. ``hip`` (F, D) the star's HIP id or ``FALSE_ID``; ``xy_m``
    (F, D, 2) measured; ``magnitude`` (F, D) measured; ``mask`` (F, D) valid entries; ``kind``
    (F, D) ``KIND_*``; ``xy_true_m`` (F, D, 2) noise-free point (NaN for false detections);
    ``C_IK`` (F, 3, 3) the true camera attitude; ``sun_blinded`` (F,) frames within the Sun exclusion."""

    hip: np.ndarray
    xy_m: np.ndarray
    magnitude: np.ndarray
    mask: np.ndarray
    kind: np.ndarray
    xy_true_m: np.ndarray
    C_IK: np.ndarray
    sun_blinded: np.ndarray


def camera_attitude(C_IE: Any, theta_rad: Any, C_ES: Any = None) -> np.ndarray:
    """True C_IK = exp(−Φ(θ)) C_SK,nom C_ES C_IE with C_SK,nom = C_ESᵀ (the measurement chain), ``(..., 3, 3)``."""
    C_IE = np.asarray(C_IE, dtype=float)
    C_ES = np.eye(3) if C_ES is None else np.asarray(C_ES, dtype=float)
    result: np.ndarray = misalignment_dcm(np.asarray(theta_rad, dtype=float)) @ np.swapaxes(C_ES, -1, -2) @ C_ES @ C_IE
    return result


def _radec_unit(ra_deg: Any, dec_deg: Any) -> np.ndarray:
    ra, dec = np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float))
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec) * np.ones_like(ra)], axis=-1)


def inertial_hold(ra_deg: Any, dec_deg: Any, roll_deg: Any = 0.0) -> np.ndarray:
    """C_IE with the camera's boresight (−z_E) on (RA, Dec) and x_E towards the north celestial pole
    turned by ``roll_deg`` about the boresight, ``(...,) -> (..., 3, 3)`` (``attitude.frame_from_z_and_x``)."""
    b = _radec_unit(ra_deg, dec_deg)
    roll = np.radians(np.asarray(roll_deg, float))[..., None]
    north = np.array([0.0, 0.0, 1.0]) - b[..., 2:3] * b
    north = np.where(np.linalg.norm(north, axis=-1, keepdims=True) < 1e-9, [1.0, 0.0, 0.0], north)
    north = north / np.linalg.norm(north, axis=-1, keepdims=True)
    east = np.cross(north, b)
    return frame_from_z_and_x(-b, np.cos(roll) * north + np.sin(roll) * east)


def slew(C_IE_start: Any, C_IE_end: Any, fraction: Any) -> np.ndarray:
    """Attitudes along the shortest rotation from ``C_IE_start`` to ``C_IE_end`` (scipy's Slerp) at
    ``fraction`` ∈ [0, 1], ``(N,) -> (N, 3, 3)``."""
    from scipy.spatial.transform import Rotation, Slerp

    C0, C1 = np.asarray(C_IE_start, float), np.asarray(C_IE_end, float)
    key = Rotation.from_matrix(np.stack([C0.T, C1.T]))  # active rotations E → I
    result: np.ndarray = np.swapaxes(Slerp([0.0, 1.0], key)(np.asarray(fraction, float)).as_matrix(), -1, -2)
    return result


def zenith_pointing(r_i_m: Any, v_i_m_s: Any) -> np.ndarray:
    """C_IE with the camera's boresight (−z_E) on the zenith and x_E along the velocity: the nadir law
    (``orbits.attitude.nadir``) turned over, for a pass that scans the sky at the orbital rate
    (on the night side: ``in_earth_shadow``), ``(..., 3) -> (..., 3, 3)``."""
    return frame_from_z_and_x(-np.asarray(r_i_m, float), v_i_m_s)


def in_earth_shadow(r_i_m: Any, sun_direction_i: Any) -> np.ndarray:
    """The spacecraft is in the Earth's shadow (cylindrical umbra of radius R⊕; the penumbra, ≤ 0.3°
    of arc along a LEO orbit, is ignored): behind the Earth from the Sun and within R⊕ of the
    Earth–Sun line. ``sun_direction_i`` is the unit vector to the Sun (e.g. −``astrom["eh"]`` of
    ``orbits.star_apparent.observer_states``), ``(..., 3) -> (...)``."""
    r = np.asarray(r_i_m, float)
    s = np.asarray(sun_direction_i, float)
    along = np.sum(r * s, axis=-1)
    result: np.ndarray = (along < 0) & (np.sum(r * r, axis=-1) - along**2 < R_EARTH_M**2)
    return result


def candidate_pairs(
    catalogue: StarCatalogue, directions_i: Any, radius_rad: float, tdb_jd: float
) -> tuple[np.ndarray, np.ndarray]:
    """(query index, star index) of every catalogue star within ``radius_rad`` (plus the largest
    motion to ``tdb_jd`` and the apparent-place terms) of each inertial direction ``(Q, 3)``:
    a k-d tree on the catalogue's unit vectors at its epoch (scipy ``cKDTree``, chord distance)."""
    from scipy.spatial import cKDTree

    q = np.asarray(directions_i, dtype=float).reshape(-1, 3)
    years = (tdb_jd - catalogue.epoch_jd_tt) / 365.25
    angle = min(radius_rad + catalogue.max_displacement_rad(years) + _APPARENT_MARGIN_RAD, np.pi)
    tree = cKDTree(catalogue.unit_vectors())
    hits = tree.query_ball_point(q, 2.0 * np.sin(angle / 2.0))
    counts = np.array([len(h) for h in hits], dtype=np.int64)
    stars = np.concatenate([np.asarray(h, dtype=np.int64) for h in hits]) if counts.sum() else np.zeros(0, np.int64)
    return np.repeat(np.arange(q.shape[0]), counts), stars


def _earth_blocks(r_i_m: Any, e_i: Any) -> np.ndarray:
    """The line of sight from r along e passes within R⊕ + margin of the Earth's centre, ahead of r."""
    r = np.asarray(r_i_m, float)
    along = -np.sum(r * e_i, axis=-1)  # distance along e to the closest approach (> 0: ahead)
    closest2 = np.sum(r * r, axis=-1) - along**2
    result: np.ndarray = (along > 0) & (closest2 < (R_EARTH_M + EARTH_LIMB_MARGIN_M) ** 2)
    return result


def simulate_star_frames(
    catalogue: StarCatalogue,
    camera: Camera,
    times: Any,
    r_gcrs_m: Any,
    v_gcrs_m_s: Any,
    C_IE: Any,
    theta_rad: Any,
    detector: StarDetector,
    rng: np.random.Generator,
    C_ES: Any = None,
) -> StarFrames:
    """Star frames at ``times`` (F,) for a spacecraft at GCRS ``r_gcrs_m``, ``v_gcrs_m_s`` (F, 3) with
    body attitude ``C_IE`` (F, 3, 3), true misalignment ``theta_rad`` (3,) and mount ``C_ES``
    (default identity). See the module docstring for the model and the draw order."""
    from astropy.time import Time

    t = Time(times).reshape(-1)
    F = t.size
    C_IK = camera_attitude(np.broadcast_to(np.asarray(C_IE, float), (F, 3, 3)), theta_rad, C_ES)
    r = np.asarray(r_gcrs_m, float).reshape(F, 3)
    observer = observer_states(t, r, v_gcrs_m_s)
    boresight_i = -C_IK[:, 2, :]  # −z_K in I
    half_diag = np.arctan(np.sqrt(2.0) * np.tan(np.radians(camera.fov_deg) / 2.0))
    bright = catalogue.subset(catalogue.magnitude_hp <= detector.mag_limit_hp)
    frame, star = candidate_pairs(bright, boresight_i, half_diag, float(np.max(observer.tdb_jd1 + observer.tdb_jd2)))
    e = apparent_directions(bright, observer, star, frame)
    s_k = np.einsum("kij,kj->ki", C_IK[frame], e)
    sun_i = -observer.astrom["eh"]  # the Sun from the observer (ERFA: eh is Sun → observer)
    blinded = np.sum(boresight_i * sun_i, axis=-1) > np.cos(np.radians(detector.sun_exclusion_deg))
    seen = camera.visible(s_k) & ~_earth_blocks(r[frame], e) & ~blinded[frame]
    seen &= rng.uniform(size=seen.shape) < detector.detection_probability
    frame, star, s_k = frame[seen], star[seen], s_k[seen]
    xy_true = project(s_k, camera.focal_length_m)
    mag_true = bright.magnitude_hp[star]
    noise = rng.normal(size=xy_true.shape) * detector.centroid.sigma_m(mag_true)[:, None]
    xy = render_image_points(camera, xy_true, noise)
    mag = mag_true + detector.sigma_magnitude * rng.normal(size=mag_true.shape)
    # false detections: Poisson per frame, uniform in the field
    n_false = rng.poisson(detector.false_per_frame, size=F)
    f_frame = np.repeat(np.arange(F), n_false)
    w = camera.half_width_m
    f_xy = rng.uniform(-w, w, size=(f_frame.size, 2))
    f_mag = rng.uniform(detector.mag_limit_hp - 3.0, detector.mag_limit_hp, size=f_frame.size)
    hot = detector.hot_pixels_xy_m
    h_frame = np.repeat(np.arange(F), hot.shape[0])
    h_xy = np.tile(hot, (F, 1))
    all_frame = np.concatenate([frame, f_frame, h_frame])
    parts = {
        "hip": np.concatenate([bright.hip[star], np.full(f_frame.size + h_frame.size, FALSE_ID)]),
        "xy_m": np.concatenate([xy, f_xy, h_xy]),
        "magnitude": np.concatenate([mag, f_mag, np.full(h_frame.size, detector.hot_pixel_magnitude)]),
        "kind": np.concatenate(
            [np.full(frame.size, KIND_STAR), np.full(f_frame.size, KIND_FALSE), np.full(h_frame.size, KIND_HOT_PIXEL)]
        ),
        "xy_true_m": np.concatenate([xy_true, np.full((f_frame.size + h_frame.size, 2), np.nan)]),
    }
    # pad to (F, D) in a shuffled order within each frame
    order = np.lexsort((rng.uniform(size=all_frame.size), all_frame))
    counts = np.bincount(all_frame, minlength=F)
    D = int(counts.max()) if F else 0
    slot = np.arange(all_frame.size) - np.repeat(np.cumsum(counts) - counts, counts)
    fr = all_frame[order]
    mask = np.zeros((F, D), bool)
    mask[fr, slot] = True
    out: dict[str, np.ndarray] = {}
    for k, v in parts.items():
        fill: Any = FALSE_ID if k == "hip" else (-1 if k == "kind" else np.nan)
        a = np.full((F, D) + v.shape[1:], fill, dtype=v.dtype)
        a[fr, slot] = v[order]
        out[k] = a
    return StarFrames(out["hip"], out["xy_m"], out["magnitude"], mask, out["kind"], out["xy_true_m"], C_IK, blinded)
