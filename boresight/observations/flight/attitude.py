"""Attitude input: CCSDS AEM (KVN and XML, read with the ``ccsds-ndm`` package) or a CSV of
quaternions with a declared order and frame, as an ``AttitudeTrack`` of the star tracker
(GCRS → star tracker, scalar-last — the observation file's convention) interpolated by SLERP.

Conventions. An AEM quaternion with ``ATTITUDE_DIR = A2B`` rotates frame A into frame B: its
attitude matrix (the same formula as ours, CCSDS 504.0-B ADM annex / Wertz) maps A components to B
components. The inertial frame may be either REF_FRAME_A or REF_FRAME_B; a quaternion that maps
the body (star tracker) to inertial is conjugated. ``QUATERNION_TYPE = FIRST`` is handled by the
reader library (it stores the scalar as ``qc``). The non-inertial frame is taken as the star
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

from orbits.rotations import ARCSEC

from boresight.observations.flight.common import (
    IngestError, InterpolationError, merge_segments, require_extra, sample_offsets,
)
from boresight.observations.flight.frames import attitude_frame_to_gcrs, frame_kind
from boresight.observations.flight.interpolate import slerp

__all__ = ["AttitudeTrack", "read_aem", "read_attitude_csv", "MAX_ATTITUDE_ERROR_ARCSEC"]

MAX_ATTITUDE_ERROR_ARCSEC = 0.05
# DECISION: quaternions are normalised; a norm further than 1 % from 1 is refused as not a
# quaternion. (The CCSDS 504.0-B AEM example itself has a sample of norm 1.0049; Orekit also
# normalises.) Order and conjugation slips keep the norm: the convention doctor catches those.
NORM_TOLERANCE = 0.01


@dataclass(frozen=True)
class AttitudeTrack:
    """Star-tracker attitude samples: ``times`` (astropy Time, K), ``q_is`` (K, 4) GCRS → star tracker, scalar last."""

    times: object
    q_is: np.ndarray
    source: str = ""
    useable: tuple | None = None

    def at(self, times, max_error_arcsec: float = MAX_ATTITUDE_ERROR_ARCSEC):
        """(q (Q, 4), error estimate (Q,) rad) at ``times`` by SLERP; refuses times outside the samples and errors above the bound."""
        tn, t = sample_offsets(self.times, times, self.useable, self.source, "attitude")
        q, err = slerp(tn, self.q_is, t)
        if np.any(err > max_error_arcsec * ARCSEC):
            k = int(np.argmax(err))
            raise InterpolationError(
                f"{self.source}: SLERP error estimate {err[k] / ARCSEC:.3g} arcsec at image time {times[k].isot} exceeds {max_error_arcsec:g} arcsec; "
                "give denser attitude samples or raise the bound (--max-attitude-error-arcsec)")
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


def read_aem(path, C_BS=None) -> AttitudeTrack:
    """Read a CCSDS AEM (KVN or XML) of QUATERNION or QUATERNION/DERIVATIVE type."""
    ndm_io = require_extra("ccsds_ndm.ndm_io")
    from astropy.time import Time

    where = str(path)
    try:
        msg = ndm_io.NdmIo().from_path(path)
    except FileNotFoundError:
        raise
    except Exception as exc:
        raise IngestError(f"{where}: not a readable CCSDS AEM: {exc}") from exc
    if type(msg).__name__ != "Aem":
        raise IngestError(f"{where}: a {type(msg).__name__.upper()} message, not an AEM")
    times, qs, span = [], [], []
    for k, seg in enumerate(msg.body.segment):
        md = seg.metadata
        w = f"{where}: segment {k}"
        atype = str(getattr(md.attitude_type, "value", md.attitude_type)).upper()
        if atype not in ("QUATERNION", "QUATERNION/DERIVATIVE", "QUATERNION/RATE"):
            raise IngestError(f"{w}: ATTITUDE_TYPE {atype!r} is not supported (QUATERNION, QUATERNION/DERIVATIVE, QUATERNION/RATE)")
        scale = str(getattr(md.time_system, "value", md.time_system)).lower()
        if scale not in Time.SCALES:
            raise IngestError(f"{w}: TIME_SYSTEM {scale.upper()!r} is not supported")
        direction = str(getattr(md.attitude_dir, "value", md.attitude_dir)).upper()
        q, ep = [], []
        for i, st in enumerate(seg.data.attitude_state):
            rec = st.quaternion_state or st.quaternion_derivative or getattr(st, "quaternion_euler_rate", None)
            if rec is None:
                raise IngestError(f"{w}: data line {i}: no quaternion")
            qq = rec.quaternion
            q.append([qq.q1, qq.q2, qq.q3, qq.qc])
            ep.append(rec.epoch)
        q = np.asarray(q, float)
        n = np.linalg.norm(q, axis=-1)
        if np.any(np.abs(n - 1) > NORM_TOLERANCE):
            i = int(np.argmax(np.abs(n - 1)))
            raise IngestError(f"{w}: data line {i}: quaternion norm {n[i]:.9g}, expected 1 (±{NORM_TOLERANCE:g})")
        q = q / n[:, None]
        fa, fb = md.ref_frame_a, md.ref_frame_b
        x, y = (fa, fb) if direction == "A2B" else (fb, fa)
        try:
            tt = Time(ep, scale=scale).utc
        except ValueError as exc:
            raise IngestError(f"{w}: epoch: {exc}") from exc
        times.append(tt)
        qs.append(_orient(q, x, y, w, C_BS))
        ustart = md.useable_start_time or md.start_time
        ustop = md.useable_stop_time or md.stop_time
        span.append((Time(ustart, scale=scale).utc, Time(ustop, scale=scale).utc))
    t_all, order = merge_segments(times, where, "attitudes")
    useable = (min(s[0] for s in span), max(s[1] for s in span))
    return AttitudeTrack(t_all, np.concatenate(qs)[order], where, useable)


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
