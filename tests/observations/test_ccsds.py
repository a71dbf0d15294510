"""The strict CCSDS layer (boresight.observations.flight.ccsds): variants of the CCSDS blue books'
OEM / AEM examples written here by hand (segments, gaps, missing and version-misused keywords),
each refused with the file, the keyword and the right line, or read correctly.

The base texts follow CCSDS 502.0-B-2 figure 5-? (the Mars Global Surveyor OEM, moved to Earth
orbit: CENTER_NAME EARTH and LEO numbers) and 504.0-B-1 (the MGS AEM)."""

import re

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from cli_argv import ingest_argv
from flight_camera import camera
from scipy.spatial.transform import Rotation

from boresight.observations import flight as bio
from orbits.rotations import ARCSEC

T0 = Time("2024-03-01T12:00:00", scale="utc")
MU = 3.986004418e14


def _kepler(ts):
    """A circular 700 km orbit (positions m, velocities m/s) at offsets ts (s)."""
    a = 6378137.0 + 700e3
    n = np.sqrt(MU / a**3)
    c, s = np.cos(n * ts), np.sin(n * ts)
    inc = np.radians(98.0)
    r = a * np.stack([c, s * np.cos(inc), s * np.sin(inc)], -1)
    v = a * n * np.stack([-s, c * np.cos(inc), c * np.sin(inc)], -1)
    return r, v


def _iso(ts):
    return [(T0 + t * u.s).isot for t in ts]


def oem_text(
    version="2.0",
    segments=((0.0, 600.0, 60.0, None),),
    header_extra=(),
    meta_extra=(),
    interpolation=("HERMITE", "7"),
    drop=(),
    cov=None,
    rows_hook=None,
):
    """An OEM in KVN: segments = [(start s, stop s, step s, (useable start s, useable stop s) or None)]."""
    out = [f"CCSDS_OEM_VERS = {version}", *header_extra, "CREATION_DATE = 1996-11-04T17:22:31", "ORIGINATOR = NASA/JPL", ""]
    for k, (a, b, h, use) in enumerate(segments):
        ts = np.arange(a, b + h / 2, h)
        meta = [
            ("OBJECT_NAME", "MARS GLOBAL SURVEYOR"),
            ("OBJECT_ID", "1996-062A"),
            ("CENTER_NAME", "EARTH"),
            ("REF_FRAME", "EME2000"),
            ("TIME_SYSTEM", "UTC"),
            ("START_TIME", _iso([a])[0]),
        ]
        if use is not None:
            meta += [("USEABLE_START_TIME", _iso([use[0]])[0]), ("USEABLE_STOP_TIME", _iso([use[1]])[0])]
        meta += [("STOP_TIME", _iso([b])[0])]
        if interpolation:
            meta += [("INTERPOLATION", interpolation[0]), ("INTERPOLATION_DEGREE", interpolation[1])]
        meta += list(meta_extra)
        out += (
            ["META_START"]
            + [f"{key} = {val}" for key, val in meta if key not in drop]
            + ["META_STOP", "COMMENT This file was produced by M.R. Somebody, MSOO NAV/JPL, 1996NOV 04."]
        )
        r, v = _kepler(ts)
        rows = [f"{s} " + " ".join(f"{x:.9f}" for x in np.r_[ri / 1e3, vi / 1e3]) for s, ri, vi in zip(_iso(ts), r, v)]
        out += rows_hook(rows) if rows_hook else rows
        if cov is not None:
            out += ["COVARIANCE_START", f"EPOCH = {_iso([a])[0]}", "COV_REF_FRAME = EME2000"]
            L = np.linalg.cholesky(cov).T if False else None  # noqa: F841 (the matrix is given)
            for i in range(6):
                out.append(" ".join(f"{cov[i, j]:.6e}" for j in range(i + 1)))
            out += ["COVARIANCE_STOP"]
        out.append("")
    return "\n".join(out) + "\n"


