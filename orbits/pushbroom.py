"""Pushbroom (line-scanner) geometry: position and attitude per line, direct and inverse location.

A pushbroom image is a stack of lines, each its own exposure at its own time (``docs/pushbroom.md``).
The sensor (look directions per chip pixel, on the frame camera's collinearity model) and the line
datation are in ``orbits.camera`` (``LineSensor``, ``LinearLineDatation``, ``TabulatedLineDatation``);
this module adds the platform and the Earth:

* **Position per line** — Lagrange interpolation (``orbits.interpolate.lagrange_values``, degree 7
  by default) of orbit samples (t, r, v) in I (GCRS), the way an OEM is read.
* **Attitude per line** — SLERP (scipy ``Slerp``) of the star tracker's attitude quaternions (the
  inertial → S map A, scalar-last), then the measurement chain of ``docs/architecture.md``:
  ``C_IK(t) = exp(−Φ(θ)) exp(−Φ(j(t))) C_SK,nom A(t)``, ``C_SK,nom = C_ESᵀ`` (Kiev 2012 eqs 23-24),
  with j(t) the attitude jitter the tracker samples do not carry (camera axes):
  j_a(t) = Σ_f A_fa sin(2π f t + φ_fa) for each axis a.
* **Earth orientation** — ``itrs_to_gcrs_dcm`` (astropy: precession, nutation, polar motion, UT1)
  evaluated on a grid (1 s by default) and SLERPed between: the rotation is uniform about an axis
  that moves by < 1e-10 rad in a second, so the SLERP is exact to ~1e-13 rad
  (``tests/orbits/test_pushbroom.py`` checks it against astropy at mid-points).
* **The forward-model parameters** (``LineScanParameters``): θ, a line-time offset δt, a relative
  line-period error ε (t(L) = t_nom(L) + δt + ε (t_nom(L) − t_nom(L_ref))), per-chip look-angle
  offsets, a focal scale κ and the jitter's frequencies, amplitudes and phases. The same functions
  serve the simulator's truth and (later) the estimator's predictions and finite-difference Jacobians.

**Light time and aberration** (both modelled, both switchable, as Rugged's flags: ``SightCorrections``): the
one implementation is ``orbits.sight`` (``apparent_sight_i``, ``earth_turn``, ``remove_aberration``; its docstring
derives them), which the frame camera's landmark rows use too; this module calls it on the strip's position,
velocity and C_GI interpolated at each line's time. The Earth's spin w (ITRS axes) is the rotation between the first
and last Earth samples over their span (``StripTrajectory.earth_spin_g_rad_s``) — the rotation the SLERP between
samples makes, without two more interpolations per light-time step. DECISION: not ω about ITRS z: the spin axis is
2.2e-6 rad off z (polar motion), a 3e-13 rad error in 2 ms that the Earth's radius turns into 2 µm on the ground
(5e-7 px; measured against the brute-force oracle, which SLERPs); the spin's own change (precession-nutation rates,
~1e-11 rad/s) adds ~2e-14 rad in Δt. Direct location inverts both exactly (``remove_aberration``; Δt by fixed-point
iteration, contraction ≈ v_ground/c ≈ 1.5e-6).

**Atmospheric refraction** (``Refraction``, off by default, as in Rugged: ``SightCorrections.refraction``): the point seen is displaced from the true
point, horizontally and away from the spacecraft, by a first-order flat-atmosphere law (``Refraction``'s docstring);
inverse location looks at the displaced point, direct location solves T = P − shift(T) with P on the ray.

**Direct location** (line, pixel → ground point in G): the line's time, position, velocity and
attitude, the pixel's line of sight ``LineSensor.look_direction``, aberration removed, then the ray
is intersected with the terrain: the WGS84 ellipsoid plus a height function h(lat, lon) (no DEM
grid: any vectorised callable, or a constant). The intersection starts from the ray's hit of the
ellipsoid grown by h₀ and iterates Newton's step on g(ρ) = h_geodetic(r₀ + ρ l) − h(lat, lon)
with the slope l·n̂ (n̂ the geodetic normal; terrain slope left out of the derivative, so the
contraction factor is ≈ terrain slope × tan(incidence)).

**Inverse location** (ground point → line, pixel), vectorised over points, one loop over chips only:

1. *Mean-plane crossing* (Rugged's ``SensorMeanPlaneCrossing``): n the normal of the sensor's mean
   plane of sight (``LineSensor.mean_plane_normal``); find the line where the point's apparent
   direction u_K(L) crosses it, n · û_K(L) = 0, by the secant method from the middle line (Rugged
   uses Newton with the derivative carried by automatic differentiation; both converge in a few steps
   since the crossing angle varies almost linearly with the line).
2. *Newton on (line, chip index)* per chip: the apparent direction must be imaged where the pixel
   is, R(L, j) = τ(u_K(L)) − τ_c(j) = 0 with τ = (tan ψx, tan ψy) (``LineSensor.image_tan_psi``,
   ``LineSensor.tan_psi``). ∂R/∂j = −τ_c′(j) is exact, ∂R/∂L by a forward difference of 0.01 line;
   the start is the crossing line and the chip index where the across-track law meets the point.
   Unlike Rugged's second stage (which assumes the pixels lie near the mean plane and then corrects),
   this solves for the chip's true along-track look angle, so staggered chips need no mean plane of
   their own. A point stops (and is left where it stopped) when both its steps are below
   ``INVERSE_TOL`` (1e-8 line, 1e-8 pixel); the iteration is quadratic up to the difference
   derivative's relative error (~1e-6), so it takes 3-4 steps. A point that has not converged in
   ``INVERSE_MAX_ITER`` steps is an error if it lies on the chip, and not seen by the chip if it lies
   more than a pixel off it (where a table chip's law is extrapolated).

A point is *seen* by a chip if the solution lies within the chip's pixels (j ∈ [−0.5, n − 0.5)),
within the given line range and in front of the camera; a point in the overlap of two chips is seen
by both (at different lines).

Times are seconds from the strip's epoch (one astropy ``Time``, UTC), positions metres.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .camera import LinearLineDatation, LineSensor, TabulatedLineDatation
from .earth import geodetic_from_itrs, itrs_from_geodetic
from .errors import InputValueError, LocationError
from .interpolate import lagrange_values
from .rotations import misalignment_dcm, rotvec_dcm
from .sight import SPEED_OF_LIGHT_M_S, Refraction, SightCorrections, apparent_sight_i, earth_turn, remove_aberration

__all__ = [
    "SPEED_OF_LIGHT_M_S",
    "INVERSE_TOL",
    "LocationError",
    "LineScanParameters",
    "Refraction",
    "SightCorrections",
    "StripTrajectory",
    "InverseLocation",
    "earth_orientation_samples",
    "geodetic_from_itrs",
    "itrs_from_geodetic",
    "line_time_s",
    "camera_attitude",
    "apparent_direction_i",
    "direct_location",
    "inverse_location",
    "locate_on_chips",
    "LineSight",
    "line_sight",
    "sight_tan_psi",
]

#: inverse location stops when the line and chip-index steps are both below this (line, pixel)
INVERSE_TOL = 1e-8
INVERSE_MAX_ITER = 30
#: direct location stops when the ray's point is within this of the terrain (m)
DIRECT_TOL_M = 1e-6
DIRECT_MAX_ITER = 50
#: the line step of the forward difference for ∂τ/∂L in inverse location
_DL = 0.01

Datation = LinearLineDatation | TabulatedLineDatation
#: a terrain: height above the WGS84 ellipsoid (m) as a function of geodetic latitude and longitude (rad)
Terrain = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class LineScanParameters:
    """The forward model's parameters (SI). ``theta_rad`` (3,) the misalignment (eq 24, camera axes);
    ``line_time_offset_s`` δt; ``line_period_error`` ε (relative); ``chip_offsets_rad`` (C, 2) the
    per-chip look-angle offsets (δψx along-track, δψy across-track) or None; ``focal_scale`` κ;
    ``jitter_frequency_hz`` (F,), ``jitter_amplitude_rad`` and ``jitter_phase_rad`` (F, 3), per
    frequency and camera axis (``jitter_rad``)."""

    theta_rad: Any = (0.0, 0.0, 0.0)
    line_time_offset_s: float = 0.0
    line_period_error: float = 0.0
    chip_offsets_rad: Any = None
    focal_scale: float = 0.0
    jitter_frequency_hz: Any = ()
    jitter_amplitude_rad: Any = ()
    jitter_phase_rad: Any = ()

    def __post_init__(self) -> None:
        theta = np.asarray(self.theta_rad, dtype=float)
        if theta.shape != (3,) or not np.all(np.isfinite(theta)):
            raise InputValueError(f"LineScanParameters.theta_rad must be 3 finite numbers, got {self.theta_rad!r}")
        object.__setattr__(self, "theta_rad", theta)
        for name in ("line_time_offset_s", "line_period_error", "focal_scale"):
            if not np.isfinite(getattr(self, name)):
                raise InputValueError(f"LineScanParameters.{name} must be finite, got {getattr(self, name)!r}")
        if not self.focal_scale > -1:
            raise InputValueError(f"LineScanParameters.focal_scale must be > −1, got {self.focal_scale!r}")
        f = np.atleast_1d(np.asarray(self.jitter_frequency_hz, dtype=float))
        amp = np.asarray(self.jitter_amplitude_rad, dtype=float).reshape(-1, 3) if f.size else np.zeros((0, 3))
        phase = np.asarray(self.jitter_phase_rad, dtype=float).reshape(-1, 3) if f.size else np.zeros((0, 3))
        if f.ndim != 1 or amp.shape != (f.size, 3) or phase.shape != (f.size, 3):
            raise InputValueError(
                f"LineScanParameters: jitter_amplitude_rad and jitter_phase_rad must be ({f.size}, 3) (per frequency, per "
                f"camera axis), got {amp.shape} and {phase.shape}"
            )
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(amp)) and np.all(np.isfinite(phase))):
            raise InputValueError("LineScanParameters: the jitter's frequencies, amplitudes and phases must be finite")
        object.__setattr__(self, "jitter_frequency_hz", f)
        object.__setattr__(self, "jitter_amplitude_rad", amp)
        object.__setattr__(self, "jitter_phase_rad", phase)

    def jitter_rad(self, t_s: Any) -> np.ndarray:
        """j(t) (..., 3): Σ_f A_f ⊙ sin(2π f t + φ_f), camera axes (rad)."""
        t = np.asarray(t_s, dtype=float)[..., None, None]
        arg = 2 * np.pi * self.jitter_frequency_hz[:, None] * t + self.jitter_phase_rad
        result: np.ndarray = np.sum(self.jitter_amplitude_rad * np.sin(arg), axis=-2)
        return result


@dataclass(frozen=True, eq=False)
class StripTrajectory:
    """The samples a strip is located with (seconds from the strip's epoch).

    ``orbit_t_s`` (K,), ``orbit_r_i_m``, ``orbit_v_i_m_s`` (K, 3) in I; ``tracker_t_s`` (Q,),
    ``tracker_quat`` (Q, 4) the star tracker's attitude quaternions (inertial → S, scalar-last);
    ``C_ES`` (3, 3) the tracker mount (body E → S; the nominal camera is the body, C_SK,nom = C_ESᵀ);
    ``earth_t_s`` (P,), ``earth_C_GI`` (P, 3, 3) ITRS → GCRS (``earth_orientation_samples``).
    """

    orbit_t_s: np.ndarray
    orbit_r_i_m: np.ndarray
    orbit_v_i_m_s: np.ndarray
    tracker_t_s: np.ndarray
    tracker_quat: np.ndarray
    C_ES: np.ndarray
    earth_t_s: np.ndarray
    earth_C_GI: np.ndarray
    orbit_degree: int = 7
    _slerps: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        from scipy.spatial.transform import Rotation, Slerp

        def times(name: str, n_min: int) -> np.ndarray:
            t = np.array(getattr(self, name), dtype=float)
            if t.ndim != 1 or t.size < n_min or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
                raise InputValueError(f"StripTrajectory.{name} must be ≥ {n_min} finite, strictly increasing times")
            t.setflags(write=False)
            object.__setattr__(self, name, t)
            return t

        def array(name: str, shape: tuple[int, ...]) -> np.ndarray:
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise InputValueError(f"StripTrajectory.{name} must be finite of shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
            return a

        k = times("orbit_t_s", self.orbit_degree + 1).size
        array("orbit_r_i_m", (k, 3))
        array("orbit_v_i_m_s", (k, 3))
        q = array("tracker_quat", (times("tracker_t_s", 2).size, 4))
        array("C_ES", (3, 3))
        C = array("earth_C_GI", (times("earth_t_s", 2).size, 3, 3))
        self._slerps["tracker"] = Slerp(self.tracker_t_s, Rotation.from_quat(q))
        self._slerps["earth"] = Slerp(self.earth_t_s, Rotation.from_matrix(C))
        # the Earth's spin in ITRS axes (rad/s): C_GI(t₁) = C_GI(t₀) exp(Φ(w (t₁ − t₀))) over the samples' span
        w = (Rotation.from_matrix(C[0]).inv() * Rotation.from_matrix(C[-1])).as_rotvec()
        self._slerps["earth_spin"] = w / (self.earth_t_s[-1] - self.earth_t_s[0])

    @property
    def earth_spin_g_rad_s(self) -> np.ndarray:
        """The Earth's spin w (3,) in ITRS axes (rad/s): C_GI(t₁) = C_GI(t₀) exp(Φ(w (t₁ − t₀))) over the samples' span
        (module docstring, "Light time and aberration")."""
        w: np.ndarray = self._slerps["earth_spin"]
        return w

    @property
    def span_s(self) -> tuple[float, float]:
        """The times every sample set covers."""
        lo = max(self.orbit_t_s[0], self.tracker_t_s[0], self.earth_t_s[0])
        hi = min(self.orbit_t_s[-1], self.tracker_t_s[-1], self.earth_t_s[-1])
        return float(lo), float(hi)

    def _check(self, t: np.ndarray) -> None:
        lo, hi = self.span_s
        bad = ~((t >= lo) & (t <= hi))
        if np.any(bad):
            k = int(np.argmax(bad.ravel()))
            raise LocationError(f"time {t.ravel()[k]!r} s (index {k}) is outside the strip's samples [{lo}, {hi}] s")

    def state_i(self, t_s: Any) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and velocity (m/s) in I at ``t_s`` (...,): Lagrange of degree ``orbit_degree``."""
        t = np.asarray(t_s, dtype=float)
        self._check(t)
        y = np.concatenate([self.orbit_r_i_m, self.orbit_v_i_m_s], axis=1)
        p = lagrange_values(self.orbit_t_s, y, t.ravel(), self.orbit_degree).reshape(t.shape + (6,))
        return p[..., :3], p[..., 3:]

    def tracker_sample_weights(self, t_s: Any) -> tuple[np.ndarray, np.ndarray]:
        """The star-tracker samples an attitude at ``t_s`` (...) is made of: indices (..., 2) of the bracketing samples
        and their weights (..., 2) = (1 − f, f), f = (t − t_k)/(t_{k+1} − t_k) — the SLERP's.

        Errors per sample enter the line's attitude through these two samples only: with A_meas,k = exp(Φ(δ_k)) A_k,
        the SLERP of the measured samples is exp(Φ((1 − f) δ_k + f δ_{k+1})) A(t) to first order (the frames of the
        two samples differ by the platform's turn between them, ≤ 3e-4 rad at 4 Hz, a relative error of that size),
        and C_IK = exp(−Φ(θ)) C_ESᵀ exp(Φ(δ)) A = exp(−Φ(θ)) exp(Φ(C_ESᵀ δ)) C_ESᵀ A: a tracker error δ acts on a
        detection as a misalignment of −C_ESᵀ δ (camera axes) at the line's time. So
        ∂(line, pixel)/∂δ_k = −w_k(t) ∂(line, pixel)/∂θ · C_ESᵀ — two samples per detection, whatever the
        strip's length. First order: the detection's own move ΔL changes its weight by ΔL T/Δt_k, a relative
        error of 2.9e-3 for a 2″ sample error, 3e-4 for 0.2″ (``tests/orbits/test_strip.py``, against moved samples)."""
        t = np.asarray(t_s, dtype=float)
        self._check(t)
        n = self.tracker_t_s.size
        k = np.clip(np.searchsorted(self.tracker_t_s, t, side="right") - 1, 0, n - 2)
        f = (t - self.tracker_t_s[k]) / (self.tracker_t_s[k + 1] - self.tracker_t_s[k])
        return np.stack([k, k + 1], axis=-1), np.stack([1.0 - f, f], axis=-1)

    def C_IS(self, t_s: Any) -> np.ndarray:
        """The tracker's attitude matrix A(t) (inertial → S), SLERP of the samples, ``(...) -> (..., 3, 3)``."""
        t = np.asarray(t_s, dtype=float)
        self._check(t)
        m = self._slerps["tracker"](t.ravel()).as_matrix()  # Rotation.from_quat(q).as_matrix() = A(q)ᵀ
        result: np.ndarray = np.swapaxes(m, -1, -2).reshape(t.shape + (3, 3))
        return result

    def C_GI(self, t_s: Any) -> np.ndarray:
        """ITRS → GCRS at ``t_s``, SLERP of the Earth-orientation samples, ``(...) -> (..., 3, 3)``."""
        t = np.asarray(t_s, dtype=float)
        self._check(t)
        result: np.ndarray = self._slerps["earth"](t.ravel()).as_matrix().reshape(t.shape + (3, 3))
        return result


def earth_orientation_samples(
    epoch: Any, t_start_s: float, t_stop_s: float, step_s: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """(t_s (P,), C_GI (P, 3, 3)): ``itrs_to_gcrs_dcm`` on a grid covering [t_start, t_stop] (one astropy call)."""
    from astropy import units as u
    from astropy.time import Time

    from .earth import itrs_to_gcrs_dcm

    if not (np.isfinite(t_start_s) and np.isfinite(t_stop_s) and t_stop_s > t_start_s and step_s > 0):
        raise InputValueError(
            f"earth_orientation_samples: need t_start < t_stop and step > 0, got {t_start_s}, {t_stop_s}, {step_s}"
        )
    n = int(np.ceil((t_stop_s - t_start_s) / step_s)) + 1
    t = t_start_s + step_s * np.arange(n)
    return t, itrs_to_gcrs_dcm(Time(epoch, scale="utc") + t * u.s)


def line_time_s(datation: Datation, line: Any, params: LineScanParameters) -> np.ndarray:
    """t(L) = t_nom(L) + δt + ε (t_nom(L) − t_nom(L_ref)): the datation with the line-time offset and period error."""
    t_nom = datation.time_s(line)
    t_ref = datation.time_s(datation.reference_line)
    result: np.ndarray = t_nom + params.line_time_offset_s + params.line_period_error * (t_nom - t_ref)
    return result


def _line_of_time(datation: Datation, t_s: Any, params: LineScanParameters) -> np.ndarray:
    """The inverse of ``line_time_s``."""
    t_ref = datation.time_s(datation.reference_line)
    return datation.line(t_ref + (np.asarray(t_s, float) - params.line_time_offset_s - t_ref) / (1 + params.line_period_error))


def camera_attitude(traj: StripTrajectory, t_s: Any, params: LineScanParameters) -> np.ndarray:
    """C_IK(t) = exp(−Φ(θ)) exp(−Φ(j(t))) C_ESᵀ A(t) (Kiev 2012 eq 24 with the jitter), ``(...) -> (..., 3, 3)``."""
    C_IS = traj.C_IS(t_s)
    return _camera_from_nominal(np.einsum("ji,...jk->...ik", traj.C_ES, C_IS), t_s, params)  # C_SK,nom A = C_ESᵀ A


def _camera_from_nominal(C: np.ndarray, t_s: Any, params: LineScanParameters) -> np.ndarray:
    """exp(−Φ(θ)) exp(−Φ(j(t))) C for the nominal camera attitudes C = C_SK,nom A(t) (..., 3, 3)."""
    if params.jitter_frequency_hz.size:
        C = np.einsum("...ij,...jk->...ik", rotvec_dcm(-params.jitter_rad(t_s)), C)
    result: np.ndarray = np.einsum("ij,...jk->...ik", misalignment_dcm(params.theta_rad), C)
    return result


def apparent_direction_i(
    traj: StripTrajectory, t_s: Any, ground_g_m: Any, corrections: SightCorrections = SightCorrections()
) -> np.ndarray:
    """Unit direction (..., 3) in I in which the spacecraft at ``t_s`` sees ground points (..., 3) of G, with the
    ``corrections`` (by default light time and aberration, no refraction): ``orbits.sight.apparent_sight_i`` on the
    strip's position, velocity and C_GI interpolated at ``t_s`` and its Earth spin (``StripTrajectory.earth_spin_g_rad_s``)."""
    t = np.asarray(t_s, dtype=float)
    r, v = traj.state_i(t)
    sight = apparent_sight_i(r, v, traj.C_GI(t), np.asarray(ground_g_m, dtype=float), traj.earth_spin_g_rad_s, corrections)
    return sight.direction_i


def _terrain_height(terrain: Terrain | Any, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """The terrain's height at (lat, lon): a function's value, or a constant / per-point array broadcast."""
    h = terrain(lat, lon) if callable(terrain) else terrain
    return np.broadcast_to(np.asarray(h, dtype=float), lat.shape)


def _ellipsoid_hit(r0: np.ndarray, d: np.ndarray, h_m: np.ndarray) -> np.ndarray:
    """Range ρ to the first hit of r0 + ρ d (d unit) on the ellipsoid of semi-axes (a + h, a + h, b + h)."""
    import erfa

    a, f = erfa.eform(1)
    b = a * (1 - f)
    scale = np.stack([a + h_m, a + h_m, b + h_m], axis=-1)
    r0s, ds = r0 / scale, d / scale
    A = np.sum(ds * ds, axis=-1)
    B = np.sum(r0s * ds, axis=-1)
    C = np.sum(r0s * r0s, axis=-1) - 1
    disc = B * B - A * C
    if np.any(disc < 0):
        k = int(np.argmax(np.ravel(disc < 0)))
        raise LocationError(f"line of sight {k} misses the Earth (no intersection with the WGS84 ellipsoid)")
    result: np.ndarray = (-B - np.sqrt(disc)) / A
    return result


def _intersect_terrain(r0_g: np.ndarray, d_g: np.ndarray, terrain: Terrain | Any, shift: np.ndarray) -> np.ndarray:
    """Range ρ along r0 + ρ d (G frame, d unit) where the geodetic height equals the terrain's at the point less
    ``shift`` (the refraction's apparent − true displacement, zero without it; module docstring)."""
    rho = _ellipsoid_hit(r0_g, d_g, np.zeros(r0_g.shape[:-1]))
    lat, lon, _ = geodetic_from_itrs(r0_g + rho[..., None] * d_g - shift)
    rho = _ellipsoid_hit(r0_g, d_g, _terrain_height(terrain, lat, lon))
    for _ in range(DIRECT_MAX_ITER):
        _, _, h = geodetic_from_itrs(r0_g + rho[..., None] * d_g)
        lat, lon, _ = geodetic_from_itrs(r0_g + rho[..., None] * d_g - shift)
        g = h - _terrain_height(terrain, lat, lon)
        if np.all(np.abs(g) <= DIRECT_TOL_M):
            return rho
        up = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
        rho = rho - g / np.sum(d_g * up, axis=-1)
    k = int(np.argmax(np.ravel(np.abs(g) > DIRECT_TOL_M)))
    raise LocationError(
        f"direct location of point {k} did not reach the terrain to {DIRECT_TOL_M} m in {DIRECT_MAX_ITER} iterations "
        f"(left {np.ravel(g)[k]:.3g} m: a terrain too steep for the incidence?)"
    )


def direct_location(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    line: Any,
    pixel: Any,
    params: LineScanParameters | None = None,
    terrain: Terrain | Any = 0.0,
    corrections: SightCorrections = SightCorrections(),
) -> np.ndarray:
    """Ground points (..., 3) in G (ITRS, m) seen at (line, pixel) (line columns, ``LineSensor.chip_of``).

    ``terrain`` is a height above the WGS84 ellipsoid (m): a constant, one per point (an array broadcast with the
    points), or a function h(lat_rad, lon_rad). ``corrections``: light time and aberration removed, refraction solved
    for (module docstring).
    """
    params = params or LineScanParameters()
    light_time, refraction = corrections.light_time, corrections.refraction
    line_a, pixel_a = np.broadcast_arrays(np.asarray(line, float), np.asarray(pixel, float))
    t = line_time_s(datation, line_a, params)
    r, v = traj.state_i(t)
    chip, j = sensor.chip_of(pixel_a)
    s_k = sensor.look_direction(chip, j, params.focal_scale, params.chip_offsets_rad)
    o = np.einsum("...ji,...j->...i", camera_attitude(traj, t, params), s_k)  # C_IKᵀ s
    o = o / np.linalg.norm(o, axis=-1, keepdims=True)
    d_i = remove_aberration(o, v) if corrections.aberration else o
    C_GI = traj.C_GI(t)
    r_g = np.einsum("...ji,...j->...i", C_GI, r)
    d_g0 = np.einsum("...ji,...j->...i", C_GI, d_i)
    dt = np.zeros(t.shape)
    shift = np.zeros(r_g.shape)
    for _ in range(3 if light_time else 1):  # Δt by fixed point (contraction ≈ 1.5e-6); C_GI(t − Δt)ᵀ = turn(C_GI(t)ᵀ, Δt)
        w = traj.earth_spin_g_rad_s
        r0_g, d_g = earth_turn(w, r_g, dt), earth_turn(w, d_g0, dt)
        n_refraction = 3 if refraction is not None else 1
        for k in range(n_refraction):  # the true point T = P − shift(T), P on the ray (the last pass keeps its shift)
            rho = _intersect_terrain(r0_g, d_g, terrain, shift)
            if refraction is not None and k < n_refraction - 1:
                shift = refraction.shift_g(r0_g + rho[..., None] * d_g - shift, r0_g)
        dt = rho / SPEED_OF_LIGHT_M_S if light_time else dt
    result: np.ndarray = r0_g + rho[..., None] * d_g - shift
    return result


@dataclass(frozen=True)
class InverseLocation:
    """Where each ground point is imaged, per chip: ``line``, ``pixel`` (line column) and ``seen`` of shape
    (C, G) (NaN where not seen), and the mean-plane crossing line (G,) of stage 1."""

    line: np.ndarray
    pixel: np.ndarray
    seen: np.ndarray
    crossing_line: np.ndarray

    def primary(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(line, pixel, chip) (G,) from the lowest-numbered chip that sees each point (chip −1, NaN: none)."""
        any_seen = np.any(self.seen, axis=0)
        chip = np.where(any_seen, np.argmax(self.seen, axis=0), -1)
        g = np.arange(self.line.shape[1])
        pick = np.maximum(chip, 0)
        line = np.where(any_seen, self.line[pick, g], np.nan)
        pixel = np.where(any_seen, self.pixel[pick, g], np.nan)
        return line, pixel, chip


def _target_tan_psi(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    line: np.ndarray,
    ground_g: np.ndarray,
    params: LineScanParameters,
    corrections: SightCorrections,
) -> tuple[np.ndarray, np.ndarray]:
    """(u_K unit (G, 3), τ (G, 2)): the apparent direction of the points in K at ``line`` and where it is imaged."""
    t = line_time_s(datation, line, params)
    o = apparent_direction_i(traj, t, ground_g, corrections)
    u = np.einsum("gij,gj->gi", camera_attitude(traj, t, params), o)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = sensor.image_tan_psi(u)
    return u, tau


@dataclass(frozen=True)
class LineSight:
    """What a ground point's image at a line depends on besides θ, the jitter and the sensor's look angles: the line's
    time ``t_s`` (G,), the point's apparent direction in I ``direction_i`` (G, 3) (its ``SightCorrections``)
    and the nominal camera attitude ``C_nominal`` (G, 3, 3) = C_SK,nom A(t). ``sight_tan_psi`` turns it into τ for any
    θ and jitter: an estimator differentiating in those reuses one ``line_sight``."""

    t_s: np.ndarray
    direction_i: np.ndarray
    C_nominal: np.ndarray

    @cached_property
    def direction_nominal(self) -> np.ndarray:
        """(G, 3) the apparent direction in the nominal camera axes, C_nominal ``direction_i``: computed once, then
        ``sight_tan_psi`` turns it by the jitter and θ alone (a (G, 3) product, not a (G, 3, 3) one, per θ)."""
        out: np.ndarray = np.einsum("gij,gj->gi", self.C_nominal, self.direction_i)
        return out


def line_sight(
    datation: Datation,
    traj: StripTrajectory,
    line: Any,
    ground_g_m: Any,
    params: LineScanParameters,
    corrections: SightCorrections = SightCorrections(),
) -> LineSight:
    """The ``LineSight`` of ground points (G, 3) of G at (fractional) lines (G,), dated with ``params``' timing."""
    g = np.asarray(ground_g_m, dtype=float).reshape(-1, 3)
    L = np.broadcast_to(np.asarray(line, dtype=float), (g.shape[0],))
    t = line_time_s(datation, L, params)
    o = apparent_direction_i(traj, t, g, corrections)
    return LineSight(t, o, np.einsum("ji,...jk->...ik", traj.C_ES, traj.C_IS(t)))


def sight_tan_psi(sensor: LineSensor, sight: LineSight, params: LineScanParameters) -> np.ndarray:
    """τ (G, 2) where the sight's points are imaged under ``params``' θ and jitter (its timing is the sight's):
    u = exp(−Φ(θ)) exp(−Φ(j(t))) (C_nominal o), ``_camera_from_nominal``'s rotations applied to the sight's
    ``direction_nominal`` (the same product associated the other way: equal to round-off, ~1e-16), then the frame
    camera's projection (``LineSensor.image_tan_psi``).

    ``sight_tan_psi(sensor, line_sight(datation, traj, line, ground_g_m, params, corrections), params)`` is the
    forward model of a pushbroom row: where ground points (G, 3) of G are imaged, τ = (tan ψx, tan ψy), at the given
    (fractional) lines (G,). A detection at (line, chip, j) is exact when it equals ``sensor.tan_psi(chip, j)``: the
    residual an estimator on pushbroom rows minimises (instantaneous line dating: the measured line fixes the time,
    ``docs/pushbroom.md``)."""
    u = sight.direction_nominal
    if params.jitter_frequency_hz.size:
        u = np.einsum("...ij,...j->...i", rotvec_dcm(-params.jitter_rad(sight.t_s)), u)
    u = u @ misalignment_dcm(params.theta_rad).T
    with np.errstate(divide="ignore", invalid="ignore"):
        result: np.ndarray = sensor.image_tan_psi(u)
    return result


def _crossing_lines(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    g: np.ndarray,
    start_line: float,
    bounds: tuple[float, float],
    params: LineScanParameters,
    corrections: SightCorrections,
) -> np.ndarray:
    """Stage 1 of inverse location: the line where each point crosses the sensor's mean plane (secant method)."""
    n = sensor.mean_plane_normal(params.focal_scale, params.chip_offsets_rad)

    def crossing(L: np.ndarray) -> np.ndarray:
        u, _ = _target_tan_psi(sensor, datation, traj, L, g, params, corrections)
        result: np.ndarray = u @ n
        return result

    L0 = np.full(g.shape[0], np.clip(start_line, bounds[0], bounds[1]))
    L1 = np.clip(L0 + 10.0, bounds[0], bounds[1])
    f0, f1 = crossing(L0), crossing(L1)
    for _ in range(INVERSE_MAX_ITER):
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(f1 != f0, -f1 * (L1 - L0) / (f1 - f0), 0.0)
        L0, f0 = L1, f1
        L1 = np.clip(L1 + np.nan_to_num(step), bounds[0], bounds[1])
        if np.all(np.abs(step) < 1e-3):
            break
        f1 = crossing(L1)
    return L1


def _line_bounds(datation: Datation, traj: StripTrajectory, params: LineScanParameters) -> tuple[float, float]:
    """The lines whose times (and a difference step beyond) the samples cover."""
    lo_t, hi_t = traj.span_s
    lo_l, hi_l = np.sort(_line_of_time(datation, np.array([lo_t, hi_t]), params))
    return float(lo_l) + 1.0, float(hi_l) - 1.0  # room for the difference step


def inverse_location(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    ground_g_m: Any,
    line_range: tuple[float, float],
    params: LineScanParameters | None = None,
    corrections: SightCorrections = SightCorrections(),
) -> InverseLocation:
    """(line, pixel) of ground points (G, 3) in G on each chip: mean-plane crossing, then Newton (module docstring).

    ``line_range`` (first, last) are the strip's lines: a solution outside [first − 0.5, last + 0.5] is not seen.
    Raises ``LocationError`` naming the first point whose Newton iteration did not converge.
    """
    params = params or LineScanParameters()
    g = np.asarray(ground_g_m, dtype=float).reshape(-1, 3)
    first, last = float(line_range[0]), float(line_range[1])
    bounds = _line_bounds(datation, traj, params)
    L_cross = _crossing_lines(sensor, datation, traj, g, 0.5 * (first + last), bounds, params, corrections)
    C, G = sensor.n_chips, g.shape[0]
    lines, pixels, seen = np.full((C, G), np.nan), np.full((C, G), np.nan), np.zeros((C, G), bool)
    for c, chip in enumerate(sensor.chips):
        L, seen_c, j = _newton_chip(sensor, datation, traj, g, params, c, L_cross, bounds, corrections)
        seen_c &= (L >= first - 0.5) & (L <= last + 0.5) & (j >= -0.5) & (j < chip.n_pixels - 0.5)
        lines[c] = np.where(seen_c, L, np.nan)
        pixels[c] = np.where(seen_c, j + sensor.first_pixel(c), np.nan)
        seen[c] = seen_c
    return InverseLocation(lines, pixels, seen, L_cross)


def locate_on_chips(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    ground_g_m: Any,
    chip: Any,
    params: LineScanParameters | None = None,
    start_line: float | None = None,
    corrections: SightCorrections = SightCorrections(),
) -> tuple[np.ndarray, np.ndarray]:
    """The forward model of a detection: (line, pixel) (G,) of ground points (G, 3) each on its given chip (G,).

    Inverse location without the seen-tests (a prediction may fall just off its chip or strip, as an estimator's
    trial parameters move it), so a function of ``params`` an estimator differentiates. NaN where the point is
    behind the camera or beyond the samples. ``start_line`` seeds the mean-plane crossing (default: the datation's
    reference line).
    """
    params = params or LineScanParameters()
    g = np.asarray(ground_g_m, dtype=float).reshape(-1, 3)
    chips = np.broadcast_to(np.asarray(chip, dtype=int), (g.shape[0],))
    if np.any((chips < 0) | (chips >= sensor.n_chips)):
        k = int(np.argmax((chips < 0) | (chips >= sensor.n_chips)))
        raise InputValueError(f"chip[{k}] = {chips[k]} is not a chip of the sensor (0 … {sensor.n_chips - 1})")
    bounds = _line_bounds(datation, traj, params)
    start = datation.reference_line if start_line is None else start_line
    line, pixel = np.full(g.shape[0], np.nan), np.full(g.shape[0], np.nan)
    L_cross = _crossing_lines(sensor, datation, traj, g, start, bounds, params, corrections)
    for c in np.unique(chips):
        k = chips == c
        L, ok, j = _newton_chip(sensor, datation, traj, g[k], params, int(c), L_cross[k], bounds, corrections)
        line[k] = np.where(ok, L, np.nan)
        pixel[k] = np.where(ok, j + sensor.first_pixel(int(c)), np.nan)
    return line, pixel


def _newton_chip(
    sensor: LineSensor,
    datation: Datation,
    traj: StripTrajectory,
    g: np.ndarray,
    params: LineScanParameters,
    c: int,
    L_start: np.ndarray,
    bounds: tuple[float, float],
    corrections: SightCorrections,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage 2 of inverse location on chip ``c``: (line, in front and converged, chip index j)."""
    chip = sensor.chips[c]
    kappa, off = params.focal_scale, params.chip_offsets_rad
    ends = sensor.tan_psi(np.array([c, c]), np.array([0.0, chip.n_pixels - 1.0]), kappa, off)[:, 1]
    L = L_start.copy()
    _, tau = _target_tan_psi(sensor, datation, traj, L, g, params, corrections)
    j = np.nan_to_num((tau[:, 1] - ends[0]) / (ends[1] - ends[0]) * (chip.n_pixels - 1.0))
    G = g.shape[0]
    done, pinned, front = np.zeros(G, bool), np.zeros(G, bool), np.ones(G, bool)
    steps = np.full((G, 2), np.inf)
    for _ in range(INVERSE_MAX_ITER):
        a = np.flatnonzero(~done)  # a converged point is left where it converged
        if a.size == 0:
            break
        u, tau = _target_tan_psi(sensor, datation, traj, L[a], g[a], params, corrections)
        _, tau_h = _target_tan_psi(sensor, datation, traj, L[a] + _DL, g[a], params, corrections)
        R = tau - sensor.tan_psi(np.full(a.size, c), j[a], kappa, off)
        dR_dL = (tau_h - tau) / _DL
        dR_dj = -chip.tan_psi_derivative(j[a]) / (1.0 + kappa)
        det = dR_dL[:, 0] * dR_dj[:, 1] - dR_dL[:, 1] * dR_dj[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            dL = np.nan_to_num(-(dR_dj[:, 1] * R[:, 0] - dR_dj[:, 0] * R[:, 1]) / det)
            dj = np.nan_to_num(-(-dR_dL[:, 1] * R[:, 0] + dR_dL[:, 0] * R[:, 1]) / det)
        L_new = np.clip(L[a] + dL, bounds[0], bounds[1])
        pinned[a] = (L_new != L[a] + dL) & (L[a] == L_new)  # pushed beyond a bound it already sits on: beyond the samples
        L[a], j[a] = L_new, j[a] + dj
        front[a] = u[:, 2] < 0
        steps[a] = np.stack([dL, dj], axis=-1)
        done[a] = np.all(np.abs(steps[a]) < INVERSE_TOL, axis=-1) | pinned[a]
    # DECISION: a point that has not converged but lies off this chip by more than a pixel is "not seen" here (far
    # off the chip the law is extrapolated, and a point imaged by another chip may wander); on the chip it is an error
    stuck = ~done & (j >= -1.5) & (j < chip.n_pixels + 0.5)
    if np.any(stuck):
        k = int(np.argmax(stuck))
        raise LocationError(
            f"inverse location of ground point {k} on chip {c} did not converge in {INVERSE_MAX_ITER} Newton steps "
            f"(last steps {steps[k, 0]:.3g} line, {steps[k, 1]:.3g} px)"
        )
    return L, front & ~pinned & done, j
