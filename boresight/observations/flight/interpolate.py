"""Interpolation of orbit and attitude samples: the one implementation lives in ``orbits.interpolate``.

It moved to the world's layer because the pushbroom sensor model in ``orbits`` needs it
too and ``orbits`` never imports ``boresight``; this module keeps the flight readers' import path.
"""

from orbits.interpolate import SAFETY, hermite, lagrange, slerp, window

__all__ = ["window", "lagrange", "hermite", "slerp", "SAFETY"]
