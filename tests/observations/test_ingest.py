"""Flight-data ingestion (boresight.observations.flight): round trip, independent writers, interpolation bounds, CSV inputs."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from scipy.spatial.transform import Rotation

import boresight
from boresight.cli.main import main
from boresight.observations import flight as bio
from orbits.camera import CameraCalibration
from orbits.rotations import ARCSEC

pytest.importorskip("oem")
pytest.importorskip("ccsds_ndm")
pytest.importorskip("sgp4")

from cli_argv import flight_pass_argv, ingest_argv
from flight_camera import CAMERA


def _ingest(paths, **kw):
    ids, xyz = bio.read_landmarks_csv(paths["landmarks"])
    cam, fov = bio.read_camera_toml(paths["camera"])
    o, rep = bio.assemble(
        bio.read_oem(paths["orbit"]),
        bio.read_aem(paths["attitude"]),
        ids,
        xyz,
        bio.read_detections_csv(paths["detections"]),
        cam,
        C_SK_nominal=bio.read_mount_toml(paths["camera"]),
        fov_deg=fov,
        **kw,
    )
    return o, rep


@pytest.mark.parametrize("fmt", ["kvn", "xml"])
def test_round_trip_theta_to_1e_6_arcsec(flight_obs, tmp_path, fmt):
    """simulate → OEM + AEM + landmark CSV + pixel detections with distortion → ingest → estimate."""
    paths = bio.export_flight_files(flight_obs, tmp_path, CAMERA, fmt=fmt)
    o2, rep = _ingest(paths)
    assert np.array_equal(o2.image_index, flight_obs.image_index) and np.array_equal(o2.target_index, flight_obs.target_index)
    # the OEM's velocity goes into the file (format 1.1 v_x v_y v_z): ~7.5 km/s along the orbit
    assert o2.v_sc_i_m_s is not None and np.allclose(np.linalg.norm(o2.v_sc_i_m_s, axis=-1), 7.5e3, rtol=0.02)
    model = boresight.DisturbanceModel(
        sigma_pixel_m=3e-6, sigma_star_tracker_rad=(4 * ARCSEC,) * 3, sigma_gnss_m=15.0, sigma_catalogue_m=0.1
    )
    for kw in ({"weighting": "unit"}, {"weighting": "gls", "model": model}):
        e1, e2 = boresight.estimate(flight_obs, **kw), boresight.estimate(o2, **kw)
        assert np.max(np.abs((e1.theta - e2.theta).to_value(u.arcsec))) < 1e-6
    # the pixels really carry distortion: ignoring it moves points by more than 0.05 px (0.28 µm)
    uv = bio.read_detections_csv(paths["detections"])["uv_px"]
    undistorted = CameraCalibration(2.2, CAMERA.focal_length_px, CAMERA.principal_point_px, "+x", "-y").pixels_to_focal_plane(uv)
    assert np.max(np.abs(undistorted - flight_obs.xy_m[0])) > 0.05 * 5.5e-6


def test_cli_ingest_then_estimate(flight_obs, tmp_path, capsys):
    """ingest with the noise model on its command line writes it into the file, and the library's
    default estimate of that file is GLS under it: θ and σ equal the direct estimate's (the
    simulated set carries the same model)."""
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    out = tmp_path / "pass.ecsv"
    noise = flight_obs.noise
    options = [
        "--landmark-sight",  # what the simulated rows carry (geometric): ingest's default is flight light's
        flight_obs.landmark_sight,
        "--sigma-pixel-m",
        repr(noise["pixel"]["sigma_m"]),
        "--sigma-star-tracker-arcsec",
        *map(repr, noise["star_tracker"]["sigma_arcsec"]),
        "--sigma-gnss-m",
        repr(noise["gnss"]["sigma_m"]),
        "--sigma-catalogue-m",
        repr(noise["catalogue"]["sigma_m"]),
    ]
    assert main(ingest_argv(p, out, *options)) == 0
    e1 = boresight.estimate(flight_obs)
    e2 = boresight.estimate(boresight.ObservationSet.read(out))
    assert e1.weighting == e2.weighting == "gls"
    assert np.max(np.abs((e1.theta - e2.theta).to_value(u.arcsec))) < 1e-6
    np.testing.assert_allclose(e2.sigma.value, e1.sigma.value, rtol=1e-6)
    assert "conventions look right" in capsys.readouterr().out


@pytest.mark.parametrize(
    "slip, text, where",
    [
        ("v_axis", "your image y axis looks mirrored", "v_axis in the camera TOML"),
        # issue 29: named by the attitude CSV re-read in the other order (culprit.csv_other_order), with the option
        (
            "quaternion_order",
            "--attitude-csv ",
            "--quaternion-order scalar_last but the quaternions look scalar_first (give --quaternion-order scalar_first)",
        ),
    ],
)
def test_ingest_stops_on_a_convention_slip_with_exit_4(flight_obs, tmp_path, capsys, slip, text, where):
    """A slip in the ingest inputs (a detector axis declared the wrong way; quaternions declared
    scalar-last that are scalar-first) exits 4 like check/estimate, names the slip and the input
    that declares it, and writes nothing; --no-check writes the file."""
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    att = None  # the exported OEM and AEM
    if slip == "v_axis":
        cam = tmp_path / "camera_flipped.toml"
        cam.write_text(Path(p["camera"]).read_text().replace('v_axis = "-y"', 'v_axis = "+y"'))
        assert 'v_axis = "+y"' in cam.read_text()
    else:
        cam = p["camera"]
        t = Time(Time(flight_obs.epoch_utc, scale="utc") + flight_obs.t_s * u.s, precision=6)
        with open(tmp_path / "q.csv", "w") as f:  # scalar-first values, declared scalar-last
            f.write("time_utc,q0,q1,q2,q3\n")
            for s, x in zip(t.isot, flight_obs.q_is[0]):
                f.write(f"{s},{float(x[3])!r},{float(x[0])!r},{float(x[1])!r},{float(x[2])!r}\n")
        att = [
            "--oem",
            str(p["orbit"]),
            "--attitude-csv",
            str(tmp_path / "q.csv"),
            "--quaternion-order",
            "scalar_last",
            "--attitude-frame",
            "GCRS",
        ]
    out = tmp_path / "pass.ecsv"
    argv = ingest_argv(p, out, orbit_attitude=att, camera=cam)
    capsys.readouterr()
    assert main(argv) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"boresight ingest: ConventionError: {p['detections']} (ingested; {out} not written): {text}"
    ), err
    assert where in err[0] and "--no-check skips this test" in err[0]
    assert not out.exists()
    assert main(argv + ["--no-check"]) == 0 and out.exists()


def test_ingest_sigma_pixel_px_is_converted_with_the_calibration(flight_obs, tmp_path, capsys):
    """--sigma-pixel-px: σK written into the file is the calibration's conversion at the detections
    (pitch and distortion); a lens whose local scale varies by > 5 % is warned about."""
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    star_tracker = ["--sigma-star-tracker-arcsec", "4"]
    out = tmp_path / "px.ecsv"
    capsys.readouterr()
    assert main(ingest_argv(p, out, *star_tracker, "--sigma-pixel-px", "0.5")) == 0
    printed = capsys.readouterr().out
    uv = bio.read_detections_csv(p["detections"])["uv_px"]
    want, spread = CAMERA.focal_plane_sigma_m(0.5, uv)
    got = boresight.ObservationSet.read(out).noise["pixel"]["sigma_m"]
    assert got == pytest.approx(want, rel=1e-12) and got == pytest.approx(0.5 * 5.5e-6, rel=1e-3)
    assert f"0.5 px → σK = {want:.4g} m on the focal plane" in printed and "warning" not in printed
    assert main(ingest_argv(p, out, *star_tracker, "--sigma-pixel-px", "0.5", "--sigma-pixel-m", "3e-6")) == 1
    assert "give --sigma-pixel-px or --sigma-pixel-m, not both" in capsys.readouterr().err
    # estimate --sigma-pixel-px converts with the file's camera block (the calibration travelled
    # into the file): the same σK, so the same θ ± σ as the file's own noise model
    capsys.readouterr()
    assert main(["estimate", str(out), "--sigma-pixel-px", "0.5"]) == 0
    over = capsys.readouterr().out
    assert main(["estimate", str(out)]) == 0
    mine = capsys.readouterr().out
    pick = lambda text: [ln for ln in text.splitlines() if ln.startswith("theta_")]  # noqa: E731
    assert pick(over) == pick(mine) and len(pick(mine)) == 3
    bare = tmp_path / "bare.ecsv"
    replace(boresight.ObservationSet.read(out), camera=None).write(bare)
    assert main(["estimate", str(bare), "--sigma-pixel-px", "0.5"]) == 1
    assert "--sigma-pixel-px needs a file with a camera block" in capsys.readouterr().err
    # the same detections declared through a strongly distorting lens: the σK spread is named
    strong = tmp_path / "strong.toml"
    bio.write_camera_toml(
        strong,
        CameraCalibration(2.2, CAMERA.focal_length_px, CAMERA.principal_point_px, "+x", "-y", k1=400.0),
        C_SK_nominal=flight_obs.C_SK_nominal,
    )
    assert main(ingest_argv(p, tmp_path / "s.ecsv", *star_tracker, "--sigma-pixel-px", "0.5", "--no-check", camera=strong)) == 0
    assert "one focal-plane σK misstates the pixel noise by up to" in capsys.readouterr().out


def _tle():
    # ISS (ZARYA), a published element set (CelesTrak, epoch 2024 day 1); SGP4 propagates it
    return (
        "1 25544U 98067A   24001.50000000  .00016717  00000-0  10270-3 0  9005",
        "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.49815318432241",
    )


def test_oem_from_an_independent_writer_and_interpolation(tmp_path):
    """An OEM written by ccsds-ndm (a different library from the `oem` reader) from SGP4 states every
    60 s: the samples read back to 1 mm, and Lagrange-7 at off-sample times agrees with SGP4 to 1 mm
    with an error estimate that bounds the actual error."""
    from ccsds_ndm.mapping import NDMFileFormats
    from ccsds_ndm.ndm_io import NdmIo

    from boresight.observations.flight.frames import to_gcrs

    l1, l2 = _tle()
    t0 = Time("2024-01-01T12:00:00", scale="utc")
    nodes = t0 + np.arange(0, 1800.0, 60.0) * u.s
    track = bio.orbit_from_tle(l1, l2, nodes)
    r_teme, v_teme = to_gcrs(nodes, track.r_m, track.v_m_s, "TEME", inverse=True)
    lines = [
        "CCSDS_OEM_VERS = 2.0",
        "CREATION_DATE = 2024-01-01T00:00:00",
        "ORIGINATOR = test",
        "",
        "META_START",
        "OBJECT_NAME = ISS",
        "OBJECT_ID = 1998-067A",
        "CENTER_NAME = EARTH",
        "REF_FRAME = TEME",
        "TIME_SYSTEM = UTC",
        f"START_TIME = {nodes[0].isot}",
        f"STOP_TIME = {nodes[-1].isot}",
        "INTERPOLATION = LAGRANGE",
        "INTERPOLATION_DEGREE = 7",
        "META_STOP",
        "",
    ]
    lines += [f"{t.isot} " + " ".join(f"{x:.12e}" for x in np.r_[r / 1e3, v / 1e3]) for t, r, v in zip(nodes, r_teme, v_teme)]
    # ccsds-ndm parses this text and WRITES the files (KVN and XML) that the oem-based reader then reads
    msg = NdmIo().from_string("\n".join(lines) + "\n")
    for fmt, name in ((NDMFileFormats.KVN, "ndm.oem"), (NDMFileFormats.XML, "ndm.oem.xml")):
        NdmIo().to_file(msg, fmt, str(tmp_path / name))
        got = bio.read_oem(tmp_path / name)
        assert np.max(np.linalg.norm(got.r_m - track.r_m, axis=-1)) < 1e-3
        t_q = t0 + np.array([30.0, 395.5, 1012.25, 1739.0]) * u.s
        r, v, err = got.at(t_q)
        truth = bio.orbit_from_tle(l1, l2, t_q)
        actual = np.linalg.norm(r - truth.r_m, axis=-1)
        assert np.max(actual) < 1e-3
        assert np.all(err >= 0.5 * actual)  # the estimate is of the right size (it is an upper estimate in practice)
        assert np.max(np.linalg.norm(v - truth.v_m_s, axis=-1)) < 1e-3


def test_interpolation_refused_above_the_bound_and_outside_the_data(tmp_path):
    l1, l2 = _tle()
    t0 = Time("2024-01-01T12:00:00", scale="utc")
    nodes = t0 + np.arange(0, 3600.0, 600.0) * u.s  # 10-minute samples: far too sparse for LEO
    track = bio.orbit_from_tle(l1, l2, nodes)
    p = bio.write_oem(tmp_path / "sparse.oem", nodes, track.r_m, track.v_m_s, degree=3)
    got = bio.read_oem(p)
    with pytest.raises(bio.InterpolationError, match="exceeds 0.05 m"):
        got.at(t0 + [900.0] * u.s)
    with pytest.raises(bio.InterpolationError, match="outside the orbit data"):
        got.at(t0 + [4000.0] * u.s)
    q = Rotation.from_rotvec(np.outer(np.arange(6), [0.0, 0.2, 0.0]) + [[0.0, 0.0, 0.01 * k**2] for k in range(6)]).as_quat()
    att = bio.AttitudeTrack(nodes, q, "coarse")
    with pytest.raises(bio.InterpolationError, match="SLERP error estimate"):
        att.at(t0 + [900.0] * u.s)


def test_published_aem_example_read_to_1e_6_arcsec(tmp_path):
    """The AEM example of CCSDS 504.0-B (Mars Global Surveyor, EME2000 → SC_BODY_1, A2B, scalar last)."""
    text = """CCSDS_AEM_VERS = 1.0
