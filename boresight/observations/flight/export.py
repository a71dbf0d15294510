"""Export an ``ObservationSet`` as flight-style files — CCSDS OEM (``oem`` package's writer), CCSDS
AEM (``ccsds-ndm``'s writer), landmark CSV, pixel-detection CSV and camera TOML — so the ingestion
chain can be tested end to end (simulate → export → ``boresight ingest`` → estimate) and example
data sets can be made (``examples/make_flight_example.py``)."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

from boresight.observations.flight.common import require_extra
from boresight.observations.flight.detections import write_detections_csv
from boresight.observations.flight.frames import frame_kind, to_gcrs
from boresight.observations.flight.interpolate import lagrange
from boresight.observations.flight.landmarks import write_landmarks_csv
from boresight.observations.flight.pixels import write_camera_toml

__all__ = ["write_oem", "write_aem", "export_flight_files", "write_camera_toml"]


def _iso(t):
    return [s for s in t.utc.isot]


def write_oem(
    path,
    times,
    r_gcrs_m,
    v_gcrs_m_s=None,
    *,
    frame: str = "GCRF",
    fmt: str = "kvn",
    interpolation: str = "LAGRANGE",
    degree: int = 7,
    object_name: str = "BORESIGHT-SIM",
    object_id: str = "2026-000A",
):
    """A CCSDS OEM v2.0 (KVN or XML) of GCRS states, written in ``frame`` (GCRF, EME2000, ITRF, TEME) by the ``oem`` package."""
    oem = require_extra("oem")
    from oem.components import EphemerisSegment, HeaderSection, MetaDataSection

    r = np.asarray(r_gcrs_m, float)
    if v_gcrs_m_s is None:  # velocity: derivative of the interpolating polynomial of the positions
        ts = (times - times[0]).to_value("s")
        h = 1e-3
        v_gcrs_m_s = (
            lagrange(ts, r, ts + h, min(degree, r.shape[0] - 1))[0] - lagrange(ts, r, ts - h, min(degree, r.shape[0] - 1))[0]
        ) / (2 * h)
    rr, vv = to_gcrs(times, r, np.asarray(v_gcrs_m_s, float), frame_kind(frame, "write_oem"), inverse=True)
    iso = _iso(times)
    header = HeaderSection(
        {
            "CCSDS_OEM_VERS": "2.0",
            "CREATION_DATE": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S"),
            "ORIGINATOR": "boresight",
        }
    )
    md = MetaDataSection(
        {
            "OBJECT_NAME": object_name,
            "OBJECT_ID": object_id,
            "CENTER_NAME": "EARTH",
            "REF_FRAME": frame,
            "TIME_SYSTEM": "UTC",
            "START_TIME": iso[0],
            "STOP_TIME": iso[-1],
            "INTERPOLATION": interpolation,
            "INTERPOLATION_DEGREE": str(degree),
        },
        version="2.0",
    )
    from astropy.time import Time

    epochs = tuple(Time(iso, scale="utc", precision=6))
    cols = [tuple(rr[:, k] / 1e3) for k in range(3)] + [tuple(vv[:, k] / 1e3) for k in range(3)]
    seg = EphemerisSegment(md, (epochs, *cols), version="2.0")
    msg = oem.OrbitEphemerisMessage(header, [seg])
    msg.save_as(path, file_format=fmt)
    return path


def write_aem(
    path,
    times,
    q_is,
    *,
    frame_a: str = "ICRF",
    frame_b: str = "STAR_TRACKER",
    direction: str = "A2B",
    quaternion_type: str = "LAST",
    fmt: str = "kvn",
    object_name: str = "BORESIGHT-SIM",
    object_id: str = "2026-000A",
):
    """A CCSDS AEM (KVN or XML) of GCRS → star-tracker quaternions (ICRF axes = GCRS axes), written by ``ccsds-ndm``."""
    ndm_io = require_extra("ccsds_ndm.ndm_io")
    from ccsds_ndm.mapping import NDMFileFormats
    from ccsds_ndm.models.ndmxml2.ndmxml_2_0_0_aem_1_0 import (
        AemBody,
        AemData,
        AemMetadata,
        AemSegment,
        AttitudeStateType,
        AttitudeTypeType,
        QuaternionEphemerisType,
        QuaternionTypeType,
    )
    from ccsds_ndm.models.ndmxml2.ndmxml_2_0_0_common_2_0 import NdmHeader, QuaternionType, RotDirectionType, TimeSystemType
    from ccsds_ndm.models.ndmxml2.ndmxml_2_0_0_master_2_0 import Aem

    q = np.asarray(q_is, float)
    if direction == "B2A":
        q = q * np.array([-1.0, -1.0, -1.0, 1.0])
    iso = _iso(times)
    states = [
        AttitudeStateType(
            quaternion_state=QuaternionEphemerisType(
                epoch=s, quaternion=QuaternionType(qc=float(x[3]), q1=float(x[0]), q2=float(x[1]), q3=float(x[2]))
            )
        )
        for s, x in zip(iso, q)
    ]
    md = AemMetadata(
        object_name=object_name,
        object_id=object_id,
        center_name="EARTH",
        ref_frame_a=frame_a,
        ref_frame_b=frame_b,
        attitude_dir=RotDirectionType.A2_B if direction == "A2B" else RotDirectionType.B2_A,
        time_system=TimeSystemType.UTC,
        start_time=iso[0],
        stop_time=iso[-1],
        attitude_type=AttitudeTypeType.QUATERNION_1,
        quaternion_type=QuaternionTypeType.LAST_1 if quaternion_type == "LAST" else QuaternionTypeType.FIRST_1,
        interpolation_method="LINEAR",
        interpolation_degree=1,
    )
    msg = Aem(
        header=NdmHeader(creation_date=datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S"), originator="boresight"),
        body=AemBody(segment=[AemSegment(metadata=md, data=AemData(attitude_state=states))]),
    )
    ndm_io.NdmIo().to_file(msg, NDMFileFormats.KVN if fmt == "kvn" else NDMFileFormats.XML, str(path))
    return path


def export_flight_files(
    obs,
    folder,
    camera,
    *,
    fov_deg=None,
    run: int = 0,
    oem_frame: str = "GCRF",
    fmt: str = "kvn",
    geodetic: bool = True,
    oem_times=None,
    r_samples=None,
    v_samples=None,
    aem_times=None,
    q_samples=None,
):
    """Write ``orbit.oem``, ``attitude.aem``, ``landmarks.csv``, ``detections.csv`` and ``camera.toml`` for run ``run``.

    By default the OEM/AEM samples are the image times; pass denser samples (``oem_times``,
    ``r_samples`` GCRS, …) to exercise interpolation.
    """
    from pathlib import Path

    from astropy import units as u
    from astropy.time import Time

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t_img = Time(obs.epoch_utc, scale="utc") + obs.t_s * u.s
    t_img = Time(t_img.isot, scale="utc", precision=6)
    ext = "xml" if fmt == "xml" else ""
    paths = {}
    paths["orbit"] = write_oem(
        folder / f"orbit.oem{'.' + ext if ext else ''}",
        oem_times if oem_times is not None else t_img,
        r_samples if r_samples is not None else obs.r_sc_i_m[run],
        v_samples,
        frame=oem_frame,
        fmt=fmt,
    )
    paths["attitude"] = write_aem(
        folder / f"attitude.aem{'.' + ext if ext else ''}",
        aem_times if aem_times is not None else t_img,
        q_samples if q_samples is not None else obs.q_is[run],
        fmt=fmt,
    )
    paths["landmarks"] = write_landmarks_csv(folder / "landmarks.csv", obs.landmark_ids, obs.landmark_g_m[run], geodetic=geodetic)
    nn, mm = obs.image_index, obs.target_index  # one detection per row, in canonical order
    uv = camera.focal_plane_to_pixels(obs.xy_m[run])
    iso = t_img.isot
    paths["detections"] = write_detections_csv(folder / "detections.csv", iso[nn], obs.landmark_ids[mm], uv)
    paths["camera"] = write_camera_toml(
        folder / "camera.toml", camera, obs.C_SK_nominal, fov_deg if fov_deg is not None else obs.fov_deg
    )
    return paths
