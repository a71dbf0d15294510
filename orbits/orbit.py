"""Circular orbit and the seminar's passage over a ground site (Kiev 2012 eqs 25-27).

In Z-polar inertial axes (``orbits.earth`` explains the permutation from the seminar's
Y-polar axes) Kiev 2012 eq 25 reads

    e_c(u) = [cos u cos Ω − sin u sin Ω cos i,  cos u sin Ω + sin u cos Ω cos i,  sin u sin i]
    e_T    = [cos φ* cos Λ_G,  cos φ* sin Λ_G,  sin φ*]

and the passage over the site, e_c(u*) = e_T(Λ_G*), gives
``sin u* = sin φ* / sin i`` (u* in the first/fourth quadrant on an ascending pass, π − that on a
descending one) and ``Λ_G* = atan2(e_c,y, e_c,x)``. At time τ from the passage (eq 26)
``u = u* + ω_o τ`` and ``Λ = Λ_G* + ω_3 τ``.

Example
-------
>>> import numpy as np
>>> orb = CircularOrbit(altitude_m=400e3, inclination_rad=np.radians(98.0), raan_rad=0.0)
>>> p = orb.passage(np.radians(44.45), "ascending")
>>> bool(np.allclose(orb.unit_position(p.u_rad), [np.cos(np.radians(44.45)) * np.cos(p.site_ra_rad),
...     np.cos(np.radians(44.45)) * np.sin(p.site_ra_rad), np.sin(np.radians(44.45))]))
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .earth import MU_EARTH_M3_S2, R_EARTH_M
from .errors import InputValueError

__all__ = ["CircularOrbit", "Passage"]


@dataclass(frozen=True)
class Passage:
    """Solution of e_c = e_T (Kiev 2012 eq 25): argument of latitude and site right ascension."""

    u_rad: float
    """u*, the argument of latitude at the passage."""
    site_ra_rad: float
    """Λ_G*, the site's angle from the inertial x axis at the passage."""
    direction: str


@dataclass(frozen=True)
class CircularOrbit:
    """Circular orbit: altitude above the spherical Earth, inclination, node (SI, radians)."""

    altitude_m: float
    inclination_rad: float
    raan_rad: float = 0.0
    earth_radius_m: float = R_EARTH_M
    mu_m3_s2: float = MU_EARTH_M3_S2

    def __post_init__(self) -> None:
        for name in ("altitude_m", "inclination_rad", "raan_rad", "earth_radius_m"):
            v = getattr(self, name)
            if not np.isfinite(v):
                raise InputValueError(f"CircularOrbit.{name} must be finite, got {v!r}")
        if self.altitude_m <= 0:
            raise InputValueError(f"CircularOrbit.altitude_m must be > 0, got {self.altitude_m!r}")
        if not 0.0 < self.inclination_rad < np.pi:
            raise InputValueError(f"CircularOrbit.inclination_rad must be in (0, π), got {self.inclination_rad!r}")

    @property
    def radius_m(self) -> float:
        return self.earth_radius_m + self.altitude_m

    @property
    def mean_motion_rad_s(self) -> float:
        """ω_o = sqrt(μ / a³) (eq 26)."""
        return float(np.sqrt(self.mu_m3_s2 / self.radius_m**3))

    def unit_position(self, u_rad: Any) -> np.ndarray:
        """e_c(u) of Kiev 2012 eq 25 (Z-polar axes), ``(...,) -> (..., 3)``."""
        u = np.asarray(u_rad, dtype=float)
        cO, sO = np.cos(self.raan_rad), np.sin(self.raan_rad)
        ci, si = np.cos(self.inclination_rad), np.sin(self.inclination_rad)
        cu, su = np.cos(u), np.sin(u)
        return np.stack([cu * cO - su * sO * ci, cu * sO + su * cO * ci, su * si], axis=-1)

    def unit_velocity(self, u_rad: Any) -> np.ndarray:
        """d e_c / du: the along-track unit vector, ``(...,) -> (..., 3)``."""
        u = np.asarray(u_rad, dtype=float)
        cO, sO = np.cos(self.raan_rad), np.sin(self.raan_rad)
        ci, si = np.cos(self.inclination_rad), np.sin(self.inclination_rad)
        cu, su = np.cos(u), np.sin(u)
        return np.stack([-su * cO - cu * sO * ci, -su * sO + cu * cO * ci, cu * si], axis=-1)

    def state(self, u_rad: Any) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and velocity (m/s) in I at argument of latitude ``u``."""
        r = self.radius_m * self.unit_position(u_rad)
        v = self.radius_m * self.mean_motion_rad_s * self.unit_velocity(u_rad)
        return r, v

    def passage(self, site_lat_rad: float, direction: str = "ascending") -> Passage:
        """Solve e_c(u*) = e_T(Λ_G*) for a site at geocentric latitude φ* (Kiev 2012 eq 25).

        Raises ``InputValueError`` (a ``ValueError``) when the inclination never reaches the latitude.
        """
        if direction not in ("ascending", "descending"):
            raise InputValueError(f"direction must be 'ascending' or 'descending', got {direction!r}")
        s = np.sin(site_lat_rad) / np.sin(self.inclination_rad)
        if abs(s) > 1.0:
            reach = np.degrees(min(self.inclination_rad, np.pi - self.inclination_rad))
            raise InputValueError(
                f"site latitude {np.degrees(site_lat_rad):.4f}° is not reached by an orbit of "
                f"inclination {np.degrees(self.inclination_rad):.4f}° (|latitude| ≤ {reach:.4f}°)"
            )
        u = np.arcsin(s)
        if direction == "descending":
            u = np.pi - u
        e = self.unit_position(u)
        return Passage(u_rad=float(u), site_ra_rad=float(np.arctan2(e[1], e[0])), direction=direction)

    def raan_for_site(self, site_unit_i: Any, direction: str = "ascending") -> tuple[float, float]:
        """Node Ω and u* that put the orbit over a given inertial site direction at τ = 0.

        The astropy mode fixes the epoch (so the site's inertial direction) and solves for Ω.
        Returns ``(raan_rad, u_rad)``.
        """
        e = np.asarray(site_unit_i, dtype=float)
        lat = np.arcsin(np.clip(e[2], -1, 1))
        tmp = CircularOrbit(self.altitude_m, self.inclination_rad, 0.0, self.earth_radius_m, self.mu_m3_s2)
        p = tmp.passage(lat, direction)
        raan = np.arctan2(e[1], e[0]) - p.site_ra_rad
        return float(np.mod(raan, 2 * np.pi)), p.u_rad
