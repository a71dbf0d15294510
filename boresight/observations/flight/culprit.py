"""Which ingest input explains a failed convention check: the inputs' own slips.

The convention doctor (``observations.doctor``) tests the slips of the camera and attitude
conventions (a mirrored axis, the quaternion order, a transposed mount). A slip in the *other*
inputs — landmark coordinates in the wrong order or unit, an orbit labelled with the wrong frame or
time system — fits none of them: the doctor then says "the declared conventions need a 53°
rotation … check C_SK_nominal, the detector axes and the quaternion convention", or
"inconclusive", and sends the user to the camera. Here each such input hypothesis H is applied to
the assembled observations, the doctor is run again, and H is named when it passes the doctor's
own test (``ConventionReport.passed``: every image within 10× its noise) that the inputs as read
fail, with its declared RMS residual ``GAIN`` (3×) below theirs.

DECISION: not the slips' 100× ratio. A slip of the camera conventions moves residuals by the
field's own size (mm to m); a frame label moves them by the frames' difference, which can be
small — TEME vs GCRS in 2006 is 0.09° of precession, 1.4 mm against 66 µm of noise (21×). The
doctor's per-image 10σ test is what separates: the inputs as read fail it, H passes it.

* **landmarks** (a geodetic CSV): latitude and longitude swapped; radians written under
  ``lat_deg`` / ``lon_deg``; (an XYZ CSV) kilometres under ``X_m`` — also refused at reading
  (``landmarks._check_on_earth``); here for files assembled by other routes;
* **orbit frame**: the positions re-read in every other supported frame (GCRS, ITRS, TEME) than the
  one declared (``REF_FRAME`` or ``--orbit-frame``): r_H = to_gcrs(H, to_gcrs⁻¹(declared, r));
* **time system** of the OEM / AEM epochs (``TIME_SYSTEM``): each of UTC, TAI, GPS, TT instead of
  the declared one. An epoch e read in system S lands at UTC time t(e, S); read in S′ it lands at
  t(e, S′) = t(e, S) + δ, so the track that S′ describes is the one read, shifted: x_H(t) =
  x(t − δ), re-interpolated from the file's own samples (``OrbitTrack.at``, ``AttitudeTrack.at``).

* **quaternion order** of the AEM (``QUATERNION_TYPE``) or the attitude CSV (``--quaternion-order``):
  the file re-read with the other order (``aem_other_order``, ``csv_other_order``) and re-interpolated
  at the image (line) times. The doctor's own ``quaternion_scalar_first`` and
  ``quaternion_read_as_scalar_first`` undo the same slips on the assembled quaternions (both ways, and for
  a body → inertial file the reader conjugated), but only re-reading the file names the file, the key and
  its line, and applies the reader's own conversions exactly.

Each hypothesis costs one doctor run (~0.1 s) and is tried only when the check has already failed.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from boresight.observations.flight.ccsds import TIME_SYSTEMS_TRIED, time_system_shift_s

__all__ = [
    "InputSlip",
    "find_input_slip",
    "file_input_slip",
    "read_checked_naming_inputs",
    "TIME_SYSTEMS_TRIED",
    "FRAMES_TRIED",
    "GAIN",
    "aem_other_order",
    "csv_other_order",
]

#: how much smaller a fitting hypothesis's declared RMS residual must be than the inputs' as read
GAIN = 3.0

#: the orbit frames tried instead of the declared one (``frames.frame_kind`` names)
FRAMES_TRIED = ("GCRS", "ITRS", "TEME")


class InputSlip:
    """A fitting input hypothesis: ``name``, the ``message`` naming the input and the fix, and the
    doctor's report with the hypothesis applied."""

    def __init__(self, name: str, message: str, report: Any):
        self.name, self.message, self.report = name, message, report


def _geodetic(L: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from astropy import units as u
    from astropy.coordinates import EarthLocation

    g = EarthLocation.from_geocentric(L[:, 0], L[:, 1], L[:, 2], unit=u.m).to_geodetic("WGS84")
    return g.lat.deg, g.lon.deg, g.height.to_value(u.m)


def _itrs(lat_deg: np.ndarray, lon_deg: np.ndarray, h_m: np.ndarray) -> np.ndarray:
    from astropy import units as u
    from astropy.coordinates import EarthLocation

    loc = EarthLocation.from_geodetic(lon_deg * u.deg, lat_deg * u.deg, h_m * u.m, ellipsoid="WGS84")
    return np.stack([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)], -1)