def aem_text(
    version="1.0",
    segments=((0.0, 60.0, 1.0, None),),
    drop=(),
    meta_extra=(),
    direction="A2B",
    qtype="LAST",
    center="EARTH",
    frames=("EME2000", "SC_BODY_1"),
    header_extra=(),
):
    out = [f"CCSDS_AEM_VERS = {version}", *header_extra, "CREATION_DATE = 2002-11-04T17:22:31", "ORIGINATOR = NASA/JPL"]
    for a, b, h, use in segments:
        ts = np.arange(a, b + h / 2, h)
        meta = [
            ("OBJECT_NAME", "MARS GLOBAL SURVEYOR"),
            ("OBJECT_ID", "1996-062A"),
            ("CENTER_NAME", center),
            ("REF_FRAME_A", frames[0]),
            ("REF_FRAME_B", frames[1]),
            ("ATTITUDE_DIR", direction),
            ("TIME_SYSTEM", "UTC"),
            ("START_TIME", _iso([a])[0]),
        ]
        if use is not None:
            meta += [("USEABLE_START_TIME", _iso([use[0]])[0]), ("USEABLE_STOP_TIME", _iso([use[1]])[0])]
        meta += [
            ("STOP_TIME", _iso([b])[0]),
            ("ATTITUDE_TYPE", "QUATERNION"),
            ("QUATERNION_TYPE", qtype),
            ("INTERPOLATION_METHOD", "LINEAR"),
            ("INTERPOLATION_DEGREE", "1"),
            *meta_extra,
        ]
        out += ["META_START"] + [f"{k} = {v}" for k, v in meta if k not in drop and v is not None] + ["META_STOP", "DATA_START"]
        q = _quats(ts)
        if qtype == "FIRST":
            q = np.roll(q, 1, axis=1)
        out += [f"{s} " + " ".join(f"{x:.12f}" for x in qq) for s, qq in zip(_iso(ts), q)]
        out += ["DATA_STOP"]
    return "\n".join(out) + "\n"


def _quats(ts):
    """A slowly turning attitude, scalar last (the file's quaternion, A → B)."""
    return Rotation.from_rotvec(np.outer(ts, [1e-3, -2e-3, 5e-4]) + [0.3, 0.2, -0.1]).as_quat()


def _line(text, pattern):
    """1-based number of the first line of ``text`` that matches ``pattern``."""
    for k, ln in enumerate(text.splitlines(), 1):
        if re.search(pattern, ln):
            return k
    raise AssertionError(pattern)


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


# ----------------------------------------------------------------------------------- OEM


def test_oem_3_0_classification_and_message_id_are_valid(tmp_path):
    t = oem_text("3.0", header_extra=("CLASSIFICATION = unclassified", "MESSAGE_ID = OEM 201113719185"))
    got = bio.read_oem(_write(tmp_path, "v3.oem", t))
    r, _ = _kepler(np.arange(0, 601, 60.0))
    B = bio.frames.eme2000_bias()
    assert np.max(np.abs(got.r_m - r @ B)) < 1e-5  # km with 9 decimals: 1 µm writing precision


@pytest.mark.parametrize("version, key, first", [("2.0", "MESSAGE_ID", "3.0"), ("1.0", "CLASSIFICATION", "3.0")])
def test_oem_header_keyword_misused_by_version(tmp_path, version, key, first):
    t = oem_text(version, header_extra=(f"{key} = x",))
    with pytest.raises(
        bio.IngestError, match=rf"h.oem: line 2: header keyword {key} is not allowed in OEM {version} \(from {first}\)"
    ):
        bio.read_oem(_write(tmp_path, "h.oem", t))


def test_oem_1_0_ref_frame_epoch_and_accelerations_refused(tmp_path):
    t = oem_text("1.0", meta_extra=(("REF_FRAME_EPOCH", "2000-01-01T12:00:00"),))
    with pytest.raises(
        bio.IngestError,
        match=rf"line {_line(t, 'REF_FRAME_EPOCH')}: segment 1: REF_FRAME_EPOCH is not a OEM 1.0 metadata keyword \(from 2.0\)",
    ):
        bio.read_oem(_write(tmp_path, "e.oem", t))
    t = oem_text("1.0", rows_hook=lambda rows: rows[:3] + [rows[3] + " 0.0 0.0 0.0"] + rows[4:])
    n = _line(t, r"T12:03:00")
    with pytest.raises(bio.IngestError, match=rf"a.oem: line {n}: segment 1: 10 fields on a state line; OEM 1.0 has 7"):
        bio.read_oem(_write(tmp_path, "a.oem", t))
    # the same accelerations are valid in 2.0
    bio.read_oem(_write(tmp_path, "a2.oem", oem_text("2.0", rows_hook=lambda rows: [r + " 0.0 0.0 0.0" for r in rows])))


def test_short_state_line_names_its_own_line(tmp_path):
    """The `oem` library said 'Error on line 46' for a short line 45."""
    t = oem_text(rows_hook=lambda rows: rows[:5] + [" ".join(rows[5].split()[:6])] + rows[6:])
    n = _line(t, r"T12:05:00")
    with pytest.raises(bio.IngestError, match=rf"s.oem: line {n}: segment 1: 6 fields on a state line"):
        bio.read_oem(_write(tmp_path, "s.oem", t))


