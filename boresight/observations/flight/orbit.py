"""Orbit input: CCSDS OEM (KVN and XML, read with the ``oem`` package), a TLE (propagated with
``sgp4``) or a CSV of positions, as an ``OrbitTrack`` in GCRS interpolated to image times.

DECISION: the OEM's own ``INTERPOLATION`` / ``INTERPOLATION_DEGREE`` are used (LAGRANGE, HERMITE,
LINEAR = Lagrange degree 1); without them Lagrange degree 7, the usual default for OEM producers.
Interpolation happens in GCRS after converting the samples (``frames.to_gcrs``). The error
estimate (``interpolate.py``) is refused above ``max_error_m`` (default 0.05 m: a 0.05 m position
error moves a landmark image by F·0.05/range ≈ 0.16 µm at 680 km with F = 2.2 m, a twentieth of a
3 µm pixel σ). Image times outside the samples (or the OEM's USEABLE span) are refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from boresight.observations.flight.common import (
    IngestError, InterpolationError, merge_segments, require_extra, sample_offsets,
)
from boresight.observations.flight.frames import frame_kind, to_gcrs
from boresight.observations.flight.interpolate import hermite, lagrange

__all__ = ["OrbitTrack", "read_oem", "orbit_from_tle", "read_orbit_csv", "MAX_POSITION_ERROR_M"]

MAX_POSITION_ERROR_M = 0.05


@dataclass(frozen=True)
class OrbitTrack:
    """Spacecraft position samples in GCRS: ``times`` (astropy Time, K), ``r_m`` (K, 3), ``v_m_s`` (K, 3) or None."""

    times: object
    r_m: np.ndarray
    v_m_s: np.ndarray | None
    method: str = "LAGRANGE"
    degree: int = 7
    source: str = ""
    useable: tuple | None = None  # (start, stop) astropy Time
    exact: bool = False  # positions computed at the image times (TLE): no interpolation
    notes: list = field(default_factory=list)

    def at(self, times, max_error_m: float = MAX_POSITION_ERROR_M):
        """(r (Q, 3) m, v (Q, 3) m/s, error estimate (Q,) m) at ``times``; refuses times outside the
        samples and errors above ``max_error_m``."""
        tn, t = sample_offsets(self.times, times, self.useable, self.source, "orbit")
        if self.method == "HERMITE" and self.v_m_s is not None:
            r, err = hermite(tn, self.r_m, self.v_m_s, t, self.degree)
        else:
            r, err = lagrange(tn, self.r_m, t, self.degree)
        if self.v_m_s is not None:
            v, _ = lagrange(tn, self.v_m_s, t, max(self.degree, 1))
        else:  # derivative of the interpolating polynomial (central difference on it, h = 1 ms)
            h = 1e-3
            v = (lagrange(tn, self.r_m, t + h, self.degree)[0] - lagrange(tn, self.r_m, t - h, self.degree)[0]) / (2 * h)
        if np.any(err > max_error_m):
            k = int(np.argmax(err))
            raise InterpolationError(
                f"{self.source}: interpolation error estimate {err[k]:.3g} m at image time {times[k].isot} exceeds {max_error_m:g} m "
                f"({self.method} degree {self.degree}); give denser orbit samples or raise the bound (--max-position-error-m)")
        return r, v, err


def _time_scale(name, where):
    from astropy.time import Time

    s = str(name).strip().lower()
    if s not in Time.SCALES:
        raise IngestError(f"{where}: TIME_SYSTEM {name!r} is not supported (use one of {', '.join(sorted(Time.SCALES)).upper()})")
    return s


def read_oem(path, segment: int | None = None) -> OrbitTrack:
    """Read a CCSDS OEM (KVN or XML; v1/v2/v3 as the ``oem`` package supports). All segments are
    joined (they must be one object, one centre EARTH, and in time order)."""
    oem = require_extra("oem")
    from astropy.time import Time

    where = str(path)
    try:
        msg = oem.OrbitEphemerisMessage.open(path)
    except Exception as exc:  # the library raises ValueError/KeyError for malformed files
        raise IngestError(f"{where}: not a readable CCSDS OEM: {exc}") from exc
    segs = list(msg.segments) if segment is None else [list(msg.segments)[segment]]
    times, r, v, methods, degrees, span = [], [], [], set(), set(), []
    for k, seg in enumerate(segs):
        md = seg.metadata
        center = str(md["CENTER_NAME"]).strip().upper()
        if center != "EARTH":
            raise IngestError(f"{where}: segment {k}: CENTER_NAME {md['CENTER_NAME']!r}; boresight needs Earth-centred states (CENTER_NAME = EARTH)")
        frame = frame_kind(md["REF_FRAME"], f"{where}: segment {k}: REF_FRAME")
        states = list(seg.states)
        ep = Time([s.epoch for s in states]).utc
        pos = np.array([s.position for s in states], float) * 1e3  # km -> m
        vel = np.array([s.velocity for s in states], float) * 1e3
        pos, vel = to_gcrs(ep, pos, vel, frame)
        times.append(ep)
        r.append(pos)
        v.append(vel)
        methods.add(str(md["INTERPOLATION"]).upper() if "INTERPOLATION" in md else "LAGRANGE")
        degrees.add(int(md["INTERPOLATION_DEGREE"]) if "INTERPOLATION_DEGREE" in md else 7)
        span.append((Time(seg.useable_start_time).utc, Time(seg.useable_stop_time).utc))
    t_all, order = merge_segments(times, where, "states", " (segments overlap?)")
    method = methods.pop() if len(methods) == 1 else "LAGRANGE"
    if method == "LINEAR":
        method, degree = "LAGRANGE", 1
    else:
        degree = max(degrees)
    if method not in ("LAGRANGE", "HERMITE"):
        raise IngestError(f"{where}: INTERPOLATION {method!r} is not supported (LAGRANGE, HERMITE or LINEAR)")
    useable = (min(s[0] for s in span), max(s[1] for s in span))
    return OrbitTrack(t_all, np.concatenate(r)[order], np.concatenate(v)[order], method, degree, where, useable)


def orbit_from_tle(line1: str, line2: str, times, source: str = "TLE") -> OrbitTrack:
    """Propagate a TLE with SGP4 (``sgp4`` package, WGS72 constants as the TLE was fitted with) to
    ``times`` and convert TEME → GCRS with astropy. A TLE is good to ~1 km: the GNSS σ you give
    must say so (the observation file records the source)."""
    sgp4_api = require_extra("sgp4.api")
    sat = sgp4_api.Satrec.twoline2rv(line1.strip(), line2.strip())
    tt = times.utc
    e, r_km, v_km_s = sat.sgp4_array(tt.jd1, tt.jd2)
    if np.any(e != 0):
        k = int(np.argmax(e != 0))
        raise IngestError(f"{source}: SGP4 error code {int(e[k])} at {tt[k].isot} ({sgp4_api.SGP4_ERRORS.get(int(e[k]), '') if hasattr(sgp4_api, 'SGP4_ERRORS') else ''})")
    r, v = to_gcrs(tt, np.asarray(r_km) * 1e3, np.asarray(v_km_s) * 1e3, "TEME")
    return OrbitTrack(tt, r, v, "LAGRANGE", 1, source, exact=True, notes=["positions from a TLE (SGP4): accurate to ~1 km"])


def read_tle(path):
    """The first two-line element set in a file (an optional name line is allowed): (line1, line2)."""
    lines = [ln.rstrip() for ln in open(path, encoding="utf-8") if ln.strip()]
    for k in range(len(lines) - 1):
        if lines[k].startswith("1 ") and lines[k + 1].startswith("2 "):
            return lines[k], lines[k + 1]
    raise IngestError(f"{path}: no two-line element set found (lines starting '1 ' and '2 ')")


def read_orbit_csv(path, frame: str, degree: int = 7) -> OrbitTrack:
    """CSV with ``time_utc`` and ``x_m y_m z_m`` (optional ``vx_m_s vy_m_s vz_m_s``) in ``frame``
    (ITRF/ITRS/ECEF for GNSS fixes, or GCRS/GCRF/ICRF/EME2000/TEME)."""
    from astropy.time import Time

    from boresight.observations.flight.tables import read_csv_columns

    cols = read_csv_columns(path, required=("time_utc", "x_m", "y_m", "z_m"), optional=("vx_m_s", "vy_m_s", "vz_m_s"))
    kind = frame_kind(frame, f"{path}: --orbit-frame")
    try:
        t = Time(list(cols["time_utc"]), scale="utc")
    except ValueError as exc:
        raise IngestError(f"{path}: column 'time_utc': {exc}") from exc
    r = np.stack([cols["x_m"], cols["y_m"], cols["z_m"]], -1)
    v = np.stack([cols["vx_m_s"], cols["vy_m_s"], cols["vz_m_s"]], -1) if "vx_m_s" in cols else None
    dt = np.diff((t - t[0]).to_value("s"))
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) + 1
        raise IngestError(f"{path}: column 'time_utc' row {k}: {t[k].isot} is not after the previous row")
    r, v = to_gcrs(t, r, v, kind)
    return OrbitTrack(t, r, v, "LAGRANGE", degree, str(path))
