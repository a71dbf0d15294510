"""Attitude input: CCSDS AEM (KVN and XML, read by the strict layer ``ccsds.py``) or a CSV of
quaternions with a declared order and frame, as an ``AttitudeTrack`` of the star tracker
(GCRS → star tracker, scalar-last — the observation file's convention) interpolated by SLERP.

Conventions. An AEM quaternion with ``ATTITUDE_DIR = A2B`` rotates frame A into frame B: its
attitude matrix (the same formula as ours, CCSDS 504.0-B ADM annex / Wertz) maps A components to B
components. The inertial frame may be either REF_FRAME_A or REF_FRAME_B; a quaternion that maps
the body (star tracker) to inertial is conjugated, and the reader's notes say so. AEM 1.0 must give
``QUATERNION_TYPE`` (FIRST is reordered) and ``ATTITUDE_DIR``; AEM 2.0 is A2B scalar-last. The non-inertial frame is taken as the star
tracker; give ``C_BS`` (body → star tracker) if the AEM describes the body frame.

DECISION: SLERP, whatever ``INTERPOLATION_METHOD`` says (for quaternions the geodesic interpolation
is what LINEAR means; Lagrange on quaternion components leaves the unit sphere). The error
estimate (``interpolate.slerp``) is refused above ``max_error_arcsec`` (default 0.05″: F·0.05″
= 0.5 µm on a 2.2 m camera, a sixth of a 3 µm pixel σ).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from boresight.observations.flight.common import (
    IngestError,
    InterpolationError,
    by_start,
    sample_offsets,
    segment_of,
)
from boresight.observations.flight.frames import attitude_frame_to_gcrs, conversion, frame_kind
from boresight.observations.flight.interpolate import slerp
from orbits.rotations import ARCSEC

__all__ = ["AttitudeTrack", "read_aem", "read_attitude_csv", "MAX_ATTITUDE_ERROR_ARCSEC"]

MAX_ATTITUDE_ERROR_ARCSEC = 0.05
# DECISION: quaternions are normalised; a norm further than 1 % from 1 is refused as not a
# quaternion. (The CCSDS 504.0-B AEM example itself has a sample of norm 1.0049; Orekit also
# normalises.) Order and conjugation slips keep the norm: the convention doctor catches those.
NORM_TOLERANCE = 0.01


@dataclass(frozen=True)
class AttitudeTrack:
    """Star-tracker attitude samples: ``times`` (astropy Time, K), ``q_is`` (K, 4) GCRS → star tracker, scalar last.

    With several ``segments`` (one per AEM segment), ``at`` interpolates each image time inside the
    one segment whose useable span holds it (``times``/``q_is`` are their concatenation)."""

    times: object
    q_is: np.ndarray
    source: str = ""
    useable: tuple | None = None
    notes: tuple = ()
    segments: tuple = ()
    label: str = ""
    #: (declared CCSDS TIME_SYSTEM, its line, ((alt, δ s), …)) of an AEM segment: names a time-system slip
    #: (``common.time_slip_hint``)
    time_system: tuple = ()

    def describe(self) -> str:
        return f"{self.source} ({self.label or 'SLERP'})"

    def at(self, times, max_error_arcsec: float = MAX_ATTITUDE_ERROR_ARCSEC):
        """(q (Q, 4), error estimate (Q,) rad) at ``times`` by SLERP; refuses times outside the useable spans and errors above the bound."""
        if self.segments:
            k = segment_of(times, [s.useable for s in self.segments], self.source, "attitude")
            q, e = np.zeros((len(times), 4)), np.zeros(len(times))
            for j in np.unique(k):
                sel = np.nonzero(k == j)[0]
                q[sel], e[sel] = self.segments[j].at(times[sel], max_error_arcsec)
            return q, e
        tn, t = sample_offsets(self.times, times, self.useable, self.source, "attitude", self.time_system)
        q, err = slerp(tn, self.q_is, t)
        if np.any(err > max_error_arcsec * ARCSEC):
            worst = int(np.argmax(err))
            raise InterpolationError(
                f"{self.source}: SLERP error estimate {err[worst] / ARCSEC:.3g} arcsec at image time {times[worst].isot} exceeds {max_error_arcsec:g} arcsec; "
                "give denser attitude samples or raise the bound (--max-attitude-error-arcsec)"
            )
        return q, err


def _orient(q_xy, frame_x, frame_y, where, C_BS=None):
    """q (K, 4) scalar-last mapping X → Y; returns q GCRS → star tracker."""
    kx, ky = _is_inertial(frame_x), _is_inertial(frame_y)
    if kx == ky:
        raise IngestError(f"{where}: exactly one of the frames {frame_x!r}, {frame_y!r} must be inertial (ICRF, GCRF, EME2000)")
    if ky:  # body -> inertial given: conjugate
        q_xy = q_xy * np.array([-1.0, -1.0, -1.0, 1.0])
        frame_x, frame_y = frame_y, frame_x
    C = attitude_frame_to_gcrs(frame_kind(frame_x, where))  # frame <- GCRS
    A = Rotation.from_quat(q_xy).as_matrix().transpose(0, 2, 1) @ C  # attitude matrix GCRS -> body
    if C_BS is not None:
        A = np.asarray(C_BS, float) @ A
    q = Rotation.from_matrix(np.swapaxes(A, -1, -2)).as_quat()
    return np.where(q[:, 3:4] < 0, -q, q)


def _is_inertial(name):
    n = str(name).strip().upper()
    return n in ("ICRF", "ICRS", "GCRF", "GCRS", "EME2000", "J2000")


def read_aem(path, C_BS=None, quaternion_type: str | None = None) -> AttitudeTrack:
    """Read a CCSDS AEM (KVN or XML; versions 1.0 and 2.0) of quaternions through the strict layer
    ``ccsds.py``. Each segment keeps its own useable span; nothing is defaulted silently:
    AEM 1.0 must say ``ATTITUDE_DIR`` and ``QUATERNION_TYPE``; AEM 2.0 quaternions are A2B,
    scalar-last (the standard). Which way the quaternions map (inertial → body, or body →
    inertial and therefore conjugated) is returned in ``notes`` for the command to print.
    ``quaternion_type`` (``"FIRST"`` or ``"LAST"``) overrides an AEM 1.0 KVN file's ``QUATERNION_TYPE``: the
    other order, tested by ``culprit`` when the convention check fails (``aem_other_order``)."""
    from boresight.observations.flight import ccsds

    msg = ccsds.read_message(path, "AEM")
    tracks = [_aem_segment(msg, seg, C_BS, quaternion_type) for seg in msg.segments]
    if len(tracks) == 1:
        return tracks[0]
    tracks, t_all = by_start(tracks)
    return AttitudeTrack(
        t_all,
        np.concatenate([t.q_is for t in tracks]),
        str(path),
        (tracks[0].useable[0], tracks[-1].useable[1]),
        tuple(n for t in tracks for n in t.notes),
        tuple(tracks),
        f"{len(tracks)} segments, SLERP in each",
    )


def _aem_segment(msg, seg, C_BS, quaternion_type=None):
    from boresight.observations.flight import ccsds

    md = seg.meta
    w = f"{msg.path}: segment {seg.index + 1}"
    ep, span = ccsds.segment_times(msg, seg)
    vals = ccsds.data_numbers(msg, seg, "attitude line")
    if msg.fmt == "XML":
        q, order = vals[:, :4], "scalar-last (XML names QC)"
    elif msg.version == "1.0" and (quaternion_type or md["QUATERNION_TYPE"].value).strip().upper() == "FIRST":
        q, order = np.roll(vals[:, :4], -1, axis=1), f"scalar-first (QUATERNION_TYPE = FIRST, line {md['QUATERNION_TYPE'].line})"
    elif msg.version == "1.0":
        q, order = vals[:, :4], f"scalar-last (QUATERNION_TYPE = LAST, line {md['QUATERNION_TYPE'].line})"
    else:
        q, order = vals[:, :4], "scalar-last (AEM 2.0)"
    n = np.linalg.norm(q, axis=-1)
    if np.any(np.abs(n - 1) > NORM_TOLERANCE):
        i = int(np.argmax(np.abs(n - 1)))
        raise IngestError(
            f"{msg.path}: line {seg.rows[i][0]}: segment {seg.index + 1}: quaternion norm {n[i]:.9g}, expected 1 (±{NORM_TOLERANCE:g})"
        )
    q = q / n[:, None]
    fa, fb = md["REF_FRAME_A"], md["REF_FRAME_B"]
    d = md.get("ATTITUDE_DIR")
    a2b = d is None or d.value.strip().upper() == "A2B"  # AEM 2.0: always A2B (checked in ccsds.py); 1.0: mandatory
    x, y = (fa, fb) if a2b else (fb, fa)
    dir_text = f"ATTITUDE_DIR = {d.value.strip()} (line {d.line})" if d is not None else "AEM 2.0: A2B"
    ix, iy = _is_inertial(x.value), _is_inertial(y.value)
    if ix == iy:
        both = "both" if ix else "neither"
        raise IngestError(
            f"{msg.path}: line {fa.line}: segment {seg.index + 1}: REF_FRAME_A {fa.value!r} and REF_FRAME_B {fb.value!r}: {both} inertial; "
            "exactly one must be (ICRF, GCRF, EME2000), the other the spacecraft or star-tracker frame"
        )
    inertial, body = (x, y) if ix else (y, x)
    conj = not ix
    qi = _orient(q, x.value, y.value, f"{w}: line {inertial.line}", C_BS)
    note = (
        f"segment {seg.index + 1}: quaternions {order}, {dir_text}: they rotate {x.value.strip()} into {y.value.strip()}"
        + (f", i.e. body → inertial: conjugated to {inertial.value.strip()} → {body.value.strip()}" if conj else "")
        + (f"; {inertial.value.strip()} → GCRS: {conversion(frame_kind(inertial.value, w))}")
    )
    notes = [note]
    m = md.get("INTERPOLATION_METHOD")
    how = "SLERP"
    if m is not None and m.value.strip().upper() not in ("LINEAR", "SLERP"):
        how = f"SLERP (the file asks {m.value.strip().upper()} degree {md['INTERPOLATION_DEGREE'].value.strip()}, line {m.line}; SLERP's error is bounded below)"
    ts, name = md["TIME_SYSTEM"], md["TIME_SYSTEM"].value.strip().upper()
    slip = (name, ts.line, ccsds.time_system_shifts(ep, name))  # for naming a time-system slip (common.time_slip_hint)
    return AttitudeTrack(ep, qi, w if len(msg.segments) > 1 else msg.path, span, tuple(notes), (), how, slip)


def read_attitude_csv(path, order: str, frame: str, direction: str = "inertial_to_body", C_BS=None) -> AttitudeTrack:
    """CSV with ``time_utc`` and ``q0 q1 q2 q3`` as written (``order`` = ``scalar_first`` means q0 is
    the scalar, ``scalar_last`` means q3 is); ``frame`` the inertial frame (ICRF, GCRF/GCRS,
    EME2000); ``direction`` ``inertial_to_body`` or ``body_to_inertial``."""
    from astropy.time import Time

    from boresight.observations.flight.tables import read_csv_columns

    if order not in ("scalar_first", "scalar_last"):
        raise IngestError(f"{path}: quaternion order must be 'scalar_first' or 'scalar_last', got {order!r}")
    if direction not in ("inertial_to_body", "body_to_inertial"):
        raise IngestError(f"{path}: quaternion direction must be 'inertial_to_body' or 'body_to_inertial', got {direction!r}")
    cols = read_csv_columns(path, required=("time_utc", "q0", "q1", "q2", "q3"))
    q = np.stack([cols[f"q{i}"] for i in range(4)], -1)
    if order == "scalar_first":
        q = np.roll(q, -1, axis=-1)
    n = np.linalg.norm(q, axis=-1)
    if np.any(np.abs(n - 1) > NORM_TOLERANCE):
        i = int(np.argmax(np.abs(n - 1)))
        raise IngestError(f"{path}: row {i + 1}: quaternion norm {n[i]:.9g}, expected 1 (±{NORM_TOLERANCE:g})")
    try:
        t = Time(list(cols["time_utc"]), scale="utc")
    except ValueError as exc:
        raise IngestError(f"{path}: column 'time_utc': {exc}") from exc
    dt = np.diff((t - t[0]).to_value("s"))
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) + 1
        raise IngestError(f"{path}: column 'time_utc' row {k}: {t[k].isot} is not after the previous row")
    x, y = (frame, "STAR_TRACKER") if direction == "inertial_to_body" else ("STAR_TRACKER", frame)
    if not _is_inertial(frame):
        raise IngestError(f"{path}: attitude frame {frame!r} is not inertial; use ICRF, GCRF/GCRS or EME2000")
    return AttitudeTrack(t, _orient(q / n[:, None], x, y, str(path), C_BS), str(path))