#: (message, keyword dropped, the standard the refusal names): OEM 2.0's mandatory metadata, and AEM 1.0's
#: QUATERNION_TYPE and ATTITUDE_DIR (issue 21: these were silently read scalar-first / B2A)
MANDATORY_METADATA = [
    *(("oem", key, r"OEM 2.0\)") for key in ("OBJECT_ID", "CENTER_NAME", "REF_FRAME", "TIME_SYSTEM", "START_TIME", "STOP_TIME")),
    *(("aem", key, "AEM 1.0") for key in ("QUATERNION_TYPE", "ATTITUDE_DIR")),
]


@pytest.mark.parametrize("kind, drop, standard", MANDATORY_METADATA)
def test_missing_mandatory_metadata_is_refused_at_its_segment(tmp_path, kind, drop, standard):
    text, read = {"oem": (oem_text, bio.read_oem), "aem": (aem_text, bio.read_aem)}[kind]
    t = text(drop=(drop,))
    with pytest.raises(
        bio.IngestError,
        match=rf"m.{kind}: line {_line(t, 'META_START')}: segment 1: metadata without {drop} \(mandatory in {standard}",
    ):
        read(_write(tmp_path, f"m.{kind}", t))


def test_oem_unknown_keyword_center_and_interpolation(tmp_path):
    t = oem_text(meta_extra=(("REF_FRAME_EPOC", "2000-01-01T00:00:00"),))
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'REF_FRAME_EPOC ')}: segment 1: REF_FRAME_EPOC is not a OEM 2.0 metadata keyword"
    ):
        bio.read_oem(_write(tmp_path, "u.oem", t))
    t = oem_text().replace("CENTER_NAME = EARTH", "CENTER_NAME = MARS BARYCENTER")
    with pytest.raises(bio.IngestError, match=rf"line {_line(t, 'CENTER_NAME')}: segment 1: CENTER_NAME 'MARS BARYCENTER'"):
        bio.read_oem(_write(tmp_path, "c.oem", t))
    t = oem_text(drop=("INTERPOLATION_DEGREE",))
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'INTERPOLATION =')}: segment 1: INTERPOLATION without INTERPOLATION_DEGREE"
    ):
        bio.read_oem(_write(tmp_path, "i.oem", t))
    # no INTERPOLATION at all: boresight's default, and the description says so
    got = bio.read_oem(_write(tmp_path, "n.oem", oem_text(interpolation=None)))
    assert "boresight's default" in got.describe() and got.degree == 7
    t = oem_text().replace("CCSDS_OEM_VERS = 2.0", "CCSDS_OEM_VERS = 2.1")
    with pytest.raises(bio.IngestError, match=r"line 1: CCSDS_OEM_VERS = '2.1' is not a version"):
        bio.read_oem(_write(tmp_path, "v.oem", t))
    with pytest.raises(bio.IngestError, match=r"line 1: this is a CCSDS AEM"):
        bio.read_oem(_write(tmp_path, "x.oem", aem_text()))


def test_ref_frame_epoch_honoured_or_refused(tmp_path):
    got = bio.read_oem(_write(tmp_path, "e.oem", oem_text(meta_extra=(("REF_FRAME_EPOCH", "2000-01-01T12:00:00"),))))
    assert any("REF_FRAME_EPOCH" in n and "not used" in n for n in got.notes)
    t = oem_text(meta_extra=(("REF_FRAME_EPOCH", "2000-01-01T12:00:00"),)).replace("REF_FRAME = EME2000", "REF_FRAME = TEME")
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'REF_FRAME_EPOCH')}: segment 1: REF_FRAME_EPOCH with REF_FRAME TEME"
    ):
        bio.read_oem(_write(tmp_path, "t.oem", t))
    t = oem_text().replace("REF_FRAME = EME2000", "REF_FRAME = TOD")
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'REF_FRAME =')}: segment 1: REF_FRAME: reference frame 'TOD' is not supported"
    ):
        bio.read_oem(_write(tmp_path, "tod.oem", t))


def test_two_segments_with_a_hole_refuse_images_in_it(tmp_path):
    """Issue 21: useable spans leaving a 40 s hole gave exit 0 with images outside both spans."""
    t = oem_text(segments=((0.0, 600.0, 60.0, (0.0, 580.0)), (600.0, 1200.0, 60.0, (620.0, 1200.0))))
    orbit = bio.read_oem(_write(tmp_path, "two.oem", t))
    assert len(orbit.segments) == 2
    ok = T0 + np.array([100.0, 579.0, 621.0, 1100.0]) * u.s
    r, _, err = orbit.at(ok)
    rt, _ = _kepler(np.array([100.0, 579.0, 621.0, 1100.0]))
    assert np.max(np.linalg.norm(r - rt @ bio.frames.eme2000_bias(), axis=-1)) < 1e-3
    with pytest.raises(
        bio.InterpolationError,
        match=r"two.oem: image time 2024-03-01T12:09:50.000 is in the gap between segment 1 useable "
        r"2024-03-01T12:00:00.000 .. 2024-03-01T12:09:40.000 and segment 2 useable 2024-03-01T12:10:20.000 .. 2024-03-01T12:20:00.000",
    ):
        orbit.at(T0 + np.array([100.0, 590.0]) * u.s)
    with pytest.raises(bio.InterpolationError, match=r"after segment 2 useable"):
        orbit.at(T0 + np.array([1300.0]) * u.s)


