"""A pushbroom strip over a site: the true geometry, the star tracker's samples and the ground-control points.

``strip_geometry(config)`` builds the world of one strip (the pass and the platform, no random draw):

* the orbit is ``CircularOrbit`` (radius ``R_EARTH_M + altitude_m``, as ``orbits.geometry.wgs84_pass``),
  its node solved (``CircularOrbit.raan_for_site``) so that at τ = 0 the spacecraft is over the
  *nadir point* P from which a roll of ``roll_deg`` looks at the site: with the site at geocentric
  distance R_s and the orbit radius R_o, the off-nadir angle φ and the Earth-central angle γ between
  P and the site obey R_s sin(φ + γ) = R_o sin φ (the law of sines in the triangle centre-spacecraft-site),
  and P is γ from the site across the track of the orbit over P, away from the side the camera rolls
  to (a positive roll, a frame turned about +x_E, tilts −z_E toward +y_E, the orbit normal r × v):
  site = cos γ P + sign(roll) sin γ n(P), solved for P by a fixed point (``_nadir_point``);
* the body attitude is the orbital frame (``orbits.attitude.nadir``) turned by the roll about
  x_E: C_IE = axis_dcm(0, roll) C_IO;
* orbit samples (exact states of the circular orbit) every ``orbit_step_s``, star-tracker samples
  A_k = C_ES C_IE(t_k) at ``tracker_rate_hz``, Earth-orientation samples every second, all covering
  the strip's lines plus ``margin_s`` on each side;
* the line datation is linear, centred on τ = 0: t(L) = (L − (N − 1)/2) T.

``simulate_strip(geometry, truth, rng, layout, tracker, sigma_pixel)`` draws one strip's data: ground-control
points at random (line, pixel) and heights inside the swath (placed by direct location with the nominal model),
their true detections by inverse location with the hidden effects of ``truth`` (``LineScanParameters``: θ, a
line-time offset, a line-period error, per-chip look-angle offsets, a focal scale, jitter sinusoids), pixel noise,
and the star tracker's reports with their own errors per sample (``TrackerNoise``: white, plus an optional
Gauss–Markov process). Pure functions over arrays, vectorised over the points; the forward model of a detection,
``orbits.pushbroom.locate_on_chips``, takes the same parameters, so an estimator's predictions and Jacobians
(finite differences in each parameter) come from the function that made the truth.

``strip_records(sim)`` lays a strip's detections out as the row model's tables (one image per detection at its
measured line's time, the tracker's samples as the attitude-sample table, ``LineScanRecords`` the pushbroom context;
``boresight.observations.strip`` builds the ``ObservationSet``); ``load_strip_scenario`` reads a pushbroom scenario
file (``kind = "pushbroom"``: one strip or a campaign of strips, the GCPs, the noise, the truth and hidden
``[effects]`` of ``orbits.effects.LINE_EFFECTS``, the ``[estimate]`` unknowns; ``docs/data-format.md``).

DECISION: the world's attitude between tracker samples is the SLERP of the error-free samples (the
sensor model's own interpolation), so the truth carries no interpolation error of its own: the
orbital frame turns uniformly about the orbit normal, which SLERP reproduces exactly; what a real
platform adds between samples is the jitter, modelled apart (``LineScanParameters``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .attitude import nadir
from .camera import LinearLineDatation, LineChip, LineSensor
from .earth import itrs_to_gcrs_dcm, wgs84_site
from .errors import InputValueError, LocationError
from .orbit import CircularOrbit
from .pushbroom import (
    Datation,
    LineScanParameters,
    StripTrajectory,
    direct_location,
    earth_orientation_samples,
    inverse_location,
    line_time_s,
)
from .rotations import axis_dcm, dcm_from_quat, misalignment_dcm, quat_from_dcm, star_tracker_error_dcm

__all__ = [
    "StripConfig",
    "StripGeometry",
    "strip_geometry",
    "zy3_like_sensor",
    "zy3_like_effects",
    "hills_height_m",
    "TrackerNoise",
    "GcpLayout",
    "StripSimulation",
    "measured_trajectory",
    "simulate_strip",
    "simulate_campaign",
    "LineScanRecords",
    "strip_records",
    "line_records",
    "StripScenario",
    "STRIP_SCENARIO_KEYS",
    "strip_scenario_from_dict",
    "load_strip_scenario",
    "is_strip_scenario",
]


def zy3_like_sensor(
    n_chips: int = 3,
    pixels_per_chip: int = 8192,
    overlap_px: int = 100,
    stagger_px: float = 40.0,
    focal_length_m: float = 1.7,
    pixel_pitch_m: float = 7e-6,
) -> LineSensor:
    """An illustrative staggered line of ``n_chips`` polynomial chips, sized like the ZY-3 nadir camera
    (F = 1.7 m, 7 µm pixels: 2.1 m on the ground from 505 km; three 8192-pixel chips).

    Chip c spans the across-track positions k = c (n − overlap) + j − k_mid (pixels, centred on the
    line), tan ψy = k p/F plus a small quadratic term (1e-13 per pixel²: a 0.07 px distortion at the
    chip's end); alternate chips sit ``stagger_px`` ahead and behind the line (tan ψx = ∓ stagger p/F)
    with a slight rotation (1e-9 per pixel), as a staggered focal plane is built.
    """
    pitch = pixel_pitch_m / focal_length_m
    k_mid = (n_chips * pixels_per_chip - (n_chips - 1) * overlap_px - 1) / 2.0
    chips = []
    for c in range(n_chips):
        start = c * (pixels_per_chip - overlap_px) - k_mid
        sign = 1.0 if c % 2 else -1.0
        chips.append(
            LineChip(pixels_per_chip, tan_psi_x=(sign * stagger_px * pitch, 1e-9), tan_psi_y=(start * pitch, pitch, 1e-13))
        )
    return LineSensor(focal_length_m, tuple(chips), pixel_pitch_m)


def zy3_like_effects() -> LineScanParameters:
    """Every effect of the forward model switched on for ``zy3_like_sensor()``, at sizes a calibration meets: θ of
    tens of arcseconds (1e-4, −2e-4, 3e-4 rad), a 2 ms line-time offset, a 1e-4 line-period error, chip offsets of
    about a pixel (2-5 µrad; a pixel is 7 µm / 1.7 m = 4.1 µrad), a 1e-4 focal scale and a 0.65 Hz jitter of about a
    pixel. The hidden truth of the location round trips (``tests/orbits/test_pushbroom.py``) and of the location
    benchmark (``benchmarks/bench_pushbroom.py``)."""
    return LineScanParameters(
        theta_rad=(1e-4, -2e-4, 3e-4),
        line_time_offset_s=2e-3,
        line_period_error=1e-4,
        chip_offsets_rad=[[4e-6, -4e-6], [0.0, 3e-6], [-2e-6, 5e-6]],
        focal_scale=1e-4,
        jitter_frequency_hz=[0.65],
        jitter_amplitude_rad=[[4e-6, 4e-6, 2e-6]],
        jitter_phase_rad=[[0.1, 1.0, 2.0]],
    )


def hills_height_m(lat_rad: Any, lon_rad: Any) -> np.ndarray:
    """An illustrative terrain (``orbits.pushbroom.Terrain``): hills of 300-2700 m above the WGS84 ellipsoid,
    h = 1500 + 1200 sin(800 lat) cos(700 lon) (m, lat and lon in rad: wavelengths of about 50 km), for
    direct and inverse location over relief (with ``zy3_like_effects``)."""
    return np.asarray(1500.0 + 1200.0 * np.sin(800.0 * np.asarray(lat_rad)) * np.cos(700.0 * np.asarray(lon_rad)))


#: the nadir point's fixed point (``_nadir_point``) stops when P moves by less than this (rad; 6 µm on the ground)
_NADIR_POINT_TOL_RAD = 1e-12
_NADIR_POINT_MAX_ITER = 20


@dataclass(frozen=True, eq=False)
class StripConfig:
    """One strip: the site (geodetic WGS84), the UTC ``epoch`` of τ = 0, the orbit, the roll angle,
    the sensor and its line period, the sample rates. ``tracker_mount_rotvec_deg`` turns the star
    tracker's frame from the body: C_ES = exp(−Φ(v)) (a frame turned by v, ``docs/conventions.md``)."""

    sensor: LineSensor
    site_lat_deg: float = 40.0
    site_lon_deg: float = 116.0
    site_height_m: float = 0.0
    epoch: str = "2024-06-01T03:00:00"
    altitude_m: float = 505_000.0
    inclination_deg: float = 97.4
    direction: str = "descending"
    roll_deg: float = 0.0
    n_lines: int = 10_000
    line_period_s: float = 3.1e-4
    tracker_rate_hz: float = 4.0
    orbit_step_s: float = 1.0
    margin_s: float = 5.0
    tracker_mount_rotvec_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("site_lat_deg", "site_lon_deg", "site_height_m", "altitude_m", "inclination_deg", "roll_deg"):
            if not np.isfinite(getattr(self, name)):
                raise InputValueError(f"StripConfig.{name} must be finite, got {getattr(self, name)!r}")
        if not -60.0 < self.roll_deg < 60.0:
            raise InputValueError(f"StripConfig.roll_deg must be within ±60°, got {self.roll_deg!r}")
        if isinstance(self.n_lines, bool) or not isinstance(self.n_lines, (int, np.integer)) or self.n_lines < 2:
            raise InputValueError(f"StripConfig.n_lines must be an integer ≥ 2, got {self.n_lines!r}")
        for name in ("line_period_s", "tracker_rate_hz", "orbit_step_s", "margin_s"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise InputValueError(f"StripConfig.{name} must be > 0, got {getattr(self, name)!r}")


@dataclass(frozen=True, eq=False)
class StripGeometry:
    """The true world of a strip: its trajectory (error-free tracker samples), datation and line range,
    the body attitude at the tracker's sample times, the orbit, and the site in G."""

    config: StripConfig
    trajectory: StripTrajectory
    datation: LinearLineDatation
    C_IE: np.ndarray
    orbit: CircularOrbit
    u0_rad: float
    site_g_m: np.ndarray

    @property
    def line_range(self) -> tuple[float, float]:
        return 0.0, float(self.config.n_lines - 1)


def _nadir_point(site_unit_i: np.ndarray, base: CircularOrbit, config: StripConfig, site_radius_m: float) -> np.ndarray:
    """P: the point over which the orbit's roll by ``roll_deg`` about the along-track axis looks at the site.

    The site must lie in the plane through P and the normal n(P) of the orbit that passes over P, γ from P on the
    roll's side: site = cos γ P + s sin γ n(P) (s the roll's sign), so P = (site − s sin γ n(P)) / cos γ. The normal
    depends on P (the orbit of this inclination over P has its own node), so P is a fixed point started from n(site).
    DECISION: iterated, not the first pass alone: P = cos γ site − s sin γ n(site) leaves the site off the plane the
    roll looks along by ~γ² (at 30° roll 1.8e-3 rad, 11.5 km along-track: outside a 10 000-line strip); each pass
    cuts the error by ~γ² (1.8e-3, 3.3e-6, 1.1e-11 rad at 30°; ``tests/orbits/test_strip.py``).
    """
    phi = np.radians(abs(config.roll_deg))
    gamma = np.arcsin(base.radius_m / site_radius_m * np.sin(phi)) - phi
    p: np.ndarray = site_unit_i
    for _ in range(_NADIR_POINT_MAX_ITER):
        raan, u0 = base.raan_for_site(p, config.direction)
        orbit = CircularOrbit(base.altitude_m, base.inclination_rad, raan, base.earth_radius_m)
        normal = np.cross(orbit.unit_position(u0), orbit.unit_velocity(u0))
        new = site_unit_i - np.sign(config.roll_deg) * np.sin(gamma) * normal
        new = np.asarray(new / np.linalg.norm(new))
        moved = float(np.linalg.norm(new - p))
        p = new
        if moved < _NADIR_POINT_TOL_RAD:
            return p
    raise LocationError(
        f"strip_geometry: the nadir point for roll {config.roll_deg}° did not converge in {_NADIR_POINT_MAX_ITER} passes "
        f"(last move {moved:.3g} rad)"
    )


def strip_geometry(config: StripConfig) -> StripGeometry:
    """The strip's true geometry (module docstring); deterministic."""
    from astropy.time import Time

    epoch = Time(config.epoch, scale="utc")
    site_g, _ = wgs84_site(config.site_lat_deg, config.site_lon_deg, config.site_height_m)
    e0 = itrs_to_gcrs_dcm(epoch) @ site_g
    base = CircularOrbit(config.altitude_m, np.radians(config.inclination_deg))
    p = _nadir_point(e0 / np.linalg.norm(e0), base, config, float(np.linalg.norm(site_g)))
    raan, u0 = base.raan_for_site(p, config.direction)
    orbit = CircularOrbit(config.altitude_m, np.radians(config.inclination_deg), raan)
    datation = LinearLineDatation((config.n_lines - 1) / 2.0, 0.0, config.line_period_s)
    t0 = float(datation.time_s(0.0)) - config.margin_s
    t1 = float(datation.time_s(config.n_lines - 1.0)) + config.margin_s
    t_orbit = np.arange(t0 - 4 * config.orbit_step_s, t1 + 5 * config.orbit_step_s, config.orbit_step_s)
    r, v = orbit.state(u0 + orbit.mean_motion_rad_s * t_orbit)
    t_tracker = np.arange(t0, t1 + 1.0 / config.tracker_rate_hz, 1.0 / config.tracker_rate_hz)
    rt, vt = orbit.state(u0 + orbit.mean_motion_rad_s * t_tracker)
    C_IE = np.einsum("ij,njk->nik", axis_dcm(0, np.radians(config.roll_deg)), nadir(rt, vt))
    C_ES = misalignment_dcm(np.radians(np.asarray(config.tracker_mount_rotvec_deg, float)))
    quat = quat_from_dcm(np.einsum("ij,njk->nik", C_ES, C_IE))
    t_earth, C_GI = earth_orientation_samples(epoch, t0 - 1.0, t1 + 1.0)
    traj = StripTrajectory(t_orbit, r, v, t_tracker, quat, C_ES, t_earth, C_GI)
    return StripGeometry(config, traj, datation, C_IE, orbit, float(u0), site_g)


# ---------------------------------------------------------------------------- the simulator of a strip


@dataclass(frozen=True)
class TrackerNoise:
    """Star-tracker errors per sample, per axis (the Kiev 2012 δ: A_meas = exp(Φ(δ)) A, ``docs/conventions.md``):
    white noise of σ_w plus, optionally, a first-order Gauss–Markov process of stationary σ_c and correlation time τ,
    exactly discretised on the sample times: x_k = φ_k x_{k−1} + σ_c √(1 − φ_k²) w_k, φ_k = exp(−Δt_k/τ),
    x_0 ~ N(0, σ_c²) (so every sample has variance σ_c², and corr(x_k, x_{k+m}) = exp(−|t_{k+m} − t_k|/τ))."""

    sigma_white_arcsec: float = 0.0
    sigma_correlated_arcsec: float = 0.0
    correlation_time_s: float = 30.0

    def __post_init__(self) -> None:
        for name in ("sigma_white_arcsec", "sigma_correlated_arcsec"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise InputValueError(f"TrackerNoise.{name} must be ≥ 0, got {getattr(self, name)!r}")
        if not (np.isfinite(self.correlation_time_s) and self.correlation_time_s > 0):
            raise InputValueError(f"TrackerNoise.correlation_time_s must be > 0, got {self.correlation_time_s!r}")

    def covariance_rad2(self, t_s: Any) -> np.ndarray:
        """Cov(δ_k, δ_m) (Q, Q) rad² of one axis at the sample times (the axes are independent and alike):
        σ_w² [k = m] + σ_c² exp(−|t_k − t_m|/τ). The estimator models both exactly: the Gauss–Markov part is an AR(1)
        process whose inverse covariance is tridiagonal, carried as one nuisance per sample and axis with that banded
        prior beside the white part's (``boresight.core.line_scan``; this matrix is the tests' dense oracle)."""
        t = np.asarray(t_s, dtype=float)
        arcsec2 = (np.pi / 180.0 / 3600.0) ** 2
        gm = self.sigma_correlated_arcsec**2 * np.exp(-np.abs(t[:, None] - t[None, :]) / self.correlation_time_s)
        result: np.ndarray = (self.sigma_white_arcsec**2 * np.eye(t.size) + gm) * arcsec2
        return result

    def draw_rad(self, rng: np.random.Generator, t_s: Any) -> np.ndarray:
        """δ (Q, 3) rad at the sample times ``t_s`` (Q,): white draws first, then the process's (a fixed order)."""
        t = np.asarray(t_s, dtype=float)
        arcsec = np.pi / 180.0 / 3600.0
        white = rng.standard_normal((t.size, 3)) * self.sigma_white_arcsec * arcsec
        w = rng.standard_normal((t.size, 3))
        if self.sigma_correlated_arcsec == 0.0:
            return white
        phi = np.exp(-np.diff(t) / self.correlation_time_s)
        x = np.empty((t.size, 3))
        x[0] = w[0]
        for k in range(1, t.size):  # a recursion over the (few hundred) tracker samples, not over points
            x[k] = phi[k - 1] * x[k - 1] + np.sqrt(1.0 - phi[k - 1] ** 2) * w[k]
        result: np.ndarray = white + x * self.sigma_correlated_arcsec * arcsec
        return result


def measured_trajectory(traj: StripTrajectory, delta_rad: Any) -> StripTrajectory:
    """The trajectory as the star tracker reports it: A_meas,k = exp(Φ(δ_k)) A_k at each sample (Kiev 2012's δ)."""
    A = dcm_from_quat(traj.tracker_quat)
    A_meas = np.einsum("nij,njk->nik", star_tracker_error_dcm(np.asarray(delta_rad, float)), A)
    return StripTrajectory(
        traj.orbit_t_s,
        traj.orbit_r_i_m,
        traj.orbit_v_i_m_s,
        traj.tracker_t_s,
        quat_from_dcm(A_meas),
        traj.C_ES,
        traj.earth_t_s,
        traj.earth_C_GI,
        traj.orbit_degree,
    )


@dataclass(frozen=True)
class GcpLayout:
    """Ground-control points: ``n_gcps`` at uniformly drawn (line, pixel) of the nominal strip, ``edge_margin_lines``
    / ``edge_margin_pixels`` inside its edges, at heights drawn uniformly in [height_min_m, height_max_m] above WGS84."""

    n_gcps: int = 500
    height_min_m: float = 300.0
    height_max_m: float = 3000.0
    edge_margin_lines: float = 200.0
    edge_margin_pixels: float = 200.0

    def __post_init__(self) -> None:
        if isinstance(self.n_gcps, bool) or not isinstance(self.n_gcps, (int, np.integer)) or self.n_gcps < 1:
            raise InputValueError(f"GcpLayout.n_gcps must be an integer ≥ 1, got {self.n_gcps!r}")
        if not (np.isfinite(self.height_min_m) and np.isfinite(self.height_max_m) and self.height_min_m <= self.height_max_m):
            raise InputValueError(
                f"GcpLayout: need height_min_m ≤ height_max_m, got {self.height_min_m!r}, {self.height_max_m!r}"
            )


@dataclass(frozen=True, eq=False)
class StripSimulation:
    """One simulated strip. Ground-control points: ``gcp_g_m`` (G, 3) in G and ``gcp_height_m`` (G,). Detections
    (one row per chip that sees a point: a point in a chip overlap is detected twice, at different lines):
    ``detection_gcp``, ``detection_chip`` (D,) and the true and measured ``line_*``, ``pixel_*`` (D,). The star
    tracker: ``tracker_delta_rad`` (Q, 3) its errors, ``trajectory_measured`` what it reports. ``truth`` holds the
    hidden effects (``LineScanParameters``)."""

    geometry: StripGeometry
    truth: LineScanParameters
    gcp_g_m: np.ndarray
    gcp_height_m: np.ndarray
    detection_gcp: np.ndarray
    detection_chip: np.ndarray
    line_true: np.ndarray
    pixel_true: np.ndarray
    line_measured: np.ndarray
    pixel_measured: np.ndarray
    tracker_delta_rad: np.ndarray
    trajectory_measured: StripTrajectory


def simulate_strip(
    geometry: StripGeometry,
    truth: LineScanParameters,
    rng: np.random.Generator,
    layout: GcpLayout = GcpLayout(),
    tracker: TrackerNoise = TrackerNoise(),
    sigma_pixel: float = 0.0,
) -> StripSimulation:
    """Simulate a strip (draws in a fixed order: GCP lines, pixels, heights, tracker errors, pixel noise).

    The GCPs are placed by direct location of the drawn (line, pixel) with the nominal model (no effect) on the true
    trajectory; their true detections are the inverse location with the true model (``truth``: θ, timing, chip
    offsets, focal scale, jitter); the measured ones add isotropic pixel noise of ``sigma_pixel`` (px) to line and
    pixel. The star tracker's reports carry ``tracker``'s errors.
    """
    if not (np.isfinite(sigma_pixel) and sigma_pixel >= 0):
        raise InputValueError(f"sigma_pixel must be ≥ 0, got {sigma_pixel!r}")
    cfg, sensor, traj = geometry.config, geometry.config.sensor, geometry.trajectory
    n = layout.n_gcps
    m_l, m_p = layout.edge_margin_lines, layout.edge_margin_pixels
    line0 = rng.uniform(m_l, cfg.n_lines - 1 - m_l, n)
    pixel0 = rng.uniform(m_p, sensor.n_pixels - 1 - m_p, n)
    height = rng.uniform(layout.height_min_m, layout.height_max_m, n)
    gcp = direct_location(sensor, geometry.datation, traj, line0, pixel0, LineScanParameters(), height)
    inv = inverse_location(sensor, geometry.datation, traj, gcp, geometry.line_range, truth)
    chip_idx, gcp_idx = np.nonzero(inv.seen)
    order = np.lexsort((chip_idx, gcp_idx))  # rows by point, then chip
    chip_idx, gcp_idx = chip_idx[order], gcp_idx[order]
    line_t, pixel_t = inv.line[chip_idx, gcp_idx], inv.pixel[chip_idx, gcp_idx]
    delta = tracker.draw_rad(rng, traj.tracker_t_s)
    noise = rng.standard_normal((line_t.size, 2)) * sigma_pixel
    return StripSimulation(
        geometry,
        truth,
        gcp,
        height,
        gcp_idx,
        chip_idx,
        line_t,
        pixel_t,
        line_t + noise[:, 0],
        pixel_t + noise[:, 1],
        delta,
        measured_trajectory(traj, delta),
    )


def simulate_campaign(
    geometries: Sequence[StripGeometry],
    truths: Sequence[LineScanParameters],
    rng: np.random.Generator,
    layout: GcpLayout = GcpLayout(),
    tracker: TrackerNoise = TrackerNoise(),
    sigma_pixel: float = 0.0,
) -> tuple[StripSimulation, ...]:
    """Several strips (different days, sites, roll angles), each with its own truth — a calibration campaign holds θ,
    the chips' offsets, the focal scale and the line-time offset in common and the jitter's phases differ from
    strip to strip; the caller says which. Strip k draws from the k-th generator ``rng.spawn`` gives, so a strip's
    data do not depend on how many strips come after it."""
    if len(geometries) != len(truths) or not geometries:
        raise InputValueError(
            f"simulate_campaign needs one truth per strip, got {len(geometries)} strips and {len(truths)} truths"
        )
    return tuple(
        simulate_strip(geo, truth, child, layout, tracker, sigma_pixel)
        for geo, truth, child in zip(geometries, truths, rng.spawn(len(geometries)), strict=True)
    )


# ---------------------------------------------------------------------------- a strip's detections as rows


@dataclass(frozen=True, eq=False)
class LineScanRecords:
    """The pushbroom context of a set of rows whose images are lines (``docs/architecture.md``, "a pushbroom line is an
    image"): the ``sensor``, its ``datation`` and the ``trajectory`` as the sensors report it (the tracker's measured
    samples, the orbit, the Earth's orientation), and per image (one detection each) its measured ``line`` (N,), ``chip``
    (N,) and line column ``pixel`` (N,). The forward model of a row is ``orbits.pushbroom.sight_tan_psi`` after ``line_sight`` at
    the image's line against ``sensor.tan_psi(chip, j)``; ``light_time`` and ``aberration`` as in ``SightCorrections``."""

    sensor: LineSensor
    datation: Datation
    trajectory: StripTrajectory
    line: np.ndarray
    chip: np.ndarray
    pixel: np.ndarray
    light_time: bool = True
    aberration: bool = True

    def __post_init__(self) -> None:
        n = np.shape(self.line)[0] if np.ndim(self.line) == 1 else -1
        for name in ("line", "chip", "pixel"):
            a = np.asarray(getattr(self, name))
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise InputValueError(f"LineScanRecords.{name} must be ({n},) finite (one per image), got shape {a.shape}")
        chip = np.asarray(self.chip)
        if np.any((chip < 0) | (chip >= self.sensor.n_chips)):
            k = int(np.argmax((chip < 0) | (chip >= self.sensor.n_chips)))
            raise InputValueError(
                f"LineScanRecords.chip[{k}] = {chip[k]} is not a chip of the sensor (0 … {self.sensor.n_chips - 1})"
            )

    @property
    def chip_index(self) -> np.ndarray:
        """(N,) the pixel's index j on its chip."""
        out: np.ndarray = np.asarray(self.pixel, float) - self.sensor.chip_start[np.asarray(self.chip, int)]
        return out

    @cached_property
    def tan_psi_law(self) -> np.ndarray:
        """(N, 2) each image's pixel look angles by its chip's law (``LineSensor.tan_psi`` at κ = 0, no offsets)."""
        return self.sensor.tan_psi(np.asarray(self.chip, int), self.chip_index)

    def images(self, idx: Any) -> "LineScanRecords":
        """The records of the images ``idx`` (an index array)."""
        return LineScanRecords(
            self.sensor,
            self.datation,
            self.trajectory,
            np.asarray(self.line)[idx],
            np.asarray(self.chip)[idx],
            np.asarray(self.pixel)[idx],
            self.light_time,
            self.aberration,
        )


def strip_records(sim: StripSimulation, params: LineScanParameters | None = None) -> dict[str, Any]:
    """A simulated strip's detections as the three tables of the row model (``line_records`` of its measured lines,
    pixels and tracker samples; the targets ``GCP00000`` … one per ground-control point, in the simulator's order)."""
    geo = sim.geometry
    return line_records(
        geo.config.sensor,
        geo.datation,
        sim.trajectory_measured,
        sim.line_measured,
        sim.detection_chip,
        sim.pixel_measured,
        sim.detection_gcp,
        np.array([f"GCP{g:05d}" for g in range(sim.gcp_g_m.shape[0])]),
        sim.gcp_g_m,
        geo.config.epoch,
        params,
    )


def line_records(
    sensor: LineSensor,
    datation: Datation,
    trajectory: StripTrajectory,
    line: Any,
    chip: Any,
    pixel: Any,
    target_index: Any,
    target_ids: Any,
    target_g_m: Any,
    epoch_utc: str,
    params: LineScanParameters | None = None,
    light_time: bool = True,
    aberration: bool = True,
) -> dict[str, Any]:
    """Detections of a pushbroom strip as the three tables of the row model (numpy only; ``boresight.observations.strip``
    builds the ``ObservationSet``; the simulator's ``strip_records`` and the flight readers'
    ``boresight.observations.flight.pushbroom`` both come here): one image per detection, at its measured line's time
    (``params``' datation: the nominal one by default), in time order (stable: equal lines keep their order); its
    attitude the SLERP of the *measured* tracker samples, its position and Earth orientation interpolated
    (``StripTrajectory``); the attitude-sample table the tracker's samples (``tracker_sample_weights``); the targets
    ``target_ids`` (T,) at ``target_g_m`` (T, 3) ITRS; one row per detection (``line``, ``chip``, ``pixel`` the line
    column, ``target_index``, each (D,)) whose measured point is F · tan ψ of its pixel (``LineSensor.tan_psi``,
    nominal: no focal scale, no chip offset). Also ``line_scan``, the ``LineScanRecords`` of the images."""
    params = params or LineScanParameters()
    traj = trajectory
    order = np.argsort(np.asarray(line, float), kind="stable")
    line, chip, pixel, gcp = (
        np.asarray(line, float)[order],
        np.asarray(chip)[order],
        np.asarray(pixel, float)[order],
        np.asarray(target_index)[order],
    )
    n = line.size
    t = line_time_s(datation, line, params)
    r, v = traj.state_i(t)
    k, w = traj.tracker_sample_weights(t)
    records = LineScanRecords(sensor, datation, traj, line, chip, pixel, light_time, aberration)
    F = sensor.focal_length_m
    xy = F * sensor.tan_psi(chip, records.chip_index)
    return dict(
        t_s=t,
        pass_index=np.zeros(n, np.int64),
        q_is=quat_from_dcm(traj.C_IS(t))[None],
        r_sc_i_m=r[None],
        v_sc_i_m_s=v[None],
        C_GI=traj.C_GI(t),
        landmark_ids=np.asarray(target_ids),
        landmark_g_m=np.asarray(target_g_m, float)[None],
        image_index=np.arange(n, dtype=np.int64),
        target_index=gcp.astype(np.int64),
        xy_m=xy[None],
        focal_length_m=F,
        C_SK_nominal=traj.C_ES.T.copy(),
        pixel_pitch_m=sensor.pixel_pitch_m,
        epoch_utc=epoch_utc,
        sample_t_s=np.asarray(traj.tracker_t_s, float),
        sample_index=k.astype(np.int64),
        sample_weight=w,
        line_scan=records,
    )


# ---------------------------------------------------------------------------- pushbroom scenarios


#: the tables of a pushbroom scenario file and the keys each takes (``docs/data-format.md``, "Pushbroom scenarios")
STRIP_SCENARIO_KEYS: dict[str, tuple[str, ...]] = {
    "": ("name", "description", "kind", "sensor", "strip", "strips", "gcps", "noise", "truth", "effects", "estimate"),
    "sensor": ("n_chips", "pixels_per_chip", "overlap_px", "stagger_px", "focal_length_m", "pixel_pitch_m"),
    "strip": (
        "site_lat_deg",
        "site_lon_deg",
        "site_height_m",
        "epoch",
        "altitude_m",
        "inclination_deg",
        "direction",
        "roll_deg",
        "n_lines",
        "line_period_s",
        "tracker_rate_hz",
        "orbit_step_s",
        "margin_s",
        "tracker_mount_rotvec_deg",
    ),
    "gcps": ("n_gcps", "height_min_m", "height_max_m", "edge_margin_lines", "edge_margin_pixels"),
    "noise": ("sigma_pixel_px", "star_tracker_white_arcsec", "star_tracker_correlated_arcsec", "correlation_time_s"),
    "truth": ("theta_arcsec",),
    "estimate": ("line_time_offset", "line_period_error", "focal_scale", "chip_offsets"),
}


@dataclass(frozen=True, eq=False)
class StripScenario:
    """A pushbroom scenario (``kind = "pushbroom"``): one strip or a campaign of strips (``strips``: one
    ``StripConfig`` each, the ``[strip]`` table's values overridden by each ``[[strips]]`` entry), the GCP layout, the
    noise (pixels on line and column; the star tracker's white and Gauss–Markov errors per sample), the true θ and the
    hidden line-scanner effects (``[effects]``: ``orbits.effects.LINE_EFFECTS``, common to every strip), and the
    unknowns ``boresight estimate`` floats besides θ (``[estimate]``)."""

    name: str
    description: str
    strips: tuple[StripConfig, ...]
    layout: GcpLayout
    tracker: TrackerNoise
    sigma_pixel_px: float
    theta_rad: np.ndarray
    effects: dict[str, Any]
    estimate: dict[str, Any]
    source: str = "<dict>"
    _geometries: list[StripGeometry] = field(default_factory=list, repr=False)

    def truth(self) -> LineScanParameters:
        """The forward model's parameters: θ and the hidden effects (``orbits.effects.line_scan_truth``)."""
        from .effects import line_scan_truth

        out: LineScanParameters = line_scan_truth(
            self.theta_rad, self.effects, self.strips[0].sensor.n_chips, f"{self.source}: effects"
        )
        return out

    def geometries(self) -> list[StripGeometry]:
        """Each strip's true geometry (computed once: astropy's Earth orientation takes ~2 s a strip)."""
        if not self._geometries:
            self._geometries.extend(strip_geometry(c) for c in self.strips)
        return list(self._geometries)

    def simulate(self, rng: np.random.Generator) -> tuple[StripSimulation, ...]:
        """One draw of every strip (``simulate_campaign``: strip k from the k-th spawned generator)."""
        geos = self.geometries()
        truth = self.truth()
        return simulate_campaign(geos, [truth] * len(geos), rng, self.layout, self.tracker, self.sigma_pixel_px)


def _table(d: Any, where: str, keys: tuple[str, ...]) -> dict[str, Any]:
    from .errors import checked_table
    from .scenario_schema import ScenarioError

    return checked_table(d, where, keys, ScenarioError)


def strip_scenario_from_dict(data: dict[str, Any], source: str = "<dict>") -> StripScenario:
    """Validate a parsed pushbroom scenario document and build the ``StripScenario`` (every refusal a
    ``ScenarioError`` naming ``source``, the table and the key)."""
    from .scenario_schema import ScenarioError

    d = _table(data, source, STRIP_SCENARIO_KEYS[""])
    if d.get("kind") != "pushbroom":
        raise ScenarioError(f'{source}: kind must be "pushbroom" for a pushbroom scenario, got {d.get("kind")!r}')
    try:
        sensor = zy3_like_sensor(**_table(d.get("sensor", {}), f"{source}: [sensor]", STRIP_SCENARIO_KEYS["sensor"]))
        base = _table(d.get("strip", {}), f"{source}: [strip]", STRIP_SCENARIO_KEYS["strip"])
        entries = d.get("strips", [{}])
        if not isinstance(entries, list) or not entries:
            raise ScenarioError(f"{source}: [[strips]] must be a non-empty array of tables, got {entries!r}")
        strips = []
        for k, e in enumerate(entries):
            kw = {**base, **_table(e, f"{source}: [[strips]] {k}", STRIP_SCENARIO_KEYS["strip"])}
            if "tracker_mount_rotvec_deg" in kw:
                kw["tracker_mount_rotvec_deg"] = tuple(float(v) for v in kw["tracker_mount_rotvec_deg"])
            strips.append(StripConfig(sensor, **kw))
        layout = GcpLayout(**_table(d.get("gcps", {}), f"{source}: [gcps]", STRIP_SCENARIO_KEYS["gcps"]))
        noise = _table(d.get("noise", {}), f"{source}: [noise]", STRIP_SCENARIO_KEYS["noise"])
        tracker = TrackerNoise(
            float(noise.get("star_tracker_white_arcsec", 0.0)),
            float(noise.get("star_tracker_correlated_arcsec", 0.0)),
            float(noise.get("correlation_time_s", 30.0)),
        )
        sigma_px = float(noise.get("sigma_pixel_px", 0.0))
        if not (np.isfinite(sigma_px) and sigma_px >= 0):
            raise ScenarioError(f"{source}: [noise] sigma_pixel_px must be ≥ 0, got {sigma_px!r}")
        truth = _table(d.get("truth", {}), f"{source}: [truth]", STRIP_SCENARIO_KEYS["truth"])
        theta = np.asarray(truth.get("theta_arcsec", [0.0, 0.0, 0.0]), float)
        if theta.shape != (3,) or not np.all(np.isfinite(theta)):
            raise ScenarioError(f"{source}: [truth] theta_arcsec must be 3 finite numbers, got {truth.get('theta_arcsec')!r}")
        est = _table(d.get("estimate", {}), f"{source}: [estimate]", STRIP_SCENARIO_KEYS["estimate"])
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ScenarioError):
            raise
        raise ScenarioError(f"{source}: {exc}") from exc
    sc = StripScenario(
        str(d.get("name", "pushbroom")),
        str(d.get("description", "")),
        tuple(strips),
        layout,
        tracker,
        sigma_px,
        np.radians(theta / 3600.0),
        dict(d.get("effects", {})),
        est,
        source,
    )
    try:
        sc.truth()
    except ValueError as exc:
        raise ScenarioError(str(exc)) from exc
    return sc


def load_strip_scenario(path: Any) -> StripScenario:
    """Read a pushbroom scenario TOML file (a path or a shipped scenario's name, ``orbits.scenario.scenario_path``)."""
    from .files import read_toml
    from .scenario import scenario_path
    from .scenario_schema import ScenarioError

    p = scenario_path(path)
    return strip_scenario_from_dict(read_toml(p, ScenarioError, "scenario"), source=str(p))


def is_strip_scenario(path: Any) -> bool:
    """True when the scenario file (path or shipped name) declares ``kind = "pushbroom"``."""
    from .files import read_toml
    from .scenario import scenario_path
    from .scenario_schema import ScenarioError

    try:
        p = scenario_path(path)
    except ScenarioError:
        return False
    if p.suffix != ".toml":
        return False
    try:
        return read_toml(p, ScenarioError, "scenario").get("kind") == "pushbroom"
    except ScenarioError:
        return False
