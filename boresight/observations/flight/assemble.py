"""Assemble an ``ObservationSet`` from an orbit, an attitude, a landmark catalogue and pixel detections.

Image times are the distinct ``time_utc`` strings of the detections. At each: the GNSS position
(and velocity) from the ``OrbitTrack`` (GCRS), the star-tracker quaternion from the
``AttitudeTrack`` (GCRS → star tracker), C_GI from astropy (``orbits.earth.itrs_to_gcrs_dcm``,
the same function the ECSV reader uses), and the measured focal-plane coordinates from the pixel
detections through the camera calibration (distortion removed). The largest interpolation error
estimates are returned in ``report`` for the command to print.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from boresight.observations.flight.attitude import MAX_ATTITUDE_ERROR_ARCSEC
from boresight.observations.flight.common import IngestError, distinct_times
from boresight.observations.flight.orbit import MAX_POSITION_ERROR_M
from orbits.rotations import ARCSEC

__all__ = ["assemble"]


def assemble(
    orbit,
    attitude,
    landmark_ids,
    landmarks_itrs_m,
    detections,
    camera,
    *,
    C_SK_nominal=None,
    noise=None,
    fov_deg=None,
    max_position_error_m: float = MAX_POSITION_ERROR_M,
    max_attitude_error_arcsec: float = MAX_ATTITUDE_ERROR_ARCSEC,
    source: str = "detections",
    check_geometry: bool = True,
):
    """(ObservationSet with one run, report dict). ``check_geometry=False`` defers the
    behind-the-camera / field test so the convention doctor can run first (``boresight ingest``)."""

    from boresight.observations.model import ObservationSet, canonical_order
    from orbits.earth import itrs_to_gcrs_dcm

    source = detections.get("source", source)
    t_str = np.asarray(detections["time_utc"], dtype=str)
    uniq, tt = distinct_times(t_str, source)
    image_of = {s: n for n, s in enumerate(uniq)}
    ids = [str(i) for i in landmark_ids]
    where_id = {s: m for m, s in enumerate(ids)}
    seen = []
    for k, name in enumerate(detections["landmark"]):
        if str(name) not in where_id:
            raise IngestError(
                f"{source}: column 'landmark' row {k + 1}: {str(name)!r} is not in the landmark catalogue ({len(ids)} ids)"
            )
        if where_id[str(name)] not in seen:
            seen.append(where_id[str(name)])
    keep = sorted(seen)
    cols = {m: j for j, m in enumerate(keep)}
    N, M = uniq.size, len(keep)
    # rows: one per detection, sorted into the canonical (image, landmark) order
    img = np.array([image_of[s] for s in t_str], np.int64)
    tgt = np.array([cols[where_id[str(name)]] for name in detections["landmark"]], np.int64)
    order = canonical_order(img, tgt)
    twice = (img[order][1:] == img[order][:-1]) & (tgt[order][1:] == tgt[order][:-1])
    if np.any(twice):
        k = int(np.min(order[1:][twice]))  # the first repeated detection in file order
        raise IngestError(
            f"{source}: row {k + 1}: landmark {str(detections['landmark'][k])!r} detected twice in the image at {t_str[k]}"
        )
    xy = camera.pixels_to_focal_plane(np.asarray(detections["uv_px"], float))[order]
    r, v, r_err = orbit.at(tt, max_error_m=max_position_error_m)
    q, q_err = attitude.at(tt, max_error_arcsec=max_attitude_error_arcsec)
    epoch = tt[0]
    t_s = (tt - epoch).to_value("s")
    kw = dict(
        t_s=t_s,
        pass_index=np.zeros(N, int),
        q_is=q[None],
        r_sc_i_m=r[None],
        C_GI=itrs_to_gcrs_dcm(tt),
        landmark_ids=np.array([ids[m] for m in keep]),
        landmark_g_m=np.asarray(landmarks_itrs_m, float)[keep][None],
        image_index=img[order],
        target_index=tgt[order],
        xy_m=xy[None],
        focal_length_m=float(camera.focal_length_m),
        C_SK_nominal=np.eye(3) if C_SK_nominal is None else np.asarray(C_SK_nominal, float),
        fov_deg=fov_deg,
        pixel_pitch_m=_pitch(camera),
        epoch_utc=epoch.isot,
        check_geometry=check_geometry,
    )
    names = {f.name for f in fields(ObservationSet)}
    if "check_geometry" not in names:
        kw.pop("check_geometry")
    if "v_sc_i_m_s" in names and v is not None:  # format 1.1: velocity travels in the file
        kw["v_sc_i_m_s"] = v[None]
    if "noise" in names and noise is not None:
        kw["noise"] = noise
    kw["camera"] = camera  # the calibration travels in the file (format 1.1 camera block)
    obs = ObservationSet(**kw)
    report = {
        "images": N,
        "landmarks": M,
        "observations": int(img.size),
        "orbit": orbit.describe() if hasattr(orbit, "describe") else orbit.source,
        "attitude": attitude.describe() if hasattr(attitude, "describe") else attitude.source,
        "max_position_interpolation_error_m": 0.0 if orbit.exact else float(np.max(r_err)),
        "max_attitude_interpolation_error_arcsec": float(np.max(q_err) / ARCSEC),
        "notes": list(getattr(orbit, "notes", [])) + list(getattr(attitude, "notes", ())),
    }
    return obs, report


def _pitch(camera):
    """A square pixel's pitch (m) for the file's ``pixel_pitch_m``, else None."""
    p = getattr(camera, "pixel_pitch_m", None)
    if p is None:
        f = camera.focal_length_px
        return float(camera.focal_length_m / f[0]) if np.isclose(f[0], f[1], rtol=1e-12) else None
    p = np.atleast_1d(np.asarray(p, float))
    return float(p[0]) if np.allclose(p, p[0], rtol=1e-12) else None
