"""The true geometry of a pass: where the spacecraft, the Earth and the landmarks are.

``spherical_pass`` is the seminar's world (Kiev 2012 eqs 25-27: spherical Earth, circular orbit,
uniform Earth rotation ω3, the pass solved from e_c = e_T). ``wgs84_pass`` is the high-fidelity
mode: the site is a geodetic WGS84 point (astropy ``EarthLocation``), the Earth turns as astropy's
ITRS → GCRS says at a real UTC epoch, and the orbit's node is solved so the spacecraft is over the
site at τ = 0. Both return the same ``PassGeometry`` so everything downstream is shared.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from . import attitude
from .earth import OMEGA_EARTH_RAD_S, R_EARTH_M, enu_dcm, geocentric_unit, greenwich_dcm, itrs_to_gcrs_dcm, wgs84_site
from .errors import InputValueError
from .landmarks import to_earth_fixed
from .orbit import CircularOrbit

__all__ = ["PassGeometry", "spherical_pass", "wgs84_pass", "attitude_law"]


@dataclass(frozen=True)
class PassGeometry:
    """Truth of one pass, images along the first axis (SI units, Z-polar axes).

    t_s (N,) seconds from the passage over the site; r_sc_i_m, v_sc_i_m_s (N, 3) in I;
    C_GI (N, 3, 3) Earth-fixed → inertial; site_g_m (3,), C_GT (3, 3) at the site;
    landmarks_g_m (M, 3) in G; landmarks_t_m (M, 3) as laid out in T.
    """

    t_s: np.ndarray
    r_sc_i_m: np.ndarray
    v_sc_i_m_s: np.ndarray
    C_GI: np.ndarray
    site_g_m: np.ndarray
    C_GT: np.ndarray
    landmarks_g_m: np.ndarray
    landmarks_t_m: np.ndarray
    orbit: CircularOrbit

    def landmarks_i_m(self) -> np.ndarray:
        """Landmarks in I at each image time, (N, M, 3)."""
        result: np.ndarray = np.einsum("nij,mj->nmi", self.C_GI, self.landmarks_g_m)
        return result

    def site_i_m(self) -> np.ndarray:
        """The site in I at each image time, (N, 3)."""
        result: np.ndarray = np.einsum("nij,j->ni", self.C_GI, self.site_g_m)
        return result

    def subsatellite_g(self) -> np.ndarray:
        """Unit vector of the spacecraft position in G, (N, 3) (geocentric sub-satellite track)."""
        r_g = np.einsum("nji,nj->ni", self.C_GI, self.r_sc_i_m)
        result: np.ndarray = r_g / np.linalg.norm(r_g, axis=-1, keepdims=True)
        return result


def _times(t_s: Any) -> Any:
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
        raise InputValueError(f"t_s must be a non-empty 1-D array of finite times, got {t_s!r}")
    return t


def spherical_pass(
    orbit: CircularOrbit,
    site_lat_rad: float,
    site_lon_rad: float,
    t_s: Any,
    landmarks_t_m: Any,
    direction: str = "ascending",
    placement: str = "tangent_plane",
    site_height_m: float = 0.0,
    omega_earth_rad_s: float = OMEGA_EARTH_RAD_S,
) -> PassGeometry:
    """The seminar's pass (Kiev 2012 eqs 25-27) over a site at geocentric latitude/longitude."""
    t = _times(t_s)
    p = orbit.passage(site_lat_rad, direction)
    r, v = orbit.state(p.u_rad + orbit.mean_motion_rad_s * t)  # eq 26: u = u* + ω_o τ
    greenwich = p.site_ra_rad - site_lon_rad + omega_earth_rad_s * t  # Λ = Λ_G* + ω3 τ, λ_G = Λ − λ*
    C_GI = greenwich_dcm(greenwich)
    site_g = (orbit.earth_radius_m + site_height_m) * geocentric_unit(site_lat_rad, site_lon_rad)
    C_GT = enu_dcm(site_lat_rad, site_lon_rad)
    lm_t = np.asarray(landmarks_t_m, dtype=float).reshape(-1, 3)
    lm_g = to_earth_fixed(lm_t, site_g, C_GT, placement)
    return PassGeometry(t, r, v, C_GI, site_g, C_GT, lm_g, lm_t, orbit)


def wgs84_pass(
    altitude_m: float,
    inclination_rad: float,
    site_lat_deg: float,
    site_lon_deg: float,
    epoch: Any,
    t_s: Any,
    landmarks_t_m: Any,
    direction: str = "ascending",
    placement: str = "tangent_plane",
    site_height_m: float = 0.0,
) -> PassGeometry:
    """High-fidelity pass: WGS84 geodetic site, astropy Earth rotation at UTC ``epoch + t_s``.

    The orbit radius is ``R_EARTH_M + altitude_m`` (same as the spherical mode, so the two are
    comparable); its node is solved so that the spacecraft is over the site at τ = 0.
    """
    from astropy import units as u
    from astropy.time import Time

    t = _times(t_s)
    epoch = Time(epoch, scale="utc")
    site_g, C_GT = wgs84_site(site_lat_deg, site_lon_deg, site_height_m)
    C_GI = itrs_to_gcrs_dcm(epoch + t * u.s)
    C_GI0 = itrs_to_gcrs_dcm(epoch)
    e0 = C_GI0 @ site_g
    base = CircularOrbit(altitude_m, inclination_rad, 0.0, R_EARTH_M)
    raan, u0 = base.raan_for_site(e0 / np.linalg.norm(e0), direction)
    orbit = CircularOrbit(altitude_m, inclination_rad, raan, R_EARTH_M)
    r, v = orbit.state(u0 + orbit.mean_motion_rad_s * t)
    lm_t = np.asarray(landmarks_t_m, dtype=float).reshape(-1, 3)
    lm_g = to_earth_fixed(lm_t, site_g, C_GT, placement)
    return PassGeometry(t, r, v, C_GI, site_g, C_GT, lm_g, lm_t, orbit)


def attitude_law(geom: PassGeometry, law: str, yaw_rad: float = 0.0) -> np.ndarray:
    """C_IE (N, 3, 3) for ``law`` in {"nadir", "site_tracking"} (see ``orbits.attitude``)."""
    if law == "nadir":
        return attitude.nadir(geom.r_sc_i_m, geom.v_sc_i_m_s, yaw_rad)
    if law == "site_tracking":
        return attitude.site_tracking(geom.r_sc_i_m, geom.v_sc_i_m_s, geom.site_i_m(), yaw_rad)
    raise InputValueError(f"attitude law must be 'nadir' or 'site_tracking', got {law!r}")