def test_interpolation_never_crosses_a_segment_boundary(tmp_path):
    """Segment 2 starts after a 1 km manoeuvre: an image near the end of segment 1 is interpolated
    from segment 1's states only (equal to reading segment 1 alone), each segment with its own
    INTERPOLATION."""

    def jump(rows):  # add 1 km to x in segment 2
        return [f"{r.split()[0]} {float(r.split()[1]) + 1.0:.9f} " + " ".join(r.split()[2:]) for r in rows]

    one = oem_text(segments=((0.0, 600.0, 60.0, None),))
    two = oem_text(segments=((600.0, 1200.0, 60.0, None),), rows_hook=jump, interpolation=("LAGRANGE", "5"))
    body2 = two.split("META_START", 1)[1]
    p = _write(tmp_path, "m.oem", one + "META_START" + body2)
    both = bio.read_oem(p)
    alone = bio.read_oem(p, segment=0)
    tq = T0 + np.array([570.0, 599.0]) * u.s
    assert np.array_equal(both.at(tq)[0], alone.at(tq)[0])
    assert [s.method for s in both.segments] == ["HERMITE", "LAGRANGE"] and [s.degree for s in both.segments] == [7, 5]
    # at 600 s both segments hold the image: the later one is used (its states carry the +1 km)
    r600 = both.at(T0 + [600.0] * u.s)[0]
    assert abs(r600[0] @ bio.frames.eme2000_bias().T @ [1, 0, 0] - _kepler(np.array([600.0]))[0][0, 0] - 1e3) < 1e-3


def test_covariance_block_gives_the_gnss_sigma(tmp_path):
    cov = np.diag([4e-6, 1e-6, 1e-6, 1e-10, 1e-10, 1e-10])  # km²: σ = 2, 1, 1 m
    cov[1, 0] = cov[0, 1] = 1e-7
    orbit = bio.read_oem(_write(tmp_path, "c.oem", oem_text(cov=cov)))
    s = orbit.sigma_at(T0 + np.array([10.0, 300.0]) * u.s)
    np.testing.assert_allclose(s, np.sqrt((4 + 1 + 1) / 3.0), rtol=1e-9)
    t = oem_text(cov=cov).replace("COVARIANCE_START", "COVARIANCE_START").splitlines()
    k = t.index("COVARIANCE_START")
    t[k + 5] = t[k + 5] + " 1.0"  # row 3 with 4 numbers
    with pytest.raises(bio.IngestError, match=rf"line {k + 6}: segment 1: covariance row 3 has 4 number\(s\)"):
        bio.read_oem(_write(tmp_path, "bad.oem", "\n".join(t) + "\n"))
    with pytest.raises(bio.IngestError, match=r"line \d+: COVARIANCE_START: covariance blocks are not allowed in OEM 1.0"):
        bio.read_oem(_write(tmp_path, "c1.oem", oem_text("1.0", cov=cov)))


def test_position_sigma_is_what_ingest_prints_and_writes(tmp_path, monkeypatch):
    """``OrbitTrack.position_sigma``: the per-image σ's range over the images with a block, the first image without
    one, and the noise model's one σ (the largest) — what ``boresight ingest`` prints and writes (it computed them)."""
    import dataclasses

    orbit = bio.read_oem(_write(tmp_path, "c.oem", oem_text(cov=np.diag([4e-6, 1e-6, 1e-6, 1e-10, 1e-10, 1e-10]))))
    times = T0 + np.array([10.0, 300.0]) * u.s
    ps = orbit.position_sigma(times)
    assert (ps.low_m, ps.high_m, ps.n_covered, ps.first_uncovered) == pytest.approx((np.sqrt(2), np.sqrt(2), 2, None))
    assert ps.noise_model_m == ps.high_m and np.array_equal(ps.per_image_m, orbit.sigma_at(times))
    assert dataclasses.replace(orbit, covariance=None).position_sigma(times) is None
    monkeypatch.setattr(bio.OrbitTrack, "sigma_at", lambda self, t: np.array([2.0, np.nan, 3.0, np.nan]))
    ps = orbit.position_sigma(times)
    assert (ps.low_m, ps.high_m, ps.n_covered, ps.first_uncovered, ps.noise_model_m) == (2.0, 3.0, 2, 1, 3.0)


