"""The star camera the star tests share, defined once (imported by name, like ``flight_camera``): F = 2.2 m,
a 3.4° field, 13 µm pixels; and the misalignment θ = [60, −45, 120]″ (Kiev 2012 eq 24 sign) the
star-frame, star-identification and star-row tests simulate their frames with."""

import numpy as np

from orbits.camera import Camera
from orbits.rotations import ARCSEC

CAMERA = Camera(2.2, 3.4, 13e-6)
THETA = np.array([60.0, -45.0, 120.0]) * ARCSEC
