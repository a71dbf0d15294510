"""Flight-data ingestion: CCSDS OEM / TLE / CSV orbits, CCSDS AEM / CSV attitudes, WGS84 or ITRS
landmarks and pixel detections → an observation file (``docs/tutorial-flight-data.md``).

Libraries (optional extra ``pip install 'boresight[flight]'``): ``oem`` (MIT) reads and writes
OEM, ``ccsds-ndm`` (GPL-3.0-or-later) reads and writes AEM, ``sgp4`` (MIT) propagates TLEs;
astropy (BSD-3) does frames, times and WGS84.

Example
-------
>>> from boresight.io import interpolate
>>> import numpy as np
>>> p, err = interpolate.lagrange([0.0, 1.0, 2.0, 3.0], np.array([0.0, 1.0, 8.0, 27.0]), [1.5], 3)
>>> round(float(p[0, 0]), 12), float(err[0]) > 0
(3.375, True)
"""

from .assemble import assemble
from .attitude import AttitudeTrack, read_aem, read_attitude_csv
from .common import IngestError, InterpolationError
from .detections import read_detections_csv, write_detections_csv
from .export import export_flight_files, write_aem, write_oem
from .landmarks import read_landmarks_csv, write_landmarks_csv
from .orbit import OrbitTrack, orbit_from_tle, read_oem, read_orbit_csv, read_tle
from .pixels import read_camera_toml, read_mount_toml, write_camera_toml

__all__ = [
    "assemble", "AttitudeTrack", "read_aem", "read_attitude_csv", "IngestError", "InterpolationError", "read_detections_csv",
    "write_detections_csv", "export_flight_files", "write_aem", "write_camera_toml", "write_oem", "read_landmarks_csv",
    "write_landmarks_csv", "OrbitTrack", "orbit_from_tle", "read_oem", "read_orbit_csv", "read_tle", "read_camera_toml",
    "read_mount_toml",
]