CREATION_DATE = 2002-11-04T17:22:31
ORIGINATOR = NASA/JPL
META_START
OBJECT_NAME = MARS GLOBAL SURVEYOR
OBJECT_ID = 1996-062A
CENTER_NAME = mars barycenter
REF_FRAME_A = EME2000
REF_FRAME_B = SC_BODY_1
ATTITUDE_DIR = A2B
TIME_SYSTEM = UTC
START_TIME = 1996-11-28T21:29:07.2555
USEABLE_START_TIME = 1996-11-28T22:08:02.5555
USEABLE_STOP_TIME = 1996-11-30T01:18:02.5555
STOP_TIME = 1996-11-30T01:28:02.5555
ATTITUDE_TYPE = QUATERNION
QUATERNION_TYPE = LAST
INTERPOLATION_METHOD = hermite
INTERPOLATION_DEGREE = 7
META_STOP
DATA_START
1996-11-28T21:29:07.2555 0.56748 0.03146 0.45689 0.68427
1996-11-28T22:08:03.5555 0.42319 -0.45697 0.23784 0.74533
1996-11-28T22:08:04.5555 -0.84532 0.26974 -0.06532 0.45652
1996-11-30T01:28:02.5555 0.74563 -0.45375 0.33456 0.36875
DATA_STOP
"""
    (tmp_path / "mgs.aem").write_text(text)
    # as published: a Mars orbiter's attitude is refused, naming the keyword and its line
    with pytest.raises(bio.IngestError, match=r"mgs.aem: line 7: segment 1: CENTER_NAME 'mars barycenter'"):
        bio.read_aem(tmp_path / "mgs.aem")
    (tmp_path / "mgs.aem").write_text(text.replace("mars barycenter", "EARTH"))
    att = bio.read_aem(tmp_path / "mgs.aem")
    q_file = np.array(
        [
            [0.56748, 0.03146, 0.45689, 0.68427],
            [0.42319, -0.45697, 0.23784, 0.74533],
            [-0.84532, 0.26974, -0.06532, 0.45652],
            [0.74563, -0.45375, 0.33456, 0.36875],
        ]
    )
    q_file /= np.linalg.norm(q_file, axis=-1, keepdims=True)
    B = bio.frames.eme2000_bias()
    A_read = Rotation.from_quat(att.q_is).as_matrix().transpose(0, 2, 1)  # GCRS -> body
    A_file = Rotation.from_quat(q_file).as_matrix().transpose(0, 2, 1) @ B  # EME2000 -> body, then GCRS -> EME2000
    ang = Rotation.from_matrix(A_read @ A_file.transpose(0, 2, 1)).magnitude()
    assert np.max(ang) / ARCSEC < 1e-6
    assert abs((att.useable[0] - Time("1996-11-28T22:08:02.5555", scale="utc")).to_value(u.s)) < 1e-6


def test_aem_written_by_ccsds_ndm_b2a_scalar_first(flight_obs, tmp_path):
    """ccsds-ndm writes B2A / scalar-first (XML and KVN); the reader returns the original GCRS → star-tracker quaternions to 1e-6″."""
    t = Time(flight_obs.epoch_utc, scale="utc") + flight_obs.t_s * u.s
    for fmt in ("kvn", "xml"):
        p = bio.write_aem(tmp_path / f"a.{fmt}", t, flight_obs.q_is[0], direction="B2A", quaternion_type="FIRST", fmt=fmt)
        got = bio.read_aem(p)
        ang = (Rotation.from_quat(got.q_is).inv() * Rotation.from_quat(flight_obs.q_is[0])).magnitude()
        assert np.max(ang) / ARCSEC < 1e-6


def test_csv_orbit_itrf_and_scalar_first_eme2000_attitude(flight_obs, tmp_path):
    """GNSS fixes in ITRF and quaternions scalar-first in EME2000, as CSV: the same θ as the direct estimate."""
    from boresight.observations.flight.frames import eme2000_bias, to_gcrs

    t = Time(Time(flight_obs.epoch_utc, scale="utc") + flight_obs.t_s * u.s, precision=6)
    r_itrf, _ = to_gcrs(t, flight_obs.r_sc_i_m[0], None, "ITRS", inverse=True)
    with open(tmp_path / "gnss.csv", "w") as f:
        f.write("time_utc,x_m,y_m,z_m\n")
        for s, r in zip(t.isot, r_itrf):
            f.write(f"{s},{float(r[0])!r},{float(r[1])!r},{float(r[2])!r}\n")
    A = Rotation.from_quat(flight_obs.q_is[0]).as_matrix().transpose(0, 2, 1) @ eme2000_bias().T  # EME2000 -> ST
    q = Rotation.from_matrix(A.transpose(0, 2, 1)).as_quat()
    with open(tmp_path / "q.csv", "w") as f:
        f.write("time_utc,q0,q1,q2,q3\n")
        for s, x in zip(t.isot, q):
            f.write(f"{s},{float(x[3])!r},{float(x[0])!r},{float(x[1])!r},{float(x[2])!r}\n")
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    orbit = bio.read_orbit_csv(tmp_path / "gnss.csv", "ITRF")
    att = bio.read_attitude_csv(tmp_path / "q.csv", "scalar_first", "EME2000")
    ids, xyz = bio.read_landmarks_csv(p["landmarks"])
    o2, _ = bio.assemble(
        orbit, att, ids, xyz, bio.read_detections_csv(p["detections"]), CAMERA, C_SK_nominal=flight_obs.C_SK_nominal
    )
    assert np.max(np.abs(o2.r_sc_i_m - flight_obs.r_sc_i_m)) < 1e-3
    e1, e2 = boresight.estimate(flight_obs, weighting="unit"), boresight.estimate(o2, weighting="unit")
    assert np.max(np.abs((e1.theta - e2.theta).to_value(u.arcsec))) < 1e-4


def test_bad_inputs_name_file_column_row(flight_obs, tmp_path):
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    text = Path(p["detections"]).read_text().splitlines()
    text[3] = text[3].replace(",M", ",NOPE", 1)
    (tmp_path / "bad.csv").write_text("\n".join(text) + "\n")
    ids, xyz = bio.read_landmarks_csv(p["landmarks"])
    with pytest.raises(bio.IngestError, match=r"bad.csv: column 'landmark' row 3: 'NOPE"):
        bio.assemble(
            bio.read_oem(p["orbit"]), bio.read_aem(p["attitude"]), ids, xyz, bio.read_detections_csv(tmp_path / "bad.csv"), CAMERA
        )
    (tmp_path / "lm.csv").write_text("landmark,lat_deg,lon_deg,height_m\nA,91.0,10,0\n")
    with pytest.raises(bio.IngestError, match=r"lm.csv: column 'lat_deg' row 1: 91.0"):
        bio.read_landmarks_csv(tmp_path / "lm.csv")
    (tmp_path / "q.csv").write_text("time_utc,q0,q1,q2,q3\n2024-01-01T00:00:00,1,0,0,x\n")
    with pytest.raises(bio.IngestError, match=r"q.csv: column 'q3' row 1: 'x' is not a number"):
        bio.read_attitude_csv(tmp_path / "q.csv", "scalar_first", "ICRF")
    assert issubclass(bio.IngestError, boresight.BoresightError)


def test_ingest_pixels_go_through_the_one_camera_model(flight_obs, tmp_path, monkeypatch):
    """One place for the Brown–Conrady math (orbits.camera.CameraCalibration): the ingest camera
    TOML yields that class, and assemble's focal-plane points are its pixels_to_focal_plane —
    a stand-in for the method changes them (no private copy of the model in boresight.observations.flight)."""
    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    cam, _ = bio.read_camera_toml(p["camera"])
    assert type(cam) is CameraCalibration
    o1, _ = _ingest(p)
    monkeypatch.setattr(CameraCalibration, "pixels_to_focal_plane", lambda self, uv: np.zeros(np.shape(uv)) + 1e-3)
    o2, _ = bio.assemble(
        bio.read_oem(p["orbit"]),
        bio.read_aem(p["attitude"]),
        *bio.read_landmarks_csv(p["landmarks"]),
        bio.read_detections_csv(p["detections"]),
        cam,
        C_SK_nominal=flight_obs.C_SK_nominal,
        check_geometry=False,
    )
    assert np.all(o2.xy_m[0] == 1e-3) and not np.allclose(o1.xy_m, o2.xy_m)


def test_camera_toml_round_trip_and_errors(tmp_path):
    p = bio.write_camera_toml(tmp_path / "c.toml", CAMERA, np.eye(3), 3.4)
    cam, fov = bio.read_camera_toml(p)
    assert cam == CAMERA and fov == 3.4 and np.array_equal(bio.read_mount_toml(p), np.eye(3))
    g = np.stack(np.meshgrid(np.linspace(-0.03, 0.03, 7), np.linspace(-0.03, 0.03, 7)), -1)
    assert np.max(np.abs(cam.pixels_to_focal_plane(CAMERA.focal_plane_to_pixels(g)) - g)) < 1e-12
    (tmp_path / "bad.toml").write_text("[camera]\nfocal_length_m = 2.2\nfocal_lenght_px = 1\n")
    with pytest.raises(bio.IngestError, match=r"bad.toml: \[camera\].*focal_lenght_px"):
        bio.read_camera_toml(tmp_path / "bad.toml")
    (tmp_path / "m.toml").write_text("[camera]\n[mount]\nC_SK_nominal = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\n")
    with pytest.raises(bio.IngestError, match="rotation"):
        bio.read_mount_toml(tmp_path / "m.toml")


def _shipped_ingest(tmp_path, name, **replace_files):
    """argv of ``ingest --example flight-pass`` with some inputs replaced by damaged copies."""
    from boresight.observations.flight.shipped import example_dir

    folder = example_dir("flight-pass")
    argv = flight_pass_argv(tmp_path / f"{name}.ecsv")
    for opt, (fname, edit) in replace_files.items():
        path = tmp_path / f"{name}-{fname}"
        path.write_text(edit((folder / fname).read_text()))
        argv += [f"--{opt}", str(path)]
    return argv


def _damage_one_detection(text):
    lines = text.splitlines()
    t, lm, u_px, v_px = lines[30].split(",")
    lines[30] = ",".join([t, lm, repr(float(u_px) + 400.0), v_px])  # one image, one landmark, 400 px off
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "name, files",
    [
        ("teme", {"oem": ("orbit.oem", lambda s: s.replace("REF_FRAME = GCRF", "REF_FRAME = TEME"))}),
        ("one-row", {"detections": ("detections.csv", _damage_one_detection)}),
    ],
)
def test_ingest_exits_4_and_writes_nothing_whenever_its_check_would_not_pass(tmp_path, capsys, name, files):
    """Issue 31, class 2: ingest wrote the file and exited 0 when its own convention check was
    "inconclusive" (images far above the noise, no slip fits better: an orbit labelled TEME, one
    damaged detection), and then ``boresight check`` exited 4 on that file. The property: ingest
    exits 0 only when ``check`` on its output would pass; otherwise exit 4, nothing written, the
    message names the images; ``--no-check`` still writes (and ``check`` then exits 4)."""
    argv = _shipped_ingest(tmp_path, name, **files)
    out = Path(argv[argv.index("--out") + 1])
    capsys.readouterr()
    assert main(argv) == 4
    err = capsys.readouterr().err
    # the TEME label is named as the culprit since class 3 (test_ingest_names_the_input_whose_slip_fits_not_the_camera)
    assert ("inconclusive" in err or "REF_FRAME" in err) and f"{out} not written" in err and "--no-check" in err, err
    assert not out.exists()
    assert main(argv + ["--no-check"]) == 0 and out.exists()
    assert main(["check", str(out)]) == 4
    # the clean example still passes both
    clean = _shipped_ingest(tmp_path, "clean")
    assert main(clean) == 0 and main(["check", clean[clean.index("--out") + 1]]) == 0


def _swap_lat_lon(text):
    out = [text.splitlines()[0]]
    for line in text.splitlines()[1:]:
        name, lat, lon, h = line.split(",")
        out.append(",".join([name, lon, lat, h]))
    return "\n".join(out) + "\n"


def _radians(text):
    import math

    out = [text.splitlines()[0]]
    for line in text.splitlines()[1:]:
        name, lat, lon, h = line.split(",")
        out.append(",".join([name, repr(math.radians(float(lat))), repr(math.radians(float(lon))), h]))
    return "\n".join(out) + "\n"


def _kilometres(text):
    from astropy.coordinates import EarthLocation

    out = ["landmark,X_m,Y_m,Z_m"]
    for line in text.splitlines()[1:]:
        name, lat, lon, h = line.split(",")
        loc = EarthLocation.from_geodetic(float(lon) * u.deg, float(lat) * u.deg, float(h) * u.m)
        out.append(",".join([name, *(repr(float(c.to_value(u.km))) for c in (loc.x, loc.y, loc.z))]))
    return "\n".join(out) + "\n"


def _aem_key(text, key, value):
    """An AEM with ``key``'s value replaced (the KVN's padded ``KEY   = VALUE``)."""
    import re

    out, n = re.subn(rf"^({key}\s*=\s*)\S+", rf"\g<1>{value}", text, flags=re.M)
    assert n == 1, key
    return out


def _aem_rows(text, reorder):
    """An AEM whose data rows' four numbers are ``reorder(q)`` (q as written)."""
    out = []
    for line in text.splitlines():
        f = line.split()
        if len(f) == 5 and f[0][:1].isdigit() and "T" in f[0]:
            line = "  ".join([f[0], *(repr(float(x)) for x in reorder([float(x) for x in f[1:]]))])
        out.append(line)
    return "\n".join(out) + "\n"


