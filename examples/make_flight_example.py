"""Make the flight-style example data set in ``examples/flight-pass/`` (see its README.md).

A pass of CBERS-2 (NORAD 28057, an Earth-resources imager in a 778 km sun-synchronous orbit) over
landmarks near the sub-satellite point, from the real published two-line element set of the
SGP4 verification file (Vallado et al. 2006, "Revisiting Spacetrack Report #3", AIAA 2006-6753;
shipped with the ``sgp4`` package as ``SGP4-VER.TLE``), propagated with ``sgp4``. The camera tracks
a site; the star tracker is mounted at an angle; the true misalignment θ is fixed below. Written:

* ``orbit.oem``       CCSDS OEM v2 (KVN, GCRF), samples every 10 s, Lagrange degree 7 (``oem`` package)
* ``attitude.aem``    CCSDS AEM (KVN, ICRF → STAR_TRACKER, scalar last), 1 Hz samples with the
                      star-tracker noise (``ccsds-ndm``)
* ``landmarks.csv``   WGS84 latitude/longitude/height of 9 landmarks (catalogue error σP included)
* ``detections.csv``  pixel (u, v) of every landmark in every image as real light shows it (light time
                      and aberration, ``orbits.sight.apparent_sight_i``: ``boresight ingest``'s default
                      ``--landmark-sight light_time+aberration`` reads it back), Brown–Conrady distortion and
                      pixel noise applied
* ``camera.toml``     the calibration (OpenCV convention) and the star-tracker mount

Run from the repository root: ``python examples/make_flight_example.py`` (seeded: the files are
reproduced bit for bit on one machine; the committed ones were made this way).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from astropy import units as u
from astropy.coordinates import EarthLocation
from astropy.time import Time
from scipy.spatial.transform import Rotation

from boresight.observations import flight as bio
from orbits.camera import CameraCalibration
from orbits.earth import itrs_to_gcrs_dcm
from orbits.rotations import ARCSEC, misalignment_dcm, star_tracker_error_dcm
from orbits.sight import EARTH_SPIN_G_RAD_S, SightCorrections, apparent_sight_i

OUT = Path(__file__).resolve().parent / "flight-pass"

# CBERS 2, from SGP4-VER.TLE (Vallado et al. 2006)
TLE = (
    "1 28057U 03049A   06177.78615833  .00000060  00000-0  35940-4 0  1836",
    "2 28057  98.4283 247.6961 0000884  88.1964 271.9322 14.35478080140550",
)

THETA_TRUE_ARCSEC = np.array([25.0, -40.0, 60.0])  # the misalignment hidden in the data
MOUNT_DEG = (59.0, 19.0, 132.2)  # star tracker mount C_ES (Z-Y-X), as in the Kiev 2012 case
SIGMA_PIXEL_PX = 0.3  # centroiding noise
SIGMA_STAR_TRACKER_ARCSEC = 4.0  # per sample, per axis
SIGMA_CATALOGUE_M = 0.5  # landmark survey error per axis
PASS_START_S = 1200.0  # seconds after the TLE epoch
IMAGE_TIMES_S = np.arange(0.0, 80.0, 4.0)  # 20 images, 4 s apart, on the 1 Hz attitude grid
# 10240 × 10240 pixels of 13 µm; u (column) along +x_K, v (row) along −y_K: OpenCV's image
CAMERA = CameraCalibration(
    2.2,
    (2.2 / 13e-6,) * 2,
    (5119.5, 5119.5),
    "+x",
    "-y",
    k1=-0.08,
    k2=0.02,
    k3=0.0,
    p1=2e-5,
    p2=-1e-5,
    pixel_pitch_m=(13e-6, 13e-6),
)
FOV_DEG = 3.4


def main(seed: int = 2026) -> dict:
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    OUT.mkdir(parents=True, exist_ok=True)
    epoch = Time("2006-06-26T18:52:03", scale="utc")  # a round second near the TLE epoch (06177.786…)
    t0 = epoch + PASS_START_S * u.s

    # orbit: SGP4 (TEME) → GCRS; OEM samples every 10 s over the pass ± 60 s
    oem_t = t0 + np.arange(-60.0, IMAGE_TIMES_S[-1] + 61.0, 10.0) * u.s
    oem_track = bio.orbit_from_tle(*TLE, oem_t, source="CBERS-2 TLE")
    bio.write_oem(
        OUT / "orbit.oem",
        oem_t,
        oem_track.r_m,
        oem_track.v_m_s,
        frame="GCRF",
        degree=7,
        object_name="CBERS 2",
        object_id="2003-049A",
    )

    # the site: the ground point under the spacecraft at mid-pass, 8 km east
    t_mid = t0 + IMAGE_TIMES_S.mean() * u.s
    mid = bio.orbit_from_tle(*TLE, t_mid[None])
    C_GI_mid = itrs_to_gcrs_dcm(t_mid[None])[0]
    r_g = C_GI_mid.T @ mid.r_m[0]
    sub = EarthLocation.from_geocentric(*r_g, unit=u.m).to_geodetic("WGS84")
    lat0, lon0 = float(sub.lat.deg), float(sub.lon.deg) + 8.0 / (111.32 * np.cos(np.radians(float(sub.lat.deg))))
    site = EarthLocation.from_geodetic(lon0 * u.deg, lat0 * u.deg, 150.0 * u.m, ellipsoid="WGS84")
    site_g = np.array([site.x.to_value(u.m), site.y.to_value(u.m), site.z.to_value(u.m)])

    # landmarks: a 3 × 3 grid ±12 km around the site, heights 50..400 m
    de, dn = np.meshgrid([-12.0, 0.0, 12.0], [-12.0, 0.0, 12.0])
    lat = lat0 + dn.ravel() / 111.32
    lon = lon0 + de.ravel() / (111.32 * np.cos(np.radians(lat0)))
    h = rng.uniform(50.0, 400.0, lat.size)
    loc = EarthLocation.from_geodetic(lon * u.deg, lat * u.deg, h * u.m, ellipsoid="WGS84")
    L_true = np.stack([loc.x.to_value(u.m), loc.y.to_value(u.m), loc.z.to_value(u.m)], -1)
    ids = np.array([f"L{k + 1}" for k in range(lat.size)])
    bio.write_landmarks_csv(OUT / "landmarks.csv", ids, L_true + rng.normal(0.0, SIGMA_CATALOGUE_M, L_true.shape))

    # camera attitude: boresight (−z_K) on the site, x_K along the ground track
    def site_tracking(t):
        """(C_IK (n, 3, 3) rows: camera axes in I, C_GI, orbit) of the site-tracking attitude at ``t``."""
        sc = bio.orbit_from_tle(*TLE, t)
        C_GI = itrs_to_gcrs_dcm(t)
        z = -(C_GI @ site_g - sc.r_m)
        z /= np.linalg.norm(z, axis=-1, keepdims=True)
        x = sc.v_m_s - np.sum(sc.v_m_s * z, -1, keepdims=True) * z
        x /= np.linalg.norm(x, axis=-1, keepdims=True)
        return np.stack([x, np.cross(z, x), z], axis=-2), C_GI, sc

    t_img = t0 + IMAGE_TIMES_S * u.s
    C_IK, C_GI, sc = site_tracking(t_img)
    C_ES = Rotation.from_euler("ZYX", MOUNT_DEG, degrees=True).as_matrix().T
    C_SK_nom = C_ES.T
    C_SK_true = misalignment_dcm(THETA_TRUE_ARCSEC * ARCSEC) @ C_SK_nom

    # attitude samples at 1 Hz over the pass ± 10 s, each with its own star-tracker error
    aem_s = np.arange(-10.0, IMAGE_TIMES_S[-1] + 11.0, 1.0)
    aem_t = t0 + aem_s * u.s
    # the true attitude at every sample: the same site tracking, so its rate is smooth before the
    # first and after the last image too (issue 31: SLERP clipped to the images held it still
    # there — a rate kink of 11″/s → 1 803″/s at the first and last image)
    A_fine = C_SK_true.T @ site_tracking(aem_t)[0]  # C_IS
    on_image = np.isin(aem_s, IMAGE_TIMES_S)
    A_fine[on_image] = C_SK_true.T @ C_IK  # the image times' own (identical up to round-off)
    delta = rng.normal(0.0, SIGMA_STAR_TRACKER_ARCSEC * ARCSEC, (aem_s.size, 3))
    A_meas = star_tracker_error_dcm(delta) @ A_fine
    q_meas = Rotation.from_matrix(np.swapaxes(A_meas, -1, -2)).as_quat()
    q_meas = np.where(q_meas[:, 3:4] < 0, -q_meas, q_meas)
    bio.write_aem(OUT / "attitude.aem", aem_t, q_meas, object_name="CBERS 2", object_id="2003-049A")

    # detections: project every landmark, seen as real light shows it (light time and aberration from the true
    # position and velocity and the Earth's spin: orbits.sight.apparent_sight_i, the simulator's
    # landmark_sight="light_time+aberration"), with the true camera attitude, distort, add pixel noise
    d = apparent_sight_i(
        sc.r_m[:, None, :], sc.v_m_s[:, None, :], C_GI[:, None], L_true[None], EARTH_SPIN_G_RAD_S, SightCorrections(True, True)
    ).direction_i
    s = np.einsum("nij,nmj->nmi", C_IK, d)
    xy = -CAMERA.focal_length_m * s[..., :2] / s[..., 2:3]
    uv = CAMERA.focal_plane_to_pixels(xy) + rng.normal(0.0, SIGMA_PIXEL_PX, xy.shape)
    nn, mm = np.meshgrid(np.arange(t_img.size), np.arange(ids.size), indexing="ij")
    iso = np.array(Time(t_img, precision=3).isot)
    bio.write_detections_csv(OUT / "detections.csv", iso[nn.ravel()], ids[mm.ravel()], uv.reshape(-1, 2))
    bio.write_camera_toml(OUT / "camera.toml", CAMERA, C_SK_nom, FOV_DEG)
    return {
        "site_lat_deg": lat0,
        "site_lon_deg": lon0,
        "theta_true_arcsec": THETA_TRUE_ARCSEC.tolist(),
        "max_off_axis_mm": float(np.max(np.abs(xy)) * 1e3),
    }


if __name__ == "__main__":
    print(main())
