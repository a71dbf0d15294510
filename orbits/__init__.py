"""orbits — the synthetic world of the Kiev 2012 seminar (and an astropy WGS84 mode).

Never imports ``boresight`` (checked in ``tests/test_layering.py``).
"""

from .camera import Camera, back_project_to_plane, back_project_to_sphere, project
from .geometry import PassGeometry, attitude_law, spherical_pass, wgs84_pass
from .orbit import CircularOrbit, Passage
from .rotations import ARCSEC, dcm_from_quat, misalignment_dcm, quat_from_dcm, skew
from .scenario import (
    Scenario,
    ScenarioError,
    campaign_arrays,
    campaign_geometry,
    draw_scenario_errors,
    load_scenario,
    scenario_names,
    scenario_path,
    scenario_from_dict,
    simulate,
)
from .sensors import GnssErrors, PixelNoise, StarTrackerErrors
from .simulate import Measurements, draw_errors, observe

__all__ = [
    "ARCSEC", "Camera", "CircularOrbit", "GnssErrors", "Measurements", "PassGeometry", "Passage", "PixelNoise",
    "Scenario", "ScenarioError", "StarTrackerErrors", "attitude_law", "back_project_to_plane",
    "back_project_to_sphere", "campaign_arrays", "campaign_geometry", "draw_errors", "draw_scenario_errors", "observe", "dcm_from_quat", "load_scenario", "scenario_names", "scenario_path", "misalignment_dcm",
    "project", "quat_from_dcm", "scenario_from_dict", "simulate", "skew",
    "spherical_pass", "wgs84_pass",
]