def test_oem_xml_checked_with_lines(tmp_path):
    r, v = _kepler(np.arange(0, 601, 60.0))
    p = bio.write_oem(tmp_path / "o.xml", T0 + np.arange(0, 601, 60.0) * u.s, r, v, fmt="xml")
    got = bio.read_oem(p)
    assert np.max(np.abs(got.r_m - r)) < 1e-6
    text = p.read_text()
    bad = text.replace("<CENTER_NAME>EARTH</CENTER_NAME>", "<CENTER_NAME>MOON</CENTER_NAME>")
    with pytest.raises(bio.IngestError, match=rf"b.xml: line {_line(bad, 'CENTER_NAME')}: segment 1: CENTER_NAME 'MOON'"):
        bio.read_oem(_write(tmp_path, "b.xml", bad))
    bad = re.sub(r"\s*<OBJECT_ID>.*</OBJECT_ID>", "", text)
    with pytest.raises(bio.IngestError, match=rf"line {_line(bad, '<segment>')}: segment 1: metadata without OBJECT_ID"):
        bio.read_oem(_write(tmp_path, "c.xml", bad))
    bad = text.replace('version="2.0"', 'version="3.0"').replace("<ORIGINATOR>", "<MESSAGE_ID>1</MESSAGE_ID><ORIGINATOR>")
    bio.read_oem(_write(tmp_path, "d.xml", bad))  # 3.0 with MESSAGE_ID: valid


# ----------------------------------------------------------------------------------- AEM


def _angle(q1, q2):
    return (Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude() / ARCSEC


def test_aem_2_0_reads_scalar_last_and_refuses_first_and_b2a(tmp_path):
    ref = bio.read_aem(_write(tmp_path, "v1.aem", aem_text("1.0")))
    v2 = bio.read_aem(
        _write(
            tmp_path,
            "v2.aem",
            aem_text("2.0", drop=("QUATERNION_TYPE", "ATTITUDE_DIR"), header_extra=("MESSAGE_ID = 7", "CLASSIFICATION = none")),
        )
    )
    assert np.max(_angle(ref.q_is, v2.q_is)) < 1e-6
    assert "AEM 2.0" in v2.notes[0]
    t = aem_text("2.0", qtype="FIRST")
    with pytest.raises(
        bio.IngestError,
        match=rf"line {_line(t, 'QUATERNION_TYPE')}: segment 1: QUATERNION_TYPE 'FIRST' is not allowed in AEM 2.0",
    ):
        bio.read_aem(_write(tmp_path, "f.aem", t))
    t = aem_text("2.0", direction="B2A")
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'ATTITUDE_DIR')}: segment 1: ATTITUDE_DIR 'B2A' is not allowed in AEM 2.0"
    ):
        bio.read_aem(_write(tmp_path, "d.aem", t))
    t = aem_text("1.0", header_extra=("MESSAGE_ID = 7",))
    with pytest.raises(bio.IngestError, match=r"line 2: header keyword MESSAGE_ID is not allowed in AEM 1.0 \(from 2.0\)"):
        bio.read_aem(_write(tmp_path, "m.aem", t))
    t = aem_text("2.0", meta_extra=(("RATE_FRAME", "REF_FRAME_A"),))
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'RATE_FRAME')}: segment 1: RATE_FRAME is not a AEM 2.0 metadata keyword"
    ):
        bio.read_aem(_write(tmp_path, "r.aem", t))


def test_aem_b2a_and_first_are_read_explicitly_and_said(tmp_path):
    """B2A (the file's quaternion rotates B into A) and scalar-first: the same attitude as A2B/LAST, and the notes say what was done."""
    ref = bio.read_aem(_write(tmp_path, "a.aem", aem_text()))
    # the same attitude written B2A: the quaternion of B → A is the inverse
    t = aem_text(direction="B2A", qtype="FIRST")
    ts = np.arange(0.0, 60.5, 1.0)
    q_b2a = np.roll(Rotation.from_quat(_quats(ts)).inv().as_quat(), 1, axis=1)
    lines = t.splitlines()
    k = lines.index("DATA_START")
    lines[k + 1 : k + 1 + ts.size] = [f"{s} " + " ".join(f"{x:.12f}" for x in q) for s, q in zip(_iso(ts), q_b2a)]
    got = bio.read_aem(_write(tmp_path, "b.aem", "\n".join(lines) + "\n"))
    assert np.max(_angle(ref.q_is, got.q_is)) < 1e-6
    assert "scalar-first (QUATERNION_TYPE = FIRST" in got.notes[0] and "ATTITUDE_DIR = B2A" in got.notes[0]
    assert "body → inertial: conjugated" in got.notes[0]
    assert "conjugated" not in ref.notes[0]


