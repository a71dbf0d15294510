"""orbits — the synthetic world of the Kiev 2012 seminar (and an astropy WGS84 mode).

Never imports ``boresight`` (checked in ``tests/project/test_layering.py``).
"""

import importlib
import warnings
from typing import Any

# DECISION: names resolve on first use (PEP 562): ``import orbits.errors`` (under every boresight
# refusal) and ``boresight --help`` must not build the whole world model. Each public
# name → the module that defines it. (``orbits.simulate_passes`` is the function; the measurement model
# it drives is the module ``orbits.measurements``.)
_EXPORTS = {
    "Camera": "camera",
    "back_project_to_plane": "camera",
    "back_project_to_sphere": "camera",
    "project": "camera",
    "PassGeometry": "geometry",
    "attitude_law": "geometry",
    "spherical_pass": "geometry",
    "wgs84_pass": "geometry",
    "CircularOrbit": "orbit",
    "Passage": "orbit",
    "ARCSEC": "rotations",
    "dcm_from_quat": "rotations",
    "misalignment_dcm": "rotations",
    "quat_from_dcm": "rotations",
    "skew": "rotations",
    "Scenario": "scenario",
    "ScenarioError": "scenario",
    "campaign_arrays": "scenario",
    "campaign_geometry": "scenario",
    "draw_scenario_errors": "scenario",
    "load_scenario": "scenario",
    "scenario_names": "scenario",
    "scenario_path": "scenario",
    "scenario_from_dict": "scenario",
    "simulate_passes": "scenario",
    "GnssErrors": "sensors",
    "PixelNoise": "sensors",
    "StarTrackerErrors": "sensors",
    "StarCatalogue": "star_catalogue",
    "load_hipparcos": "star_catalogue",
    "apparent_directions": "star_apparent",
    "observer_states": "star_apparent",
    "StarDetector": "star_frames",
    "simulate_star_frames": "star_frames",
    "Measurements": "measurements",
    "draw_errors": "measurements",
    "observe": "measurements",
    "LineChip": "camera",
    "LineSensor": "camera",
    "LinearLineDatation": "camera",
    "TabulatedLineDatation": "camera",
    "LineScanParameters": "pushbroom",
    "StripTrajectory": "pushbroom",
    "direct_location": "pushbroom",
    "inverse_location": "pushbroom",
    "locate_on_chips": "pushbroom",
    "StripConfig": "strip",
    "strip_geometry": "strip",
    "simulate_strip": "strip",
    "simulate_campaign": "strip",
    "TrackerNoise": "strip",
    "GcpLayout": "strip",
    "zy3_like_sensor": "strip",
}


#: old name → new name: still resolved, with a ``DeprecationWarning`` (``CHANGES.md``, one release)
_DEPRECATED = {"simulate": "simulate_passes"}


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:  # not cached: every use warns
        new = _DEPRECATED[name]
        warnings.warn(
            f"orbits.{name} is deprecated, use orbits.{new} (the landmark passes' Measurements; "
            "boresight.simulate gives an ObservationSet)",
            DeprecationWarning,
            stacklevel=2,
        )
        return __getattr__(new)
    if name not in _EXPORTS:
        raise AttributeError(f"module 'orbits' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"orbits.{_EXPORTS[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[Any]:
    return sorted(__all__)


__all__ = [
    "ARCSEC",
    "Camera",
    "CircularOrbit",
    "GnssErrors",
    "Measurements",
    "PassGeometry",
    "Passage",
    "PixelNoise",
    "Scenario",
    "ScenarioError",
    "StarCatalogue",
    "StarDetector",
    "StarTrackerErrors",
    "apparent_directions",
    "attitude_law",
    "back_project_to_plane",
    "back_project_to_sphere",
    "campaign_arrays",
    "campaign_geometry",
    "draw_errors",
    "draw_scenario_errors",
    "observe",
    "observer_states",
    "dcm_from_quat",
    "load_hipparcos",
    "load_scenario",
    "scenario_names",
    "scenario_path",
    "misalignment_dcm",
    "project",
    "quat_from_dcm",
    "scenario_from_dict",
    "simulate_passes",
    "simulate_star_frames",
    "skew",
    "spherical_pass",
    "wgs84_pass",
    "LineChip",
    "LineSensor",
    "LinearLineDatation",
    "TabulatedLineDatation",
    "LineScanParameters",
    "StripTrajectory",
    "direct_location",
    "inverse_location",
    "locate_on_chips",
    "StripConfig",
    "strip_geometry",
    "simulate_strip",
    "simulate_campaign",
    "TrackerNoise",
    "GcpLayout",
    "zy3_like_sensor",
]