def _landmark_hypotheses(obs: Any, landmarks: str, geodetic: bool) -> list[tuple[str, str, Any]]:
    """(name, message head, observations) for the landmark file's slips."""
    L = np.asarray(obs.landmark_g_m[0], float)
    out = []
    if not geodetic:
        if np.median(np.linalg.norm(L, axis=-1)) < 1e5:  # inside the Earth: kilometres? (on its surface: not tried)
            out.append(("landmarks_km", f"{landmarks}: columns 'X_m', 'Y_m', 'Z_m' look like kilometres", L * 1e3))
        return [(n, m, x) for n, m, x in out]
    lat, lon, h = _geodetic(L)
    latlon = (
        "the landmarks' latitudes and longitudes (landmark_g_m read back as WGS84)"
        if "landmark_g_m" in landmarks
        else "columns 'lat_deg' and 'lon_deg'"
    )
    if np.all(np.abs(lon) <= 90.0):
        out.append(
            (
                "landmarks_lat_lon_swapped",
                f"{landmarks}: {latlon} look swapped (latitude written as longitude and back)",
                _itrs(lon, lat, h),
            )
        )
    if np.all(np.abs(lat) <= np.pi / 2 + 1e-9) and np.all(np.abs(lon) <= 2 * np.pi + 1e-9):
        out.append(
            (
                "landmarks_radians",
                f"{landmarks}: {latlon} look like radians (× 180/π gives the latitude and longitude)",
                _itrs(np.degrees(lat), np.degrees(lon), h),
            )
        )
    return out


def _image_times(obs: Any) -> Any:
    from astropy import units as u
    from astropy.time import Time

    return Time(obs.epoch_utc, scale="utc") + np.asarray(obs.t_s, float) * u.s


def _frame_hypotheses(obs: Any, declared: str, orbit_input: str) -> list[tuple[str, str, Any]]:
    """(name, message head, observations) with the orbit positions re-read in another frame."""
    from boresight.errors import BoresightError
    from boresight.observations.flight.frames import to_gcrs

    t = _image_times(obs)
    r = np.asarray(obs.r_sc_i_m[0], float)
    raw, _ = to_gcrs(t, r, None, declared, inverse=True)  # the numbers as the file wrote them
    out = []
    for alt in FRAMES_TRIED:
        if alt == declared:
            continue
        r_alt, _ = to_gcrs(t, raw, None, alt)
        try:
            alt_obs = replace(obs, r_sc_i_m=np.asarray(r_alt)[None])
        except (BoresightError, ValueError):
            continue
        out.append(
            (
                f"orbit_frame_{alt.lower()}",
                f"{orbit_input}: the orbit looks like {alt} although its frame is declared {declared}",
                alt_obs,
            )
        )
    return out


def _time_hypotheses(obs: Any, track: Any, declared: str, which: str, input_name: str) -> list[tuple[str, str, Any]]:
    """(name, message head, observations) with the orbit or attitude re-sampled as if its epochs
    were in another time system; a shift the track cannot cover is skipped."""
    from astropy import units as u

    from boresight.errors import BoresightError

    t = _image_times(obs)
    out = []
    for alt in TIME_SYSTEMS_TRIED:
        if alt == declared:
            continue
        d = time_system_shift_s(t, declared, alt)
        try:
            if which == "orbit":
                r = np.asarray(track.at(t - d * u.s, max_error_m=np.inf)[0])
                alt_obs = replace(obs, r_sc_i_m=r[None])
            else:
                q = np.asarray(track.at(t - d * u.s, max_error_arcsec=np.inf)[0])
                alt_obs = replace(obs, q_is=q[None])
        except (BoresightError, ValueError):
            continue  # the shifted times leave the samples: not testable here
        out.append(
            (
                f"{which}_time_{alt.lower()}",
                f"{input_name}: the {which} epochs look like {alt} although TIME_SYSTEM is {declared} (a {d:+.4g} s shift)",
                alt_obs,
            )
        )
    return out


def aem_other_order(path: Any) -> tuple[str, Any] | None:
    """(message head, attitude track) of an AEM 1.0 KVN file re-read with the other ``QUATERNION_TYPE``
    than its first segment declares, or None (AEM 2.0 and XML have one order; a file the reader then
    refuses is no hypothesis)."""
    from boresight.errors import BoresightError
    from boresight.observations.flight import ccsds
    from boresight.observations.flight.attitude import read_aem

    try:
        msg = ccsds.read_message(path, "AEM")
        item = msg.segments[0].meta.get("QUATERNION_TYPE")
        if msg.fmt == "XML" or item is None:
            return None
        declared = item.value.strip().upper()
        alt = "LAST" if declared == "FIRST" else "FIRST"
        track = read_aem(path, quaternion_type=alt)
    except (BoresightError, ValueError, OSError):
        return None
    head = (
        f"{path}: QUATERNION_TYPE = {declared} (line {item.line}) but the quaternions look scalar-{alt.lower()} "
        f"(write QUATERNION_TYPE = {alt})"
    )
    return head, track


def csv_other_order(path: Any, order: str, frame: str, direction: str) -> tuple[str, Any] | None:
    """(message head, attitude track) of an attitude CSV re-read with the other ``--quaternion-order``, or None."""
    from boresight.errors import BoresightError
    from boresight.observations.flight.attitude import read_attitude_csv

    alt = "scalar_last" if order == "scalar_first" else "scalar_first"
    try:
        track = read_attitude_csv(path, alt, frame, direction)
    except (BoresightError, ValueError, OSError):
        return None
    return (
        f"--attitude-csv {path}: --quaternion-order {order} but the quaternions look {alt} (give --quaternion-order {alt})",
        track,
    )