def test_aem_center_name_checked(tmp_path):
    t = aem_text(center="MARS BARYCENTER")
    with pytest.raises(bio.IngestError, match=rf"line {_line(t, 'CENTER_NAME')}: segment 1: CENTER_NAME 'MARS BARYCENTER'"):
        bio.read_aem(_write(tmp_path, "m.aem", t))
    bio.read_aem(_write(tmp_path, "n.aem", aem_text(center=None)))  # optional in an AEM


def test_aem_image_after_useable_stop_is_refused(tmp_path):
    """Issue 21: an image after segment 1's USEABLE_STOP_TIME was accepted."""
    t = aem_text(segments=((0.0, 60.0, 1.0, (0.0, 50.0)), (70.0, 120.0, 1.0, None)))
    att = bio.read_aem(_write(tmp_path, "s.aem", t))
    q, _ = att.at(T0 + np.array([10.0, 49.5, 80.0]) * u.s)
    assert np.max(_angle(q, Rotation.from_quat(att.q_is[:1]).as_quat().repeat(3, 0))) > 0  # read
    with pytest.raises(
        bio.InterpolationError,
        match=r"s.aem: image time 2024-03-01T12:00:55.000 is in the gap between segment 1 useable "
        r"2024-03-01T12:00:00.000 .. 2024-03-01T12:00:50.000 and segment 2 useable 2024-03-01T12:01:10.000",
    ):
        att.at(T0 + np.array([10.0, 55.0]) * u.s)


def test_aem_data_errors_name_the_line(tmp_path):
    t = aem_text()
    lines = t.splitlines()
    k = lines.index("DATA_START") + 5
    lines[k] = " ".join(lines[k].split()[:4])
    with pytest.raises(
        bio.IngestError,
        match=rf"line {k + 1}: segment 1: 4 fields on an attitude line; ATTITUDE_TYPE QUATERNION in AEM 1.0 has 5",
    ):
        bio.read_aem(_write(tmp_path, "d.aem", "\n".join(lines) + "\n"))
    lines = t.splitlines()
    lines[k] = lines[k].replace("T12:00:04", "T12:00:02")
    with pytest.raises(
        bio.IngestError, match=rf"line {k + 1}: segment 1: epoch 2024-03-01T12:00:02.000 is not after the previous line's"
    ):
        bio.read_aem(_write(tmp_path, "o.aem", "\n".join(lines) + "\n"))
    lines = t.splitlines()
    lines[k] = lines[k].replace("T12:00:04.000", "T12:00:04.000 x")
    lines[k] = " ".join(lines[k].split()[:5])
    with pytest.raises(bio.IngestError, match=rf"line {k + 1}: segment 1: attitude line field 1 'x' is not a number"):
        bio.read_aem(_write(tmp_path, "n.aem", "\n".join(lines) + "\n"))


def test_ingest_takes_the_gnss_sigma_from_the_oem_covariance(flight_obs, tmp_path, capsys):
    """An OEM with covariance blocks: `ingest` without --sigma-gnss-m writes the largest per-image σ
    into the noise model and says so; with it, the option wins and the file's range is printed."""
    from pathlib import Path

    import boresight
    from boresight.cli.main import main

    obs = flight_obs
    p = bio.export_flight_files(obs, tmp_path, camera())
    lines = Path(p["orbit"]).read_text().splitlines()
    epochs = [ln.split()[0] for ln in lines if ln[:2] == "20" and len(ln.split()) == 7]
    block = []
    for k, (e, s2) in enumerate(((epochs[0], 4e-6), (epochs[-1], 9e-6))):  # km²: σ 2 m then 3 m per axis
        block += [f"EPOCH = {e}"] + [
            " ".join(f"{(s2 if i == j and i < 3 else (1e-12 if i == j else 0.0)):.3e}" for j in range(i + 1)) for i in range(6)
        ]
    Path(p["orbit"]).write_text("\n".join(lines + ["COVARIANCE_START", *block, "COVARIANCE_STOP"]) + "\n")
    # no --sigma-gnss-m: its σ is to come from the OEM's covariance
    no_gnss = ["--sigma-pixel-m", "3e-6", "--sigma-star-tracker-arcsec", "4", "--sigma-catalogue-m", "0.1"]
    argv = ingest_argv(p, tmp_path / "o.ecsv", *no_gnss, "--no-check")
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert (
        "gnss sigma    from the OEM's covariance: 2 .. 3 m per axis over 20 image(s); the noise model holds one σ: the largest, 3 m, written"
        in out
    )
    assert boresight.ObservationSet.read(tmp_path / "o.ecsv").noise["gnss"]["sigma_m"] == pytest.approx(3.0, rel=1e-12)
    assert main(argv + ["--sigma-gnss-m", "15"]) == 0
    assert "--sigma-gnss-m 15 m used; the OEM's covariance gives 2 .. 3 m per axis" in capsys.readouterr().out


