"""Flight-data ingestion: CCSDS OEM / TLE / CSV orbits, CCSDS AEM / CSV attitudes, WGS84 or ITRS
landmarks and pixel detections → an observation file (``docs/tutorial-flight-data.md``).

CCSDS OEM (1.0/2.0/3.0) and AEM (1.0/2.0) are read and checked by ``ccsds.py`` (KVN; XML through
``lxml``, BSD-3). Optional extra ``flight`` (``orbits.errors.extra_hint("flight")``): ``lxml``; ``sgp4`` (MIT)
propagates TLEs. Writing OEM / AEM (``export_flight_files``) needs the extra ``flight-export``:
``oem`` (MIT) and ``ccsds-ndm`` (GPL-3.0-or-later, hence apart: reading installs no GPL code).
astropy (BSD-3) does frames, times and WGS84.

Example
-------
>>> from boresight.observations.flight import interpolate
>>> import numpy as np
>>> p, err = interpolate.lagrange([0.0, 1.0, 2.0, 3.0], np.array([0.0, 1.0, 8.0, 27.0]), [1.5], 3)
>>> round(float(p[0, 0]), 12), float(err[0]) > 0
(3.375, True)
"""

from boresight.observations.flight import ccsds, frames, spice
from boresight.observations.flight.assemble import assemble
from boresight.observations.flight.attitude import AttitudeTrack, read_aem, read_attitude_csv
from boresight.observations.flight.common import IngestError, InterpolationError
from boresight.observations.flight.detections import read_detections_csv, write_detections_csv
from boresight.observations.flight.export import export_flight_files, write_aem, write_oem
from boresight.observations.flight.landmarks import read_landmarks_csv, write_landmarks_csv
from boresight.observations.flight.orbit import OrbitTrack, orbit_from_tle, read_oem, read_orbit_csv, read_tle
from boresight.observations.flight.pixels import read_camera_toml, read_mount_toml, write_camera_toml

__all__ = [
    "ccsds",
    "frames",
    "spice",
    "assemble",
    "AttitudeTrack",
    "read_aem",
    "read_attitude_csv",
    "IngestError",
    "InterpolationError",
    "read_detections_csv",
    "write_detections_csv",
    "export_flight_files",
    "write_aem",
    "write_camera_toml",
    "write_oem",
    "read_landmarks_csv",
    "write_landmarks_csv",
    "OrbitTrack",
    "orbit_from_tle",
    "read_oem",
    "read_orbit_csv",
    "read_tle",
    "read_camera_toml",
    "read_mount_toml",
]