INPUT_SLIPS = {
    # name: (files replaced, the words the refusal must contain)
    "lat-lon-swapped": ({"landmarks": ("landmarks.csv", _swap_lat_lon)}, ("landmarks.csv", "lat_deg", "lon_deg", "swapped")),
    "radians": ({"landmarks": ("landmarks.csv", _radians)}, ("landmarks.csv", "radians")),
    "kilometres": ({"landmarks": ("landmarks.csv", _kilometres)}, ("landmarks.csv", "kilometres")),
    "itrf-label": (
        {"oem": ("orbit.oem", lambda s: s.replace("REF_FRAME = GCRF", "REF_FRAME = ITRF"))},
        ("orbit.oem", "REF_FRAME"),
    ),
    "teme-label": (
        {"oem": ("orbit.oem", lambda s: s.replace("REF_FRAME = GCRF", "REF_FRAME = TEME"))},
        ("orbit.oem", "REF_FRAME"),
    ),
    "tai-label": (
        {"oem": ("orbit.oem", lambda s: s.replace("TIME_SYSTEM = UTC", "TIME_SYSTEM = TAI"))},
        ("orbit.oem", "TIME_SYSTEM"),
    ),
    # issue 29: the AEM's quaternion order, both ways (the doctor's own reordering undoes only scalar-first data
    # declared LAST; FIRST declared for scalar-last data was a bare 66° LargeRotationError), and a conjugated AEM
    "aem-first-for-last": (
        {"aem": ("attitude.aem", lambda s: _aem_key(s, "QUATERNION_TYPE", "FIRST"))},
        ("attitude.aem", "QUATERNION_TYPE = FIRST (line 17)", "look scalar-last"),
    ),
    "aem-last-for-first": (
        {"aem": ("attitude.aem", lambda s: _aem_rows(s, lambda q: [q[3], q[0], q[1], q[2]]))},
        ("attitude.aem", "QUATERNION_TYPE = LAST (line 17)", "look scalar-first"),
    ),
    "aem-b2a-first-for-last": (
        {
            "aem": (
                "attitude.aem",
                lambda s: _aem_key(
                    _aem_key(_aem_rows(s, lambda q: [-q[0], -q[1], -q[2], q[3]]), "ATTITUDE_DIR", "B2A"),
                    "QUATERNION_TYPE",
                    "FIRST",
                ),
            )
        },
        ("attitude.aem", "QUATERNION_TYPE = FIRST (line 17)", "look scalar-last"),
    ),
    # a 33 s slip (TAI − UTC in 2006): the images fall outside the AEM's samples, refused at reading (exit 1) naming it
    "aem-tai-label": (
        {"aem": ("attitude.aem", lambda s: _aem_key(s, "TIME_SYSTEM", "TAI"))},
        ("attitude.aem", "outside the attitude data", "in UTC (+33 s)", "time-system slip", "TIME_SYSTEM = TAI (line 13)"),
    ),
}


