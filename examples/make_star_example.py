"""Make the star-centroid example data set in ``examples/stars/`` (``docs/tutorial-stars.md``, step 1).

An inertial hold of the seminar's camera (F = 2.2 m, 3.4° field, 13 µm pixels) towards Monoceros
(RA 100°, Dec 20°) from a 600 km sun-synchronous orbit, 30 frames 10 s apart, with a true
misalignment θ = (40, −25, 70)″ the files do not contain. Written:

* ``orbit.csv``      GCRS position and velocity every 2 s (``--orbit-csv … --orbit-frame GCRS``)
* ``attitude.csv``   the star tracker's quaternion every 2 s, GCRS → star tracker, scalar last, with
                     its error, 4″ per axis per sample (``--attitude-csv … --quaternion-order
                     scalar_last --attitude-frame GCRS``); the frames fall on samples
* ``centroids.csv``  every detection of every frame as detector pixels ``u v`` and a measured
                     magnitude, without identities: Hipparcos stars to Hp 7.5 (centroid σ 0.1 pixel),
                     2 false detections per frame on average and one hot pixel, shuffled
* ``camera.toml``    the calibration (a distortion-free detector, +x columns, +y rows) and fov_deg

Run from the repository root: ``python examples/make_star_example.py`` (seeded; needs the optional
extra ``stars`` for Hipparcos).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from astropy import units as u
from astropy.time import Time

from orbits.camera import Camera, CameraCalibration
from orbits.orbit import CircularOrbit
from orbits.rotations import ARCSEC, quat_from_dcm, star_tracker_error_dcm
from orbits.star_catalogue import load_hipparcos
from orbits.star_frames import CentroidNoise, StarDetector, inertial_hold, simulate_star_frames

OUT = Path(__file__).resolve().parent / "stars"
THETA = np.array([40.0, -25.0, 70.0]) * ARCSEC
EPOCH = Time("2026-03-01T00:00:00", scale="utc")
PITCH_M, F_M, FOV_DEG = 13e-6, 2.2, 3.4
SIGMA_TRACKER = 4.0 * ARCSEC


def main() -> None:
    rng = np.random.default_rng(2028)
    orbit = CircularOrbit(600e3, np.radians(97.8), np.radians(90.0))
    # the hold: Monoceros, near the galactic plane (dense in Hipparcos stars), seen from the point of
    # the orbit closest to the zenith there, on the night side in March
    b = np.array(
        [
            np.cos(np.radians(20.0)) * np.cos(np.radians(100.0)),
            np.cos(np.radians(20.0)) * np.sin(np.radians(100.0)),
            np.sin(np.radians(20.0)),
        ]
    )
    grid = np.radians(np.arange(0.0, 360.0, 0.5))
    u0 = grid[np.argmax(orbit.unit_position(grid) @ b)]
    ts = np.arange(-10.0, 300.0 + 10.0, 2.0)
    r, v = orbit.state(u0 + orbit.mean_motion_rad_s * ts)
    times = (EPOCH + ts * u.s).isot
    with open(OUT / "orbit.csv", "w") as f:
        f.write("# GCRS position (m) and velocity (m/s) of the spacecraft; docs/tutorial-stars.md\n")
        f.write("time_utc,x_m,y_m,z_m,vx_m_s,vy_m_s,vz_m_s\n")
        for t, a, b in zip(times, r, v):
            f.write(f"{t},{a[0]:.4f},{a[1]:.4f},{a[2]:.4f},{b[0]:.6f},{b[1]:.6f},{b[2]:.6f}\n")
    C_IE = inertial_hold(100.0, 20.0, 35.0)
    delta = rng.normal(0.0, SIGMA_TRACKER, (ts.size, 3))  # the tracker's error, one per sample
    q = quat_from_dcm(star_tracker_error_dcm(delta) @ C_IE)  # mount: identity
    with open(OUT / "attitude.csv", "w") as f:
        f.write("# star-tracker attitude quaternion, GCRS -> star tracker, scalar last; docs/tutorial-stars.md\n")
        f.write("time_utc,q0,q1,q2,q3\n")
        for t, a in zip(times, q):
            f.write(f"{t},{a[0]:.12f},{a[1]:.12f},{a[2]:.12f},{a[3]:.12f}\n")
    frames = np.arange(0.0, 300.0, 10.0)
    on = np.searchsorted(ts, frames)
    cam = Camera(F_M, FOV_DEG, PITCH_M)
    det = StarDetector(centroid=CentroidNoise(0.0, 6.0, 0.1 * PITCH_M), false_per_frame=2.0, hot_pixels_xy_m=[[0.0213, -0.0371]])
    fr = simulate_star_frames(
        load_hipparcos(8.5), cam, EPOCH + frames * u.s, r[on], v[on], np.broadcast_to(C_IE, (frames.size, 3, 3)), THETA, det, rng
    )
    cal = CameraCalibration(F_M, (F_M / PITCH_M,) * 2, (2619.5, 2619.5), "+x", "+y")
    f_, d_ = np.nonzero(fr.mask)
    uv = cal.focal_plane_to_pixels(fr.xy_m[f_, d_])
    with open(OUT / "centroids.csv", "w") as f:
        f.write("# star centroids without identities (pixels) and measured magnitudes; docs/tutorial-stars.md\n")
        f.write("time_utc,u,v,magnitude\n")
        for t, p, m in zip((EPOCH + frames[f_] * u.s).isot, uv, fr.magnitude[f_, d_]):
            f.write(f"{t},{p[0]:.4f},{p[1]:.4f},{m:.2f}\n")
    (OUT / "camera.toml").write_text(
        "# the camera of examples/stars (docs/tutorial-stars.md): 2.2 m, 13 µm pixels, 5240 × 5240, no distortion\n"
        "[camera]\nfocal_length_m = 2.2\npixel_pitch_m = 13e-6\nprincipal_point_px = [2619.5, 2619.5]\n"
        'u_axis = "+x"\nv_axis = "+y"\nfov_deg = 3.4\n'
    )
    print(f"wrote {OUT}: {fr.mask.sum()} centroids in {frames.size} frames ({np.sum(fr.kind[fr.mask] == 0)} stars)")


if __name__ == "__main__":
    main()