def test_aem_2_0_xml_and_oem_day_of_year_gps_epochs(tmp_path):
    """An AEM 2.0 in XML (hand-written after the ADM 2.0 schema's element names) reads like its KVN;
    an OEM with day-of-year epochs in GPS time reads to the same states as UTC calendar epochs."""
    ts = np.arange(0.0, 10.5, 1.0)
    q = _quats(ts)
    states = "\n".join(
        f"<attitudeState><quaternionState><EPOCH>{s}</EPOCH><quaternion><Q1>{float(x[0])!r}</Q1><Q2>{float(x[1])!r}</Q2><Q3>{float(x[2])!r}</Q3>"
        f"<QC>{float(x[3])!r}</QC></quaternion></quaternionState></attitudeState>"
        for s, x in zip(_iso(ts), q)
    )
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>
<aem id="CCSDS_AEM_VERS" version="2.0">
<header><CREATION_DATE>2024-01-01T00:00:00</CREATION_DATE><ORIGINATOR>test</ORIGINATOR><MESSAGE_ID>42</MESSAGE_ID></header>
<body><segment><metadata>
<OBJECT_NAME>X</OBJECT_NAME><OBJECT_ID>2024-001A</OBJECT_ID><REF_FRAME_A>EME2000</REF_FRAME_A><REF_FRAME_B>SC_BODY_1</REF_FRAME_B>
<TIME_SYSTEM>UTC</TIME_SYSTEM><START_TIME>{_iso([0.0])[0]}</START_TIME><STOP_TIME>{_iso([10.0])[0]}</STOP_TIME>
<ATTITUDE_TYPE>QUATERNION</ATTITUDE_TYPE>
</metadata><data>
{states}
</data></segment></body></aem>
"""
    got = bio.read_aem(_write(tmp_path, "a2.xml", xml))
    ref = bio.read_aem(
        _write(tmp_path, "a2.aem", aem_text("2.0", segments=((0.0, 10.0, 1.0, None),), drop=("QUATERNION_TYPE", "ATTITUDE_DIR")))
    )
    assert np.max(_angle(got.q_is, ref.q_is)) < 1e-6
    bad = xml.replace(
        "<ATTITUDE_TYPE>QUATERNION</ATTITUDE_TYPE>",
        "<ATTITUDE_TYPE>QUATERNION</ATTITUDE_TYPE><QUATERNION_TYPE>FIRST</QUATERNION_TYPE>",
    )
    with pytest.raises(
        bio.IngestError,
        match=rf"line {_line(bad, 'QUATERNION_TYPE')}: segment 1: QUATERNION_TYPE 'FIRST' is not allowed in AEM 2.0",
    ):
        bio.read_aem(_write(tmp_path, "b.xml", bad))
    # OEM: 2024-03-01 is day 061; GPS = UTC + 18 s in 2024
    utc = oem_text()
    gps = utc.replace("TIME_SYSTEM = UTC", "TIME_SYSTEM = GPS")
    gps = re.sub(r"2024-03-01T12:(\d\d):(\d\d)", lambda m: f"2024-061T12:{m.group(1)}:{int(m.group(2)) + 18:02d}", gps)
    a, b = bio.read_oem(_write(tmp_path, "u.oem", utc)), bio.read_oem(_write(tmp_path, "g.oem", gps))
    assert np.max(np.abs((a.times - b.times).to_value("s"))) < 1e-6 and np.array_equal(a.r_m, b.r_m)


def test_ingest_refuses_images_in_an_oem_gap_with_exit_1(flight_obs, tmp_path, capsys):
    """Issue 21, from the command line: an OEM cut into two segments whose useable spans leave a
    hole over some image times gave exit 0; now exit 1 and one line naming both spans."""
    from pathlib import Path

    from boresight.cli.main import main

    obs = flight_obs
    p = bio.export_flight_files(obs, tmp_path, camera())
    lines = Path(p["orbit"]).read_text().splitlines()
    k0 = lines.index("META_START")
    k1 = lines.index("META_STOP")
    head, meta = lines[:k0], lines[k0 + 1 : k1]
    rows = [ln for ln in lines[k1 + 1 :] if ln.strip()]
    ep = [r.split()[0] for r in rows]
    half = len(rows) // 2

    def seg(rs, a, b):
        m = [ln for ln in meta if not ln.startswith(("START_TIME", "STOP_TIME"))]
        return [
            "META_START",
            *m,
            f"START_TIME = {rs[0].split()[0]}",
            f"STOP_TIME = {rs[-1].split()[0]}",
            f"USEABLE_START_TIME = {a}",
            f"USEABLE_STOP_TIME = {b}",
            "META_STOP",
            *rs,
            "",
        ]

    text = head + seg(rows[: half + 2], ep[0], ep[half - 1]) + seg(rows[half - 2 :], ep[half + 1], ep[-1])
    Path(p["orbit"]).write_text("\n".join(text) + "\n")
    rc = main(ingest_argv(p, tmp_path / "o.ecsv", "--no-check"))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and not (tmp_path / "o.ecsv").exists()
    iso = lambda s: Time(s, scale="utc").isot  # noqa: E731 - as the message prints times
    assert (
        len(err) == 1
        and f"image time {iso(ep[half])} is in the gap between segment 1 useable {iso(ep[0])} .. {iso(ep[half - 1])} and segment 2 useable {iso(ep[half + 1])}"
        in err[0]
    ), err


# ----------------------------------------------------------------------------------- issue 31, class 4


@pytest.mark.parametrize("value", ["LAST", "FIRST"])
def test_aem_2_0_refuses_the_1_0_only_quaternion_type(tmp_path, value):
    """AEM 2.0 (504.0-B-2) has no QUATERNION_TYPE: its quaternions are scalar-last by definition.
    A 2.0 header over 1.0 metadata is a writer's slip whose data order cannot be trusted, so the
    keyword is refused with its line whatever its value (it used to be accepted when LAST)."""
    t = aem_text("2.0", qtype=value, drop=("ATTITUDE_DIR",))
    with pytest.raises(
        bio.IngestError, match=rf"line {_line(t, 'QUATERNION_TYPE')}: segment 1: QUATERNION_TYPE .* not allowed in AEM 2.0"
    ):
        bio.read_aem(_write(tmp_path, "q2.aem", t))


@pytest.mark.parametrize("field, value", [(4, "-1e308"), (1, "1e12"), (2, "nan"), (6, "9e9")])
def test_oem_refuses_an_absurd_value_in_any_state_even_one_no_image_uses(tmp_path, field, value):
    """``X_DOT = -1e308`` on a state no image used was accepted. Every state of an Earth orbiter's
    OEM is checked: finite, |r| between 6 000 and 2 000 000 km, |v| below 20 km/s."""

    def hook(rows):
        parts = rows[-1].split()
        parts[field] = value
        return rows[:-1] + [" ".join(parts)]

    t = oem_text(rows_hook=hook)
    last = [ln for ln in t.splitlines() if value in ln][0]
    with pytest.raises(bio.IngestError, match=rf"line {t.splitlines().index(last) + 1}: segment 1: "):
        bio.read_oem(_write(tmp_path, "x.oem", t))


@pytest.mark.parametrize("kind", ["aem", "oem"])
def test_data_that_stop_short_of_stop_time_are_refused(tmp_path, kind):
    """START_TIME .. STOP_TIME is the span the data cover (502.0-B table 5-3, 504.0-B table 4-3);
    data that end 30 s before STOP_TIME (a truncated file) used to be accepted."""
    if kind == "aem":
        t = aem_text(segments=((0.0, 60.0, 1.0, None),))
        t = t.replace(f"STOP_TIME = {_iso([60.0])[0]}", f"STOP_TIME = {_iso([90.0])[0]}")
        read = bio.read_aem
    else:
        t = oem_text()
        t = t.replace(f"STOP_TIME = {_iso([600.0])[0]}", f"STOP_TIME = {_iso([630.0])[0]}")
        read = bio.read_oem
    with pytest.raises(bio.IngestError, match=rf"line {_line(t, 'STOP_TIME')}: segment 1: the data stop 30 s before STOP_TIME"):
        read(_write(tmp_path, f"short.{kind}", t))


def test_the_shipped_example_attitude_has_no_rate_kink():
    """examples/flight-pass/attitude.aem held the attitude still before the first and after the last
    image (SLERP clipped to the images): the rate jumped 11″/s → 1 803″/s there. Regenerated with
    the site-tracking attitude at every sample: the sample-to-sample rate changes by the star
    tracker's noise only — 4″ per axis per sample gives a rate difference of about
    √6 · 4 · √3 ≈ 17″/s rms in magnitude, so 200″/s is > 10 σ, and the kink was 1 792″/s."""
    from boresight.observations.flight.shipped import example_dir

    a = bio.read_aem(example_dir("flight-pass") / "attitude.aem")
    t = (a.times - a.times[0]).to_value("s")
    r = Rotation.from_quat(a.q_is)
    rate = (r[1:] * r[:-1].inv()).magnitude() / np.diff(t) / ARCSEC
    assert np.abs(np.diff(rate)).max() < 200.0, np.abs(np.diff(rate)).max()