@pytest.mark.parametrize("name", list(INPUT_SLIPS))
def test_ingest_names_the_input_whose_slip_fits_not_the_camera(tmp_path, capsys, name):
    """Issue 31, class 3: latitude and longitude swapped, radians under ``lat_deg``, ECEF in km, an
    orbit labelled ITRF or TEME that is GCRF, a TAI label on UTC epochs were refused as "need a 53°
    rotation … check C_SK_nominal, the detector axes, quaternions" (or "inconclusive"); the landmark
    file, REF_FRAME or TIME_SYSTEM was never named. Each input hypothesis is now tested and the one
    that fits is named; nothing is written."""
    files, words = INPUT_SLIPS[name]
    argv = _shipped_ingest(tmp_path, "case", **files)  # a neutral name: the words must come from the message
    out = Path(argv[argv.index("--out") + 1])
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    assert code in (1, 4), err
    line = err.strip().splitlines()[-1]
    for w in words:
        assert w in line, (w, line)
    assert "C_SK_nominal" not in line, line
    assert not out.exists()


def _refusal_of_a_written_file(tmp_path, capsys, name, command):
    """The last line ``boresight COMMAND`` prints (it must exit 4) on the file ``ingest --no-check`` writes
    from the inputs of ``INPUT_SLIPS[name]``."""
    files, _ = INPUT_SLIPS[name]
    argv = _shipped_ingest(tmp_path, "case", **files)
    out = Path(argv[argv.index("--out") + 1])
    assert main(argv + ["--no-check"]) == 0
    capsys.readouterr()
    assert main([command, str(out)]) == 4
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize("name", ["lat-lon-swapped", "radians"])
def test_check_names_the_input_slip_of_a_written_file(tmp_path, capsys, name):
    """Class 3 for a file already written (``ingest --no-check``, or another tool): ``check`` tests
    the landmark and orbit-frame hypotheses on the file's own arrays and names them (an orbit in
    the wrong frame puts the landmarks behind the camera: such a file cannot be written)."""
    line = _refusal_of_a_written_file(tmp_path, capsys, name, "check")
    assert "landmark_g_m" in line and "latitudes and longitudes" in line and "C_SK_nominal" not in line, line


def test_estimate_names_the_landmarks_slip_of_a_written_file(tmp_path, capsys):
    """``estimate`` (and ``diagnose``, ``montecarlo FILE``) read through the same check: a file with
    latitude and longitude swapped is refused naming the landmarks, not C_SK_nominal."""
    line = _refusal_of_a_written_file(tmp_path, capsys, "lat-lon-swapped", "estimate")
    assert "landmark_g_m" in line and "swapped" in line and "C_SK_nominal" not in line, line
