"""A simulated pushbroom strip as an ``ObservationSet`` on rows: one image per line that holds a detection.

``orbits.strip.strip_records`` lays the strip's detections out as the row model's three tables (images at the
measured lines' times, their attitudes interpolated from the measured tracker samples, one target per ground-control
point, one row per detection), with the attitude-sample table that carries the star tracker's errors per sample
(``docs/architecture.md``, "a pushbroom line is an image") and the pushbroom context (``LineScanRecords``) the
measurement model of a line needs (``boresight.core.line_scan``). The frame-camera fields are filled as a frame
camera's would be (a line's ``q_is`` is the SLERP of the measured samples at its time), so the set is checked as any
other; the observation file refuses it (the format cannot carry the sample table yet).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.line_scan import LineScanUnknowns
from boresight.observations.model import ObservationSet
from orbits.pushbroom import LineScanParameters
from orbits.scenario_schema import ScenarioError
from orbits.strip import StripScenario, StripSimulation, strip_records

_ARCSEC = np.pi / 180.0 / 3600.0

__all__ = [
    "strip_observations",
    "simulate_strip_scenario",
    "strip_noise_model",
    "strip_unknowns",
    "line_noise_model",
    "line_unknowns",
]


def strip_observations(
    sim: StripSimulation, noise: dict[str, Any] | None = None, params: LineScanParameters | None = None
) -> ObservationSet:
    """The ``ObservationSet`` of a simulated strip (one run); ``noise`` the sensor noise mapping (``ObservationSet.noise``),
    ``params`` the datation the lines are dated with (default: nominal)."""
    return ObservationSet(**strip_records(sim, params), noise=noise)


def strip_noise_model(sc: StripScenario) -> DisturbanceModel:
    """The noise model of a pushbroom scenario (``line_noise_model`` of its ``[noise]``): the pixel σ, the star
    tracker's white σ and its Gauss–Markov σ and correlation time (``TrackerNoise``, modelled exactly by the GLS:
    ``boresight.core.line_scan``)."""
    sensor = sc.strips[0].sensor
    if sensor.pixel_pitch_m is None or not sc.sigma_pixel_px > 0:
        raise ScenarioError(
            f"{sc.source}: [noise] sigma_pixel_px must be > 0 and [sensor] pixel_pitch_m given to weight the rows"
        )
    tr = sc.tracker
    return line_noise_model(
        sc.sigma_pixel_px,
        tr.sigma_white_arcsec,
        sensor.pixel_pitch_m,
        sc.source,
        sigma_star_tracker_correlated_arcsec=tr.sigma_correlated_arcsec,
        correlation_time_s=tr.correlation_time_s,
    )


def line_noise_model(
    sigma_pixel_px: float,
    sigma_star_tracker_arcsec: float,
    pixel_pitch_m: float | None,
    source: str = "<noise>",
    *,
    sigma_star_tracker_correlated_arcsec: float = 0.0,
    correlation_time_s: float = 30.0,
) -> DisturbanceModel:
    """The noise model of pushbroom lines: the pixel σ on the focal plane (σ px × the pitch), the star tracker's white
    error per sample (mode ``per_image``: per *sample* on lines, ``boresight.core.line_scan``) and its first-order
    Gauss–Markov error of stationary σ ``sigma_star_tracker_correlated_arcsec`` and correlation time
    ``correlation_time_s`` (the same on the three axes, as ``orbits.strip.TrackerNoise`` draws it)."""
    if pixel_pitch_m is None or not sigma_pixel_px > 0:
        raise ScenarioError(f"{source}: the pixel σ must be > 0 and the sensor's pixel pitch given to weight the rows")
    for what, v in (("σ", sigma_star_tracker_arcsec), ("Gauss–Markov σ", sigma_star_tracker_correlated_arcsec)):
        if not (np.isfinite(v) and v >= 0):
            raise ScenarioError(f"{source}: the star tracker's {what} must be ≥ 0, got {v!r} arcsec")
    if not (np.isfinite(correlation_time_s) and correlation_time_s > 0):
        raise ScenarioError(f"{source}: the star tracker's correlation time must be > 0, got {correlation_time_s!r} s")
    return DisturbanceModel(
        sigma_pixel_m=sigma_pixel_px * pixel_pitch_m,
        sigma_star_tracker_rad=(sigma_star_tracker_arcsec * _ARCSEC,) * 3,
        star_tracker_mode="per_image",
        sigma_star_tracker_correlated_rad=(sigma_star_tracker_correlated_arcsec * _ARCSEC,) * 3,
        star_tracker_correlation_time_s=correlation_time_s,
    )


def strip_unknowns(sc: StripScenario) -> LineScanUnknowns:
    """The unknowns a scenario's ``[estimate]`` table floats besides θ."""
    return line_unknowns(sc.estimate, sc.strips[0].sensor.n_chips, f"{sc.source}: [estimate]")


def line_unknowns(e: dict[str, Any], n_chips: int, where: str) -> LineScanUnknowns:
    """The unknowns an ``[estimate]`` table (a pushbroom scenario's, or a pushbroom file's ``estimate``) floats besides θ."""
    known = ("line_time_offset", "line_period_error", "focal_scale", "chip_offsets")
    unknown = sorted(set(e) - set(known))
    if unknown:
        raise ScenarioError(f"{where}: unknown key(s) {unknown}; known: {', '.join(known)}")
    try:
        chips = tuple((int(c), int(a)) for c, a in e.get("chip_offsets", []))
    except (TypeError, ValueError):
        chips = ((-1, -1),)
    bad = [ca for ca in chips if not (0 <= ca[0] < n_chips and ca[1] in (0, 1))]
    if bad:
        raise ScenarioError(f"{where} chip_offsets {bad}: each is [chip 0 … {n_chips - 1}, axis 0 (along) or 1 (across)]")
    return LineScanUnknowns(
        line_time_offset=bool(e.get("line_time_offset", False)),
        line_period_error=bool(e.get("line_period_error", False)),
        focal_scale=bool(e.get("focal_scale", False)),
        chip_offsets=chips,
    )


def simulate_strip_scenario(sc: StripScenario, rng: np.random.Generator) -> list[ObservationSet]:
    """One draw of a pushbroom scenario: an ``ObservationSet`` of lines per strip (``strip_observations``), each with
    the scenario's noise mapping — none when the tracker has a Gauss–Markov part (estimate with
    ``model=strip_noise_model(sc)``)."""
    if sc.tracker.sigma_correlated_arcsec > 0:
        # DECISION: the noise mapping (``ObservationSet.noise``, the frame file's metadata schema) has no key for the
        # tracker's Gauss–Markov error; a mapping of the white part alone would let ``boresight.estimate(strips)`` fit
        # an overconfident σ silently, so the sets carry none and the estimate asks for the model
        return [strip_observations(s) for s in sc.simulate(rng)]
    noise = {
        "pixel": {"sigma_m": sc.sigma_pixel_px * (sc.strips[0].sensor.pixel_pitch_m or 0.0)},
        "star_tracker": {"sigma_arcsec": [sc.tracker.sigma_white_arcsec] * 3, "error_mode": "per_image"},
        "gnss": {"sigma_m": 0.0, "error_mode": "per_pass"},
        "catalogue": {"sigma_m": 0.0},
    }
    return [strip_observations(s, noise) for s in sc.simulate(rng)]
