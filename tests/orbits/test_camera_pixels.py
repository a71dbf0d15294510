"""The camera in pixels: OpenCV's pinhole + Brown–Conrady model, its inverse, files with u v columns."""

from dataclasses import replace

import numpy as np
import pytest
from astropy.table import Table
from oracles import dense_grid

import boresight
import orbits
from boresight import ObservationFileError, ObservationSet
from orbits.camera import UNDISTORT_TOL_PX, CalibratedCamera, Camera, CameraCalibration

AXES = [("+x", "-y"), ("+x", "+y"), ("-y", "-x"), ("+y", "+x"), ("-x", "+y")]
# realistic lens calibrations (OpenCV sign conventions): barrel, pincushion, tangential, a mix
DISTORTIONS = [
    dict(k1=-0.12, k2=0.05, k3=-0.01, p1=2e-4, p2=-3e-4),
    dict(k1=0.08, k2=-0.02, k3=0.004),
    dict(p1=1e-3, p2=5e-4),
    dict(k1=-0.3, k2=0.1, k3=0.0, p1=-5e-4, p2=8e-4),
]


def _cal(axes=("+x", "-y"), F=0.1, pitch=5.5e-6, **dist):
    return CameraCalibration(F, (F / pitch, 1.003 * F / pitch), (1021.3, 1030.7), axes[0], axes[1], pixel_pitch_m=None, **dist)


def _grid(F=0.1, half_deg=8.0, n=21):
    h = F * np.tan(np.radians(half_deg))
    g = np.linspace(-h, h, n)
    return np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)


@pytest.mark.parametrize("dist", DISTORTIONS)
@pytest.mark.parametrize("axes", AXES)
def test_forward_map_equals_opencv_projectpoints(axes, dist):
    cv2 = pytest.importorskip("cv2")
    cam = _cal(axes, **dist)
    xy = _grid()
    basis = np.array([{"+x": (1, 0), "-x": (-1, 0), "+y": (0, 1), "-y": (0, -1)}[a] for a in axes], float)
    # OpenCV's camera frame: x_C along u, y_C along v, z_C along the line of sight (−z_K)
    pts = np.column_stack([xy @ basis.T, np.full(len(xy), cam.focal_length_m)])
    ref, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), cam.camera_matrix, cam.dist_coeffs)
    ours = cam.focal_plane_to_pixels(xy)
    assert np.abs(ours - ref.reshape(-1, 2)).max() <= 1e-9
    # the comparison can fail: the distortion moves the points by far more than the tolerance
    pinhole = replace(cam, **{k: 0.0 for k in ("k1", "k2", "k3", "p1", "p2")}).focal_plane_to_pixels(xy)
    assert np.abs(pinhole - ref.reshape(-1, 2)).max() > 1.0


@pytest.mark.parametrize("dist", DISTORTIONS)
def test_inverse_map_round_trips(dist):
    cam = _cal(("+x", "-y"), **dist)
    xy = _grid()
    uv = cam.focal_plane_to_pixels(xy)
    back = cam.pixels_to_focal_plane(uv)
    assert np.abs(cam.focal_plane_to_pixels(back) - uv).max() <= UNDISTORT_TOL_PX
    assert np.abs(back - xy).max() <= 1e-12 * cam.focal_length_m * 100  # 1e-10 of F: a 1e-9 px round trip
    # and pixels → focal plane → pixels over a detector grid
    g = np.linspace(0.0, 2048.0, 17)
    uv2 = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    assert np.abs(cam.focal_plane_to_pixels(cam.pixels_to_focal_plane(uv2)) - uv2).max() <= UNDISTORT_TOL_PX


def test_inverse_map_refuses_a_point_beyond_the_invertible_region():
    cam = _cal(("+x", "-y"), k1=-0.5)  # radial factor 1 − 0.5 r² folds over at r = 1/√1.5
    with pytest.raises(ValueError, match=r"pixel \[.*\] at index \(1,\) cannot be undistorted"):
        cam.pixels_to_focal_plane([[1024.0, 1024.0], [1021.3 + 0.9 * cam.focal_length_px[0], 1030.7]])


