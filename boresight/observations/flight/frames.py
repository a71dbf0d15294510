"""Inertial and Earth-fixed frames of flight files → the observation file's GCRS.

* ``GCRF``, ``GCRS``, ``ICRF`` (Earth-centred): the GCRS axes are the ICRS axes (IAU 2000 B1.3); a
  geocentric vector is unchanged.
* ``EME2000`` / ``J2000`` (mean equator and equinox of J2000.0): differs from the GCRS by the
  constant frame bias (~23 mas, 0.8 m at 7000 km): v_EME2000 = B v_GCRS, B from ERFA ``bp06``
  (IERS Conventions 2010 §5.4.4).
* ``ITRF`` (any realisation: ``ITRF``, ``ITRF93``, ``ITRF2000``, ``ITRF2014``, …) and ``ITRS``:
  astropy ITRS → GCRS at each epoch (IERS tables bundled with astropy); velocities transformed
  with the frame's rotation.
* ``TEME`` (SGP4 output): astropy TEME → GCRS.
"""

from __future__ import annotations

import numpy as np

from boresight.observations.flight.common import IngestError

__all__ = [
    "conversion",
    "INERTIAL_FRAMES",
    "EARTH_FIXED_FRAMES",
    "frame_kind",
    "eme2000_bias",
    "to_gcrs",
    "attitude_frame_to_gcrs",
]

INERTIAL_FRAMES = ("GCRF", "GCRS", "ICRF", "EME2000", "J2000", "TEME")
EARTH_FIXED_FRAMES = ("ITRF", "ITRS", "ITRF93", "ITRF97", "ITRF2000", "ITRF2005", "ITRF2008", "ITRF2014", "ITRF2020", "ECEF")


def frame_kind(name: str, where: str) -> str:
    """Canonical frame name ('GCRS', 'EME2000', 'TEME' or 'ITRS') for a file's frame keyword."""
    n = str(name).strip().upper().replace(" ", "")
    if n in ("GCRF", "GCRS", "ICRF", "ICRS"):
        return "GCRS"
    if n in ("EME2000", "J2000"):
        return "EME2000"
    if n == "TEME":
        return "TEME"
    if n in EARTH_FIXED_FRAMES or n.startswith("ITRF"):
        return "ITRS"
    raise IngestError(f"{where}: reference frame {name!r} is not supported; use one of {', '.join(INERTIAL_FRAMES + ('ITRF',))}")


#: how each frame is converted to GCRS, as ``boresight ingest`` prints it
CONVERSIONS = {
    "GCRS": "identity (GCRF/ICRF axes are the GCRS axes)",
    "EME2000": "IERS frame bias (ERFA bp06, 23 mas)",
    "ITRS": "astropy ITRS → GCRS (IAU 2006/2000A, IERS EOP)",
    "TEME": "astropy TEME → GCRS",
}


def conversion(kind: str) -> str:
    """The frame conversion used for a canonical frame (``frame_kind``), in words."""
    return CONVERSIONS[kind]


def eme2000_bias() -> np.ndarray:
    """Frame-bias matrix B (3, 3): v_EME2000 = B v_GCRS (ERFA bp06; date-independent)."""
    import erfa

    rb, _, _ = erfa.bp06(2451545.0, 0.0)
    return np.asarray(rb)


def _transform(times, r, v, src, dst):
    from astropy import units as u
    from astropy.coordinates import GCRS, ITRS, TEME, CartesianDifferential, CartesianRepresentation

    cls = {"GCRS": GCRS, "ITRS": ITRS, "TEME": TEME}
    rep = CartesianRepresentation(r.T * u.m)
    if v is not None:
        rep = rep.with_differentials(CartesianDifferential(v.T * u.m / u.s))
    c = cls[src](rep, obstime=times).transform_to(cls[dst](obstime=times)).cartesian
    return c.xyz.to_value(u.m).T, (None if v is None else c.differentials["s"].d_xyz.to_value(u.m / u.s).T)


def to_gcrs(times, r_m, v_m_s, frame: str, inverse: bool = False):
    """Positions (K, 3) m and velocities (K, 3) m/s or None in ``frame`` → GCRS at ``times``
    (astropy Time); ``inverse=True`` maps GCRS → ``frame`` (to export simulated data)."""
    r = np.asarray(r_m, float)
    v = None if v_m_s is None else np.asarray(v_m_s, float)
    if frame == "GCRS":
        return r, v
    if frame == "EME2000":
        B = eme2000_bias().T if inverse else eme2000_bias()  # row vectors: r @ B = (Bᵀ r)ᵀ, GCRS from EME2000
        return r @ B, (None if v is None else v @ B)
    return _transform(times, r, v, "GCRS", frame) if inverse else _transform(times, r, v, frame, "GCRS")


def attitude_frame_to_gcrs(frame: str) -> np.ndarray:
    """C (3, 3) mapping GCRS components to the attitude reference frame's: A_GCRS→B = A_frame→B · C."""
    if frame == "GCRS":
        return np.eye(3)
    if frame == "EME2000":
        return eme2000_bias()
    raise IngestError(f"attitude reference frame {frame!r} is not inertial; use ICRF, GCRF/GCRS or EME2000")
