"""Orbit input: CCSDS OEM (KVN and XML, read by the strict layer ``ccsds.py``; the ``oem`` package only writes them,
``export.py``), a TLE (propagated with
``sgp4``) or a CSV of positions, as an ``OrbitTrack`` in GCRS interpolated to image times.

DECISION: the OEM's own ``INTERPOLATION`` / ``INTERPOLATION_DEGREE`` are used (LAGRANGE, HERMITE,
LINEAR = Lagrange degree 1); without them Lagrange degree 7, the usual default for OEM producers.
Interpolation happens in GCRS after converting the samples (``frames.to_gcrs``). The error
estimate (``interpolate.py``) is refused above ``max_error_m`` (default 0.05 m: a 0.05 m position
error moves a landmark image by F·0.05/range ≈ 0.16 µm at 680 km with F = 2.2 m, a twentieth of a
3 µm pixel σ). Image times outside the samples (or the OEM's USEABLE span) are refused.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from boresight.observations.flight.common import (
    IngestError,
    InterpolationError,
    by_start,
    require_extra,
    sample_offsets,
    segment_of,
)
from boresight.observations.flight.frames import conversion, eme2000_bias, frame_kind, to_gcrs
from boresight.observations.flight.interpolate import hermite, lagrange
from boresight.observations.validation import first_outside

__all__ = ["OrbitTrack", "PositionSigma", "read_oem", "orbit_from_tle", "read_orbit_csv", "MAX_POSITION_ERROR_M"]

MAX_POSITION_ERROR_M = 0.05
DEFAULT_DEGREE = 7
#: time resolution of the sample and image times as astropy Time differences (two float64 Julian
#: dates: ulp(0.5 day) ≈ 5e-12 s each, twice): the bound adds speed × this (75 nm at 7.5 km/s)
TIME_FLOOR_S = 1e-11


@dataclass(frozen=True)
class PositionSigma:
    """The orbit file's position σ at the image times (``OrbitTrack.position_sigma``), m per axis.

    ``per_image_m`` (Q,) each image's σ (NaN where its segment has no covariance block); ``low_m``, ``high_m`` the
    smallest and largest over the ``n_covered`` images that have one (NaN when none has); ``first_uncovered`` the
    first image without one (None when every image has one); ``noise_model_m`` the one σ a noise model holds (it
    holds one GNSS σ per axis for all images): the largest.

    DECISION: the largest per-image σ, so that the reported σθ stays conservative where the covariance varies along
    the pass.
    """

    per_image_m: np.ndarray
    low_m: float
    high_m: float
    n_covered: int
    first_uncovered: int | None
    noise_model_m: float


@dataclass(frozen=True)
class OrbitTrack:
    """Spacecraft position samples in GCRS: ``times`` (astropy Time, K), ``r_m`` (K, 3), ``v_m_s`` (K, 3) or None.

    A file with several segments gives a track whose ``segments`` are the per-segment tracks
    (``times``/``r_m`` are then their concatenation, for inspection only): ``at`` interpolates
    each image time inside the one segment whose useable span holds it."""

    times: object
    r_m: np.ndarray
    v_m_s: np.ndarray | None
    method: str = "LAGRANGE"
    degree: int = 7
    source: str = ""
    useable: tuple | None = None  # (start, stop) astropy Time
    exact: bool = False  # positions computed at the image times (TLE): no interpolation
    notes: list = field(default_factory=list)
    segments: tuple = ()
    frame: str = ""  # the frame conversion used, as printed
    chosen: str = ""  # where method / degree come from
    resolution_m: float = 0.0  # half a unit in the last written digit of the positions
    covariance: tuple | None = None  # (Time (C,), (C, 3, 3) m² GCRS) from the file's covariance blocks
    label: str = ""
    #: (declared CCSDS TIME_SYSTEM, its line, ((alt, δ s), …)) of an OEM segment: names a time-system slip
    #: (``common.time_slip_hint``)
    time_system: tuple = ()

    def describe(self) -> str:
        """The method, its origin and the frame conversion, as ``boresight ingest`` prints them."""
        if self.exact:
            return f"{self.source} (SGP4 at the image times; {self.frame or 'TEME → GCRS: astropy'})"
        if self.segments:
            return f"{self.source} ({self.label}; {self.frame})"
        how = f"{'Hermite with velocities' if self.method == 'HERMITE' and self.v_m_s is not None else self.method.capitalize()} degree {self.degree}"
        return f"{self.source} ({how}, {self.chosen}; {self.frame})" if self.chosen else f"{self.source} ({how}; {self.frame})"

    def at(self, times, max_error_m: float = MAX_POSITION_ERROR_M):
        """(r (Q, 3) m, v (Q, 3) m/s, error bound (Q,) m) at ``times``; refuses times outside the
        useable spans (naming the gap's two spans) and error bounds above ``max_error_m``."""
        if self.segments:
            k = segment_of(times, [s.useable for s in self.segments], self.source, "orbit")
            r, v, e = np.zeros((len(times), 3)), np.zeros((len(times), 3)), np.zeros(len(times))
            for j in np.unique(k):
                sel = np.nonzero(k == j)[0]
                r[sel], v[sel], e[sel] = self.segments[j].at(times[sel], max_error_m)
            return r, v, e
        tn, t = sample_offsets(self.times, times, self.useable, self.source, "orbit", self.time_system)
        if self.method == "HERMITE" and self.v_m_s is not None:
            r, err = hermite(tn, self.r_m, self.v_m_s, t, self.degree, self.resolution_m)
        else:
            r, err = lagrange(tn, self.r_m, t, self.degree, self.resolution_m)
        if self.v_m_s is not None:
            v, _ = lagrange(tn, self.v_m_s, t, max(self.degree, 1))
        else:  # derivative of the interpolating polynomial (central difference on it, h = 1 ms)
            h = 1e-3
            v = (lagrange(tn, self.r_m, t + h, self.degree)[0] - lagrange(tn, self.r_m, t - h, self.degree)[0]) / (2 * h)
        err = err + np.linalg.norm(v, axis=-1) * TIME_FLOOR_S
        if np.any(err > max_error_m):
            worst = int(np.argmax(err))
            raise InterpolationError(
                f"{self.source}: interpolation error bound {err[worst]:.3g} m at image time {times[worst].isot} exceeds {max_error_m:g} m "
                f"({self.method} degree {self.degree}); give denser orbit samples or raise the bound (--max-position-error-m)"
            )
        return r, v, err

    def sigma_at(self, times):
        """Per-image position σ (m per axis, RMS of the 3 axes) from the file's covariance blocks:
        the block nearest in time within the image's segment, or None without covariance."""
        tracks = self.segments or (self,)
        if not any(s.covariance is not None for s in tracks):
            return None
        k = segment_of(times, [s.useable for s in tracks], self.source, "orbit") if self.segments else np.zeros(len(times), int)
        out = np.full(len(times), np.nan)
        for j in np.unique(k):
            cv = tracks[j].covariance
            if cv is None:
                continue
            sel = np.nonzero(k == j)[0]
            d = np.abs((times[sel][:, None] - cv[0][None, :]).to_value("s")) if len(cv[0]) > 1 else np.zeros((sel.size, 1))
            out[sel] = np.sqrt(np.trace(cv[1][np.argmin(d, axis=1)], axis1=1, axis2=2) / 3.0)
        return out

    def position_sigma(self, times) -> PositionSigma | None:
        """``sigma_at(times)`` with what ``boresight ingest`` reports and writes of it (``PositionSigma``: the range
        over the images, the first image without a covariance block, the noise model's one σ); None without
        covariance."""
        sig = self.sigma_at(times)
        if sig is None:
            return None
        have = np.isfinite(sig)
        lo, hi = (float(np.min(sig[have])), float(np.max(sig[have]))) if have.any() else (np.nan, np.nan)
        first = None if have.all() else int(np.argmax(~have))
        return PositionSigma(sig, lo, hi, int(have.sum()), first, hi)


def read_oem(path, segment: int | None = None) -> OrbitTrack:
    """Read a CCSDS OEM (KVN or XML; versions 1.0, 2.0, 3.0) through the strict layer ``ccsds.py``.

    Each segment keeps its own samples, useable span (USEABLE_START/STOP_TIME, else START/STOP_TIME),
    INTERPOLATION and INTERPOLATION_DEGREE: ``OrbitTrack.at`` interpolates an image time inside one
    segment only, never across a boundary, and refuses an image in a gap naming the two spans.
    ``segment`` (0-based) reads one segment only."""
    from boresight.observations.flight import ccsds

    msg = ccsds.read_message(path, "OEM")
    segs = msg.segments if segment is None else [msg.segments[segment]]
    tracks = [_oem_segment(msg, seg) for seg in segs]
    if len(tracks) == 1:
        return tracks[0]
    return _join(tracks, str(path))


def _oem_segment(msg, seg) -> "OrbitTrack":
    from boresight.observations.flight import ccsds

    md = seg.meta
    w = f"{msg.path}: segment {seg.index + 1}"
    fr = md["REF_FRAME"]
    frame = frame_kind(fr.value, f"{msg.path}: line {fr.line}: segment {seg.index + 1}: REF_FRAME")
    notes = []
    if "REF_FRAME_EPOCH" in md:
        it = md["REF_FRAME_EPOCH"]
        # DECISION: REF_FRAME_EPOCH only matters for frames defined at an epoch (TOD, MOD, TEME of
        # epoch …). GCRF/ICRF/EME2000/ITRF do not depend on one: the keyword is read, checked and
        # said to be unused. TEME with an epoch means TEME frozen at that epoch, which boresight
        # does not model: refused rather than read as TEME of date.
        ccsds.epochs(msg, seg, [(it.value, it.line)])
        if frame == "TEME":
            raise IngestError(
                f"{msg.path}: line {it.line}: segment {seg.index + 1}: REF_FRAME_EPOCH with REF_FRAME TEME (TEME frozen at an epoch) "
                "is not supported; give states in TEME of date (no REF_FRAME_EPOCH), GCRF, EME2000 or ITRF"
            )
        notes.append(
            f"segment {seg.index + 1}: REF_FRAME_EPOCH {it.value} (line {it.line}) not used: {fr.value} does not depend on an epoch"
        )
    ep, (u0, u1) = ccsds.segment_times(msg, seg)
    vals = ccsds.data_numbers(msg, seg, "state line")
    _check_states(msg, seg, vals)
    pos = vals[:, 0:3] * 1e3  # km -> m
    vel = vals[:, 3:6] * 1e3
    pos, vel = to_gcrs(ep, pos, vel, frame)
    if "INTERPOLATION" in md:
        method = md["INTERPOLATION"].value.strip().upper()
        degree = int(md["INTERPOLATION_DEGREE"].value)
        chosen = "the file's INTERPOLATION"
        if method == "LINEAR":
            method, degree = "LAGRANGE", 1
    else:
        # DECISION: a segment without INTERPOLATION gets Lagrange degree 7 (the usual producers'
        # choice, Orekit's default sample count 8) and the report says it is boresight's choice
        method, degree = "LAGRANGE", DEFAULT_DEGREE
        chosen = "no INTERPOLATION in the file: boresight's default"
    cov = _covariance(msg, seg, frame)
    label = f"segment {seg.index + 1}"
    return OrbitTrack(
        ep,
        pos,
        vel,
        method,
        degree,
        w if len(msg.segments) > 1 else msg.path,
        (u0, u1),
        notes=notes,
        frame=f"{fr.value.strip()} → GCRS: {conversion(frame)}",
        chosen=chosen,
        resolution_m=_resolution_m(seg),
        covariance=cov,
        label=label,
        time_system=(
            md["TIME_SYSTEM"].value.strip().upper(),
            md["TIME_SYSTEM"].line,
            ccsds.time_system_shifts(ep, md["TIME_SYSTEM"].value.strip().upper()),
        ),
    )


#: an Earth orbiter's state (km, km/s, km/s²): |r| from below the lowest orbit to beyond the Moon's
#: distance, |v| below the escape speed at the surface plus a margin, |a| below 1 km/s² (gravity at
#: LEO is 0.009 km/s²). DECISION: every state is checked, not only those an image uses:
#: a wild value elsewhere (X_DOT = -1e308) says the file is damaged, and the next pass would use it.
STATE_LIMITS = {"position": (6000.0, 2.0e6, "km"), "velocity": (0.0, 20.0, "km/s"), "acceleration": (0.0, 1.0, "km/s²")}


def _check_states(msg, seg, vals):
    """Refuse (with its line) any OEM state outside ``STATE_LIMITS``."""
    with np.errstate(over="ignore", invalid="ignore"):
        parts = [("position", vals[:, 0:3]), ("velocity", vals[:, 3:6])]
        if vals.shape[1] >= 9:
            parts.append(("acceleration", vals[:, 6:9]))
        for what, block in parts:
            lo, hi, unit = STATE_LIMITS[what]
            norm = np.sqrt(np.sum(block**2, axis=1))
            k = first_outside(norm, lo, hi)
            if k is not None:
                raise IngestError(
                    f"{msg.path}: line {seg.rows[k][0]}: segment {seg.index + 1}: a state's {what} has |{what[0]}| = "
                    f"{norm[k]:.4g} {unit}, outside the {lo:g}..{hi:g} {unit} of an Earth orbiter "
                    f"(fields {' '.join(seg.rows[k][1][1:])[:80]!r}): a damaged line, or units not km / km/s"
                )


def _resolution_m(seg):
    """Half a unit in the last written digit of the position fields (m), the largest over the segment: the rounding floor of the samples."""
    worst = 0.0
    for _, p in seg.rows[: min(len(seg.rows), 200)]:
        for s in p[1:4]:
            m = re.fullmatch(r"[+-]?(\d*)\.?(\d*)(?:[eE]([+-]?\d+))?", s.strip())
            if not m:
                continue
            e = int(m.group(3) or 0)
            worst = max(worst, 0.5 * 10.0 ** (e - len(m.group(2))) * 1e3)
    return worst


def _covariance(msg, seg, frame):
    """(Time (C,), position covariance (C, 3, 3) m² in GCRS axes) of the segment's covariance blocks, or None."""
    if not seg.covariance:
        return None
    from boresight.observations.flight import ccsds

    t = ccsds.epochs(msg, seg, [(c["epoch"].value, c["epoch"].line) for c in seg.covariance])
    P = []
    for c in seg.covariance:
        v = ccsds.numbers(msg, seg, c["line"], c["values"], "covariance")
        L = np.zeros((6, 6))
        L[np.tril_indices(6)] = v
        C = L + np.tril(L, -1).T
        cf = frame if c["frame"] is None else None
        if c["frame"] is not None:
            name = c["frame"].value.strip().upper()
            if name in ("RTN", "RSW", "RIC", "TNW", "QSW", "LVLH"):
                raise IngestError(
                    f"{msg.path}: line {c['frame'].line}: segment {seg.index + 1}: COV_REF_FRAME {c['frame'].value!r} (a local orbital "
                    "frame) is not supported; give the covariance in the segment's REF_FRAME or an inertial frame"
                )
            cf = frame_kind(name, f"{msg.path}: line {c['frame'].line}: segment {seg.index + 1}: COV_REF_FRAME")
        Pr = C[:3, :3] * 1e6  # km² -> m²
        w, _ = np.linalg.eigh(Pr)
        if w[0] < -1e-9 * max(w[-1], 1e-30):
            raise IngestError(
                f"{msg.path}: line {c['line']}: segment {seg.index + 1}: covariance block at EPOCH {c['epoch'].value} is not positive "
                f"semi-definite (position eigenvalue {w[0]:.3g} m²)"
            )
        P.append((Pr, cf))
    # rotate into GCRS axes at each block's epoch: P_GCRS = R P Rᵀ, R = d(GCRS)/d(frame)
    from orbits.earth import itrs_to_gcrs_dcm

    out = []
    for k, (Pr, cf) in enumerate(P):
        if cf == "GCRS":
            Rm = np.eye(3)
        elif cf == "EME2000":
            Rm = eme2000_bias().T
        elif cf == "ITRS":
            Rm = itrs_to_gcrs_dcm(t[k : k + 1])[0]
        else:  # TEME: the rotation from the transform of the three axes
            Rm = np.stack([to_gcrs(t[k : k + 1], 7e6 * np.eye(3)[i][None], None, cf)[0][0] for i in range(3)], axis=1) / 7e6
        out.append(Rm @ Pr @ Rm.T)
    return t, np.array(out)


def _join(tracks, source):
    """One OrbitTrack over several segments (in time order); each keeps its own span and interpolation."""
    tracks, t_all = by_start(tracks)
    notes = [n for t in tracks for n in t.notes]
    methods = sorted({f"{t.method} degree {t.degree}" for t in tracks})
    return OrbitTrack(
        t_all,
        np.concatenate([t.r_m for t in tracks]),
        np.concatenate([t.v_m_s for t in tracks]),
        tracks[0].method,
        tracks[0].degree,
        source,
        (tracks[0].useable[0], tracks[-1].useable[1]),
        notes=notes,
        segments=tuple(tracks),
        frame=tracks[0].frame,
        chosen=tracks[0].chosen,
        label=f"{len(tracks)} segments, " + "; ".join(methods),
    )


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
        raise IngestError(
            f"{source}: SGP4 error code {int(e[k])} at {tt[k].isot} ({sgp4_api.SGP4_ERRORS.get(int(e[k]), '') if hasattr(sgp4_api, 'SGP4_ERRORS') else ''})"
        )
    r, v = to_gcrs(tt, np.asarray(r_km) * 1e3, np.asarray(v_km_s) * 1e3, "TEME")
    return OrbitTrack(
        tt,
        r,
        v,
        "LAGRANGE",
        1,
        source,
        exact=True,
        notes=["positions from a TLE (SGP4): accurate to ~1 km"],
        frame=f"TEME → GCRS: {conversion('TEME')}",
    )


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
    return OrbitTrack(
        t,
        r,
        v,
        "LAGRANGE",
        degree,
        str(path),
        frame=f"{frame} → GCRS: {conversion(kind)}",
        chosen="boresight's default for a CSV",
    )