def test_opencv_paste_and_named_keys_agree():
    K = [[18000.0, 0.0, 1010.5], [0.0, 18010.0, 990.25], [0.0, 0.0, 1.0]]
    d = [-0.1, 0.02, 1e-4, -2e-4, 0.003]
    a = CameraCalibration.from_mapping({"camera_matrix": K, "dist_coeffs": d, "u_axis": "+x", "v_axis": "-y"}, focal_length_m=0.1)
    b = CameraCalibration.from_mapping(
        {
            "focal_length_px": [18000.0, 18010.0],
            "principal_point_px": [1010.5, 990.25],
            "u_axis": "+x",
            "v_axis": "-y",
            "k1": -0.1,
            "k2": 0.02,
            "p1": 1e-4,
            "p2": -2e-4,
            "k3": 0.003,
        },
        focal_length_m=0.1,
    )
    assert a == b
    assert np.array_equal(a.dist_coeffs, d) and np.array_equal(a.camera_matrix, K)
    assert CameraCalibration.from_mapping(a.to_mapping()) == a


@pytest.mark.parametrize(
    "block, msg",
    [
        ({"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "v_axis": "-y"}, r"needs u_axis"),
        ({"principal_point_px": [1, 2], "u_axis": "+x", "v_axis": "-y"}, r"needs pixel_pitch_m or focal_length_px"),
        ({"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "u_axis": "+x", "v_axis": "-x"}, r"must be perpendicular"),
        ({"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "u_axis": "x", "v_axis": "-y"}, r"u_axis must be one of"),
        (
            {"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "focal_length_px": 12000, "u_axis": "+x", "v_axis": "-y"},
            r"disagrees with focal_length_m = 0.1",
        ),
        (
            {"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "u_axis": "+x", "v_axis": "-y", "k1": True},
            r"k1 must be a finite number \(or a list of them\), got True",
        ),
        (
            {"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "u_axis": "+x", "v_axis": "-y", "dist_coeffs": [0, 0, 0]},
            r"dist_coeffs must be",
        ),
        ({"principal_point_px": [1, 2], "pixel_pitch_m": 1e-5, "u_axis": "+x", "v_axis": "-y", "kk": 1}, r"unknown key 'kk'"),
    ],
)
def test_calibration_block_errors_name_the_key(block, msg):
    with pytest.raises(ValueError, match=msg) as err:
        CameraCalibration.from_mapping(block, where="metadata 'camera'", focal_length_m=0.1)
    assert str(err.value).count("metadata 'camera'") == 1, str(err.value)  # named once, not "camera: camera: …"


@pytest.mark.parametrize(
    "block, msg",
    [
        (
            {"principal_point_px": [1, 2], "focal_length_px": 1e4, "dist_coeffs": [0, 0, 0, 0], "k1": 0.1},
            "give dist_coeffs or k1 k2 k3 p1 p2, not both",
        ),
        (
            {"camera_matrix": [[1e4, 0, 1], [0, 1e4, 1], [0, 0, 1]], "focal_length_px": 1e4},
            "give camera_matrix or focal_length_px, not both",
        ),
    ],
)
def test_calibration_block_clash_is_named_once(block, msg):
    with pytest.raises(ValueError) as err:
        CameraCalibration.from_mapping({**block, "u_axis": "+x", "v_axis": "-y"}, where="camera", focal_length_m=0.1)
    assert str(err.value) == f"camera: {msg}"


# ---------------------------------------------------------------------------- simulator and files


def _pixel_scenario(**dist):
    sc = orbits.load_scenario("scenarios/kiev2012-kalman20.toml")
    c = sc.camera
    cam = CalibratedCamera(
        c.focal_length_m, c.fov_deg, 5.5e-6, principal_point_px=(4000.5, 3999.5), u_axis="+x", v_axis="-y", **dist
    )
    return replace(sc, camera=cam)


def test_scenario_camera_keys_reach_the_calibration():
    sc = orbits.scenario_from_dict(
        {
            "name": "px",
            "orbit": {"altitude_km": 680, "inclination_deg": 98},
            "camera": {
                "focal_length_m": 2.2,
                "fov_deg": 3.4,
                "pixel_pitch_m": 5.5e-6,
                "principal_point_px": [4000, 4000],
                "u_axis": "+x",
                "v_axis": "-y",
                "k1": -0.05,
                "p2": 1e-4,
            },
            "passes": [{"site_lat_deg": 50.45, "site_lon_deg": 30.52, "t_s": [0.0, 5.0]}],
        }
    )
    cal = sc.camera.calibration()
    assert cal.focal_length_px == (2.2 / 5.5e-6,) * 2 and cal.k1 == -0.05 and cal.p2 == 1e-4
    with pytest.raises(orbits.ScenarioError, match=r"need principal_point_px"):
        orbits.scenario_from_dict(
            {
                "name": "px",
                "orbit": {"altitude_km": 680, "inclination_deg": 98},
                "camera": {"focal_length_m": 2.2, "fov_deg": 3.4, "k1": -0.05},
                "passes": [{"site_lat_deg": 50.45, "site_lon_deg": 30.52, "t_s": [0.0]}],
            }
        )


def test_simulator_renders_distortion_and_file_round_trips_in_pixels(tmp_path):
    sc = _pixel_scenario(k1=-0.2, k2=0.05, p1=3e-4, p2=-2e-4)
    quiet = replace(sc, sigma_pixel_m=0.0)
    obs = boresight.simulate(quiet, np.random.default_rng(3))
    cal = obs.camera
    assert cal is not None and cal.has_distortion
    # noise-free: the measured point undistorted back to the ideal plane is the true point (rows)
    assert np.abs(obs.xy_m[0] - obs.truth["xy_true_m"][0]).max() < 1e-13
    p_uv = obs.write(tmp_path / "uv.ecsv", image_columns="uv")
    t = Table.read(p_uv)
    assert "u" in t.colnames and "x" not in t.colnames and str(t["u"].unit) == "pix"
    # the written pixels carry the distortion: they differ from a pinhole detector's
    pinhole = replace(cal, k1=0.0, k2=0.0, p1=0.0, p2=0.0).focal_plane_to_pixels(obs.xy_m[0])
    assert np.abs(np.column_stack([t["u"], t["v"]]) - pinhole).max() > 0.01
    back = ObservationSet.read(p_uv)
    assert back.camera == cal
    assert np.abs(back.xy_m - obs.xy_m).max() < 1e-9 * 5.5e-6  # 1e-9 px
    # noisy data: θ estimated from the pixel file equals θ from the metre file
    noisy = boresight.simulate(sc, np.random.default_rng(4))
    a = boresight.estimate(ObservationSet.read(noisy.write(tmp_path / "xy.ecsv")), algorithm="image_plane")
    b = boresight.estimate(ObservationSet.read(noisy.write(tmp_path / "uv2.ecsv", image_columns="uv")), algorithm="image_plane")
    assert np.abs((a.theta - b.theta).to_value("arcsec")).max() < 1e-6


def test_uv_columns_without_camera_metadata_are_refused(tmp_path):
    obs = boresight.simulate(_pixel_scenario(k1=-0.1), np.random.default_rng(1))
    p = obs.write(tmp_path / "uv.ecsv", image_columns="uv")
    t = Table.read(p)
    del t.meta["camera"]
    t.write(p, overwrite=True)
    with pytest.raises(ObservationFileError, match=r"uv.ecsv: columns 'u v' \(pixels\) need the metadata 'camera'"):
        ObservationSet.read(p)
    t.meta["camera"] = {"principal_point_px": [1, 2], "u_axis": "+x", "v_axis": "-y"}
    t.write(p, overwrite=True)
    with pytest.raises(ObservationFileError, match=r"metadata 'camera': needs pixel_pitch_m or focal_length_px"):
        ObservationSet.read(p)


def test_simulate_cli_pixels(tmp_path):
    from boresight.cli.main import main

    sc = tmp_path / "px.toml"
    text = (
        open("scenarios/kiev2012-kalman20.toml")
        .read()
        .replace(
            "[camera]",
            '[camera]\npixel_pitch_m = 5.5e-6\nprincipal_point_px = [4000.0, 4000.0]\nu_axis = "+x"\nv_axis = "-y"\nk1 = -0.1\n',
        )
    )
    sc.write_text(text)
    assert main(["simulate", str(sc), "--out", str(tmp_path), "--image-columns", "uv"]) == 0
    back = ObservationSet.read(next(tmp_path.glob("*.ecsv")))
    assert back.camera.k1 == -0.1
    assert main(["simulate", "scenarios/kiev2012-kalman20.toml", "--out", str(tmp_path / "b"), "--image-columns", "uv"]) != 0


def test_pinhole_camera_without_calibration_is_unchanged():
    cam = Camera(2.2, 3.4)
    assert cam.calibration() is None
    xy = np.array([[0.001, 0.002]])
    assert np.array_equal(orbits.camera.render_image_points(cam, xy, xy * 0.5), xy * 1.5)


# ---------------------------------------------------------------------------- pixel σ → focal-plane σK


@pytest.mark.parametrize("dist", DISTORTIONS)
@pytest.mark.parametrize("axes", AXES[:3])
def test_pixels_to_focal_plane_jacobian_equals_finite_differences(axes, dist):
    cam = _cal(axes, **dist)
    uv = cam.focal_plane_to_pixels(_grid(n=7))
    J = cam.pixels_to_focal_plane_jacobian(uv)
    h = 1e-3  # px: central differences, error ~h² × third derivative ≪ 1e-9 relative
    fd = np.stack(
        [(cam.pixels_to_focal_plane(uv + h * e) - cam.pixels_to_focal_plane(uv - h * e)) / (2 * h) for e in np.eye(2)], -1
    )
    assert np.abs(J - fd).max() <= 1e-7 * np.abs(J).max()


def test_focal_plane_sigma_without_distortion_is_sigma_px_times_pitch():
    pitch = (5.5e-6, 6.0e-6)  # rectangular pixels: the RMS per-axis σ, spread = the anisotropy
    cam = CameraCalibration(0.1, (0.1 / pitch[0], 0.1 / pitch[1]), (1000.0, 1000.0), "+x", "-y")
    s, spread = cam.focal_plane_sigma_m(0.4, [[10.0, 20.0], [1500.0, 700.0]])
    assert s == pytest.approx(0.4 * np.sqrt((pitch[0] ** 2 + pitch[1] ** 2) / 2), rel=1e-12)
    rms = np.sqrt((pitch[0] ** 2 + pitch[1] ** 2) / 2)
    assert spread == pytest.approx(max(abs(p / rms - 1) for p in pitch), rel=1e-9)
    with pytest.raises(ValueError, match="sigma_px must be a finite number ≥ 0"):
        cam.focal_plane_sigma_m(-1.0, [[0.0, 0.0]])


def _pixel_noise_monte_carlo(cal, sigma_px, runs=1000, seed=3):
    """Pixel-only noise drawn on the detector (σ_px per axis), undistorted as a u v file is read;
    θ estimated (GLS, batched over the runs) with σK = cal.focal_plane_sigma_m(σ_px) and with the
    naive σ_px × pitch: (sample sd of θ̂ − θ) / (reported σθ) per axis for each."""
    import tomllib

    from orbits.rotations import ARCSEC

    with open("scenarios/kiev2012-kalman20.toml", "rb") as fh:
        d = tomllib.load(fh)
    for t in ("gnss", "pixel", "catalogue"):
        d.setdefault(t, {})["sigma_m"] = 0.0
    d.setdefault("star_tracker", {})["sigma_arcsec"] = [0.0, 0.0, 0.0]
    obs = dense_grid(boresight.simulate(orbits.scenario_from_dict(d), np.random.default_rng(seed), runs=runs))  # tests/oracles.py
    m4 = obs.mask[None, :, :, None]
    uv_true = cal.focal_plane_to_pixels(obs.xy_m)
    uv = np.where(m4, uv_true + np.random.default_rng(seed + 1).normal(0.0, sigma_px, uv_true.shape), uv_true)
    noisy = replace(obs, xy_m=np.where(m4, cal.pixels_to_focal_plane(uv), obs.xy_m)).to_rows()
    sigma_m, spread = cal.focal_plane_sigma_m(sigma_px, uv_true[0][obs.mask])
    naive = sigma_px * cal.focal_length_m / cal.focal_length_px[0]
    out = []
    for s in (sigma_m, naive):
        est = boresight.estimate(noisy, weighting="gls", model=boresight.DisturbanceModel(sigma_pixel_m=s))
        err = est.theta.value - obs.truth["theta_rad"] / ARCSEC
        out.append(err.std(0, ddof=1) / est.sigma.value.mean(0))
    return out[0], out[1], sigma_m, spread


def _sd_ratio_bounds(runs, level=0.999):
    # (runs−1) s²/σ² ~ χ²(runs−1): the central `level` range of s/σ (±7.6 % at 1000 runs; a factor
    # 2 in σK, e.g. a pixel σ taken as metres per 2 px, is far outside it)
    from scipy.stats import chi2

    a = (1 - level) / 2
    return np.sqrt(chi2.ppf(a, runs - 1) / (runs - 1)), np.sqrt(chi2.ppf(1 - a, runs - 1) / (runs - 1))


def test_pixel_sigma_converts_to_the_right_focal_plane_sigma_with_distortion():
    """Issue 11 'camera in pixels', Monte Carlo: centroiding noise given in pixels, converted with the
    calibration (pitch and distortion), gives a reported σθ equal to the sample scatter of θ̂.
    A realistic lens (the example pass's): the conversion is σ_px × pitch to 1e-4. A synthetic
    strong lens (k1 = 250 on a 3.4° field: the local scale changes by up to 12 %): the converted σK
    passes on θx, θy where the naive σ_px × pitch (12 % too large) fails."""
    lo, hi = _sd_ratio_bounds(1000)
    real = CameraCalibration(2.2, (2.2 / 13e-6,) * 2, (5119.5, 5119.5), "+x", "-y", k1=-0.08, k2=0.02, p1=2e-5, p2=-1e-5)
    good, _, s, spread = _pixel_noise_monte_carlo(real, 0.3)
    assert s == pytest.approx(0.3 * 13e-6, rel=1e-4) and spread < 1e-3
    assert np.all((good > lo) & (good < hi)), (good, lo, hi)
    strong = replace(real, k1=250.0, k2=0.0)
    good, naive, s, spread = _pixel_noise_monte_carlo(strong, 0.3)
    assert 0.11 < spread < 0.13 and 0.88 < s / (0.3 * 13e-6) < 0.9  # the figures docs/tutorial-flight-data.md quotes
    assert np.all((good[:2] > lo) & (good[:2] < hi)), (good, lo, hi)
    assert np.all(naive[:2] < lo), (naive, lo)
    # θz: one isotropic σK cannot describe anisotropic noise exactly (spread 12 %); still within the band
    assert lo < good[2] < hi, (good, lo, hi)
