"""Landmark catalogue input: a CSV of geodetic WGS84 latitude/longitude/height or ITRS XYZ.

Columns ``landmark`` and either ``lat_deg lon_deg height_m`` (geodetic, WGS84 ellipsoid,
converted with astropy ``EarthLocation.from_geodetic``) or ``X_m Y_m Z_m`` (ITRS, metres).
"""

from __future__ import annotations

import numpy as np

from boresight.observations.flight.common import IngestError
from boresight.observations.flight.tables import read_csv_columns
from boresight.observations.validation import first_outside

__all__ = ["read_landmarks_csv", "write_landmarks_csv"]


def read_landmarks_csv(path) -> tuple[np.ndarray, np.ndarray]:
    """(ids (M,) str, ITRS positions (M, 3) m)."""
    from astropy import units as u
    from astropy.coordinates import EarthLocation

    with open(path, encoding="utf-8") as f:
        head = next((ln for ln in f if ln.strip() and not ln.lstrip().startswith("#")), "")
    names = {h.strip() for h in head.split(",")}
    if {"lat_deg", "lon_deg", "height_m"} <= names:
        c = read_csv_columns(path, required=("landmark", "lat_deg", "lon_deg", "height_m"))
        bad = np.abs(c["lat_deg"]) > 90
        if bad.any():
            i = int(np.argmax(bad))
            raise IngestError(f"{path}: column 'lat_deg' row {i + 1}: {float(c['lat_deg'][i])!r} is outside [-90, 90]")
        loc = EarthLocation.from_geodetic(c["lon_deg"] * u.deg, c["lat_deg"] * u.deg, c["height_m"] * u.m, ellipsoid="WGS84")
        xyz = np.stack([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)], -1)
    elif {"X_m", "Y_m", "Z_m"} <= names:
        c = read_csv_columns(path, required=("landmark", "X_m", "Y_m", "Z_m"))
        xyz = np.stack([c["X_m"], c["Y_m"], c["Z_m"]], -1)
    else:
        raise IngestError(
            f"{path}: a landmark CSV needs columns 'landmark' and 'lat_deg, lon_deg, height_m' (WGS84) or 'X_m, Y_m, Z_m' (ITRS); "
            f"the header has {sorted(names)}"
        )
    _check_on_earth(path, xyz, geodetic={"lat_deg", "lon_deg", "height_m"} <= names)
    ids = c["landmark"]
    u_ids, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        dup = str(u_ids[counts > 1][0])
        raise IngestError(
            f"{path}: column 'landmark': id {dup!r} appears on rows {', '.join(str(i + 1) for i in np.nonzero(ids == dup)[0])}"
        )
    return ids, xyz


#: a landmark's distance from the Earth's centre (m): the WGS84 polar radius less the deepest
#: surface point (Dead Sea shore, −430 m; ocean trenches are no landmarks) and 10 km of margin, to
#: the equatorial radius plus Everest and the same margin
EARTH_RADIUS_RANGE_M = (6356752.0 - 10_000.0, 6378137.0 + 8849.0 + 10_000.0)


def _check_on_earth(path, xyz, geodetic: bool) -> None:
    """Refuse a landmark that is not on the Earth's surface, naming the unit slip that would put it
    there (ECEF in km sat 6 400 m from the centre and the doctor blamed the camera)."""
    lo, hi = EARTH_RADIUS_RANGE_M
    with np.errstate(all="ignore"):
        r = np.linalg.norm(np.asarray(xyz, float), axis=-1)
    i = first_outside(r, lo, hi)
    if i is None:
        return
    if geodetic:
        raise IngestError(
            f"{path}: column 'height_m' row {i + 1}: the landmark is {r[i] - 6371e3:+.4g} m from the mean Earth surface; "
            "heights are metres above the WGS84 ellipsoid"
        )
    why = ""
    for unit, factor in (("kilometres", 1e3), ("millimetres", 1e-3)):
        if lo <= r[i] * factor <= hi:
            why = f": it looks like {unit} (× {factor:g} puts it on the surface); the columns are metres"
    raise IngestError(
        f"{path}: columns 'X_m', 'Y_m', 'Z_m' row {i + 1}: the landmark is {r[i]:.6g} m from the Earth's centre, not on its "
        f"surface ({lo / 1e3:.0f}..{hi / 1e3:.0f} km){why}"
    )


def write_landmarks_csv(path, ids, itrs_m, geodetic: bool = True):
    """Write a landmark CSV (geodetic WGS84 every digit of the double, or ITRS XYZ)."""
    from astropy import units as u
    from astropy.coordinates import EarthLocation

    xyz = np.asarray(itrs_m, float)
    with open(path, "w", encoding="utf-8") as f:
        if geodetic:
            g = EarthLocation.from_geocentric(xyz[:, 0], xyz[:, 1], xyz[:, 2], unit=u.m).to_geodetic("WGS84")
            f.write("landmark,lat_deg,lon_deg,height_m\n")
            for i, name in enumerate(ids):
                f.write(f"{name},{float(g.lat.deg[i])!r},{float(g.lon.deg[i])!r},{float(g.height.to_value(u.m)[i])!r}\n")
        else:
            f.write("landmark,X_m,Y_m,Z_m\n")
            for name, p in zip(ids, xyz):
                f.write(f"{name},{float(p[0])!r},{float(p[1])!r},{float(p[2])!r}\n")
    return path
