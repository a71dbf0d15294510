"""A simulated pushbroom strip as an ``ObservationSet`` on rows: one image per line that holds a detection.

``orbits.strip.strip_records`` lays the strip's detections out as the row model's three tables (images at the
measured lines' times, their attitudes interpolated from the measured tracker samples, one target per ground-control
point, one row per detection), with the attitude-sample table that carries the star tracker's errors per sample
(``docs/architecture.md``, "a pushbroom line is an image") and the pushbroom context (``LineScanRecords``) the
measurement model of a line needs (``boresight.core.line_scan``). The frame-camera fields are filled as a frame
camera's would be (a line's ``q_is`` is the SLERP of the measured samples at its time), so the set is checked as any
other; the dense view refuses it (it cannot carry the sample table).
"""

from __future__ import annotations

from typing import Any

from boresight.observations.model import ObservationSet
from orbits.pushbroom import LineScanParameters
from orbits.strip import StripSimulation, strip_records

__all__ = ["strip_observations"]


def strip_observations(
    sim: StripSimulation, noise: dict[str, Any] | None = None, params: LineScanParameters | None = None
) -> ObservationSet:
    """The ``ObservationSet`` of a simulated strip (one run); ``noise`` the sensor noise mapping (``ObservationSet.noise``),
    ``params`` the datation the lines are dated with (default: nominal)."""
    return ObservationSet(**strip_records(sim, params), noise=noise)