def _order_hypotheses(obs: Any, reordered: tuple[str, Any]) -> list[tuple[str, str, Any]]:
    """(name, message head, observations) with the attitude re-read in the other quaternion order."""
    from boresight.errors import BoresightError

    head, track = reordered
    try:
        q = np.asarray(track.at(_image_times(obs), max_error_arcsec=np.inf)[0])
        return [("attitude_quaternion_order", head, replace(obs, q_is=q[None]))]
    except (BoresightError, ValueError):
        return []


def find_input_slip(
    obs: Any,
    report: Any,
    *,
    landmarks: str | None = None,
    landmarks_geodetic: bool = True,
    orbit_input: str | None = None,
    orbit_frame: str | None = None,
    orbit_track: Any = None,
    orbit_time_system: str | None = None,
    attitude_input: str | None = None,
    attitude_track: Any = None,
    attitude_time_system: str | None = None,
    attitude_reordered: tuple[str, Any] | None = None,
) -> InputSlip | None:
    """The input hypothesis that explains a failed doctor ``report`` (``diagnose_conventions`` of
    ``obs``), or None: the one whose declared RMS residual is smallest among those that pass the
    doctor and fit ``GAIN``× better than the inputs as read. Each argument left None skips its
    hypotheses (``orbit_frame``: a ``frames.frame_kind`` name; time systems: CCSDS names;
    ``attitude_reordered``: ``aem_other_order`` or ``csv_other_order`` of the attitude input)."""
    from boresight.errors import BoresightError
    from boresight.observations.doctor import diagnose_conventions

    if report.passed:
        return None
    hyps: list[tuple[str, str, Any]] = []
    if landmarks is not None:
        for name, head, L in _landmark_hypotheses(obs, landmarks, landmarks_geodetic):
            try:  # a hypothesis the data model refuses (a landmark beyond its bounds) is not a fit
                hyps.append((name, head, replace(obs, landmark_g_m=np.asarray(L)[None])))
            except (BoresightError, ValueError):
                continue
    if orbit_frame is not None and orbit_input is not None:
        hyps += _frame_hypotheses(obs, orbit_frame, orbit_input)
    if orbit_track is not None and orbit_time_system in TIME_SYSTEMS_TRIED and orbit_input is not None:
        hyps += _time_hypotheses(obs, orbit_track, orbit_time_system, "orbit", orbit_input)
    if attitude_track is not None and attitude_time_system in TIME_SYSTEMS_TRIED and attitude_input is not None:
        hyps += _time_hypotheses(obs, attitude_track, attitude_time_system, "attitude", attitude_input)
    if attitude_reordered is not None:
        hyps += _order_hypotheses(obs, attitude_reordered)
    d0 = report.rms_m["declared"]
    best = None
    for name, head, alt in hyps:
        with np.errstate(all="ignore"):
            rep = diagnose_conventions(alt)
        d = rep.rms_m["declared"]
        if rep.passed and d * GAIN < d0 and (best is None or d < best[2].rms_m["declared"]):
            best = (name, head, rep)
    if best is None:
        return None
    name, head, rep = best
    msg = (
        f"{head}: with it undone the images fit the declared camera conventions — RMS residual {d0:.3g} m as read, "
        f"{rep.rms_m['declared']:.3g} m with it undone (rotation needed {report.rotation_deg['declared']:.3g}° → "
        f"{rep.rotation_deg['declared']:.3g}°)"
    )
    return InputSlip(name, msg, rep)


def file_input_slip(obs: Any, report: Any, source: str) -> InputSlip | None:
    """``find_input_slip`` for an observation file already written (``boresight check``): the
    landmark hypotheses on its ``landmark_g_m`` (read back as WGS84 latitude, longitude, height)
    and the orbit frame on its ``r_sc_i_m`` (declared GCRS); the time systems need the flight
    tracks and are tested by ``ingest`` only."""
    return find_input_slip(
        obs,
        report,
        landmarks=f"{source}: landmark_g_m",
        landmarks_geodetic=bool(np.median(np.linalg.norm(np.asarray(obs.landmark_g_m[0], float), axis=-1)) > 1e5),
        orbit_input=f"{source}: r_sc_i_m",
        orbit_frame="GCRS",
    )


def read_checked_naming_inputs(path, check: bool = True) -> Any:
    """``doctor.read_checked``, but a failed convention check whose cause is the landmarks' or the
    orbit's own slip (``file_input_slip``) is refused naming that instead of the camera: the
    reader of ``estimate``, ``diagnose`` and ``montecarlo FILE``."""
    from boresight.observations.doctor import ConventionError, read_checked
    from boresight.observations.ecsv import read_ecsv

    try:
        return read_checked(path, check=check)
    except ConventionError as exc:
        report = getattr(exc, "report", None)
        if report is None or report.verdict not in (None, "large_rotation"):
            raise  # a camera-convention slip: the doctor named it
        try:
            obs = read_ecsv(path, geometry_checks=False)
            slip = file_input_slip(obs, report, str(path))
        except Exception:  # noqa: BLE001 - the doctor's own refusal stands
            slip = None
        if slip is None:
            raise
        raise ConventionError(f"{path}: {slip.message}", slip=slip.name, report=slip.report) from exc
