"""Earth models: the seminar's spherical Earth and a WGS84 / astropy mode.

Axes: the project uses the usual Z-polar axes for I (inertial) and G (Earth-fixed); the
Kiev 2012 eqs 25-27 put the pole on Y. Their (X, Y, Z) is our (y, z, x) — a cyclic
permutation, so handedness and every formula carry over (``docs/architecture.md``).

Spherical mode (the seminar's): Earth of radius ``R_EARTH_M`` turning uniformly at
``OMEGA_EARTH_RAD_S`` about z; ``C_GI(λ_G) = axis_dcm(2, −λ_G)`` where λ_G is the Greenwich angle.

WGS84 mode: sites from ``astropy.coordinates.EarthLocation`` (geodetic), the real
Earth orientation ITRS → GCRS from astropy at UTC epochs (precession, nutation, polar
motion, UT1 from astropy's bundled IERS tables).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .rotations import axis_dcm

__all__ = [
    "R_EARTH_M",
    "OMEGA_EARTH_RAD_S",
    "MU_EARTH_M3_S2",
    "enu_dcm",
    "greenwich_dcm",
    "geocentric_unit",
    "itrs_to_gcrs_dcm",
    "wgs84_site",
    "geodetic_from_itrs",
    "itrs_from_geodetic",
]

#: mean Earth radius (IUGG R1), the spherical Earth's radius; the seminar gives none.
R_EARTH_M = 6_371_000.0
#: Earth rotation rate, IERS Conventions 2010 (rad/s)
OMEGA_EARTH_RAD_S = 7.292115e-5
#: Earth's gravitational parameter, IERS Conventions 2010 (m^3/s^2)
MU_EARTH_M3_S2 = 3.986004418e14


def geocentric_unit(lat_rad: Any, lon_rad: Any) -> np.ndarray:
    """Unit vector of latitude/longitude, ``(...,) -> (..., 3)``; Kiev 2012 eq 25's e_T in Z-polar axes."""
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat) * np.ones_like(lon)], axis=-1)


def enu_dcm(lat_rad: Any, lon_rad: Any) -> np.ndarray:
    """DCM from the frame the angles are measured in to topocentric T (x east, y north, z up).

    With the inertial right ascension Λ for ``lon_rad`` this is C_IT of Kiev 2012 eq 27
    (rows permuted to Z-polar axes); with the geographic longitude it is C_GT.
    Shape ``(...,) -> (..., 3, 3)``; rows are east, north, up.
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.broadcast_to(np.asarray(lon_rad, dtype=float), np.broadcast(lat, lon_rad).shape)
    lat = np.broadcast_to(lat, lon.shape)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    east = np.stack([-so, co, np.zeros_like(lon)], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([east, north, up], axis=-2)


def greenwich_dcm(greenwich_angle_rad: Any) -> np.ndarray:
    """C_GI for the spherical Earth: Earth-fixed → inertial for a Greenwich angle λ_G (rad)."""
    return axis_dcm(2, -np.asarray(greenwich_angle_rad, dtype=float))


def itrs_to_gcrs_dcm(times: Any) -> np.ndarray:
    """C_GI from astropy: the ITRS → GCRS rotation at each ``astropy.time.Time``, ``(N,) -> (N, 3, 3)``.

    Built by transforming the three ITRS basis vectors (scaled to the Earth's radius, at
    the geocentre's frame origin); the result is a rotation to ~1e-15 (checked in the tests).
    """
    from astropy import units as u
    from astropy.coordinates import GCRS, ITRS, CartesianRepresentation
    from astropy.time import Time

    t = Time(times)
    scalar = t.isscalar
    t = t.reshape(-1) if not scalar else t.reshape(1)
    n = t.size
    cols = []
    for k in range(3):
        e = np.zeros((3, n))
        e[k] = R_EARTH_M
        itrs = ITRS(CartesianRepresentation(e * u.m), obstime=t)
        g = itrs.transform_to(GCRS(obstime=t)).cartesian.xyz.to_value(u.m) / R_EARTH_M
        cols.append(g.T)  # (n, 3): column k of C_GI
    C = np.stack(cols, axis=-1)
    return C[0] if scalar else C


def wgs84_site(lat_deg: float, lon_deg: float, height_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """ITRS position (m) of a geodetic WGS84 site and its C_GT (geodetic east, north, up)."""
    from astropy import units as u
    from astropy.coordinates import EarthLocation

    loc = EarthLocation.from_geodetic(lon_deg * u.deg, lat_deg * u.deg, height_m * u.m, ellipsoid="WGS84")
    r = np.array([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)])
    return r, enu_dcm(np.radians(lat_deg), np.radians(lon_deg))


def geodetic_from_itrs(r_g_m: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS84 geodetic (lat_rad, lon_rad, height_m) of ITRS points (..., 3) (ERFA ``gc2gd``, exact to ~1e-9 m)."""
    import erfa

    lon, lat, h = erfa.gc2gd(1, np.asarray(r_g_m, dtype=float))
    return np.asarray(lat), np.asarray(lon), np.asarray(h)


def itrs_from_geodetic(lat_rad: Any, lon_rad: Any, height_m: Any) -> np.ndarray:
    """ITRS points (..., 3) of WGS84 geodetic coordinates (ERFA ``gd2gc``)."""
    import erfa

    result: np.ndarray = erfa.gd2gc(1, np.asarray(lon_rad, float), np.asarray(lat_rad, float), np.asarray(height_m, float))
    return result
