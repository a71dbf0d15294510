"""Issue 14's reader cases: every one refused with the file, the column or key, the row and the value —
or, for correct input, accepted (units converted, never-seen landmarks, simulated edge cases)."""

import re
from dataclasses import replace

import numpy as np
import pytest
from astropy.table import Table

import boresight
import orbits
from boresight import ObservationError, ObservationFileError, ObservationSet

KALMAN20 = "scenarios/kiev2012-kalman20.toml"


@pytest.fixture(scope="module")
def obs():
    return boresight.simulate(KALMAN20, np.random.default_rng(21), runs=1)


@pytest.fixture()
def path(obs, tmp_path):
    return obs.write(tmp_path / "f.ecsv")


def _edit_table(path, fn):
    t = Table.read(path)
    fn(t)
    t.write(path, overwrite=True)
    return path


def _refused(path, pattern):
    with pytest.raises(ObservationFileError) as exc:
        ObservationSet.read(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: "), msg  # the file is named
    assert re.search(pattern, msg), msg
    return msg


# ---------------------------------------------------------------------------- integrity


def test_truncated_mid_number_is_refused(path):
    """Issue 14: the last y cut to '-0.' was read as valid (θ = [−1013, −10, 1436]″, exit 0)."""
    text = path.read_text()
    last = text.rstrip("\n").rsplit(" ", 1)
    path.write_text(last[0] + " -0.")
    _refused(
        path, r"row 79: the file does not end with a newline, so its last row '.* -0\.' may be cut short \(a truncated file\)"
    )


def test_truncated_at_a_row_boundary_is_refused(path):
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-3]))
    _refused(path, r"metadata 'n_rows' = 80 but the file has 77 data rows: the file is truncated")


def test_truncated_mid_row_is_refused(path):
    text = path.read_text().rstrip("\n")
    path.write_text(text[: text.rindex("\n") + 30])
    _refused(path, r"does not end with a newline")


# ---------------------------------------------------------------------------- rotations


@pytest.mark.parametrize(
    "name, mount",
    [("negated row", np.diag([1.0, 1.0, -1.0])), ("swapped rows", np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))],
)
def test_reflected_mount_is_refused(path, obs, name, mount):
    def f(t):
        t.meta["C_SK_nominal"] = (mount @ obs.C_SK_nominal).tolist()

    _edit_table(path, f)
    _refused(path, r"metadata 'C_SK_nominal' is a reflection, not a rotation \(det = -1; a proper rotation has det = \+1\)")


def test_sign_flipped_cgi_row_is_refused(path):
    def f(t):
        sel = t["image"] == 7
        for j in (1, 2, 3):
            t[f"cgi2{j}"][sel] = -t[f"cgi2{j}"][sel]

    _edit_table(path, f)
    msg = _refused(path, r"columns 'cgi11..cgi33' row \d+: image 7: a reflection, not a rotation \(det = -1")
    row = int(re.search(r"row (\d+)", msg).group(1))
    assert Table.read(path)["image"][row] == 7


def test_reflections_refused_in_memory_too(obs):
    with pytest.raises(ObservationError, match=r"ObservationSet.C_SK_nominal: a reflection"):
        replace(obs, C_SK_nominal=-obs.C_SK_nominal)
    flipped = obs.C_GI.copy()
    flipped[3, 1] *= -1
    with pytest.raises(ObservationError, match=r"ObservationSet.C_GI at image 3: a reflection"):
        replace(obs, C_GI=flipped)


def test_quaternion_matrices_are_always_proper(obs):
    """A(q) of a unit quaternion has det = |q|⁶ = +1: a negated (q → −q) or any unit quaternion is a
    rotation, so no reflection can enter through q1..q4."""
    from orbits.rotations import dcm_from_quat

    q = np.random.default_rng(0).normal(size=(1000, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    assert np.allclose(np.linalg.det(dcm_from_quat(q)), 1.0, atol=1e-12)
    assert np.allclose(dcm_from_quat(-q), dcm_from_quat(q), atol=1e-15)


def test_spherical_earth_file_without_cgi_is_refused(path):
    """Issue 14: cgi columns missing from a spherical-Earth file gave θ of 10³–10⁵″."""
    _edit_table(path, lambda t: t.remove_columns([c for c in t.colnames if c.startswith("cgi")]))
    _refused(path, r"columns cgi11..cgi33 are required: metadata 'frames' = .*spherical-earth")


# ---------------------------------------------------------------------------- geometry (one check, both paths)


def test_behind_the_camera_in_memory_and_in_a_file(obs, tmp_path):
    L = obs.landmark_g_m.copy()
    L[:, 1] *= 3.0  # three Earth radii: above the spacecraft, behind a downward-looking camera
    with pytest.raises(
        ObservationError, match=r"landmark 'M2' in image 0 is behind the camera \(camera-frame z = [\d.e+]+ m ≥ 0\)"
    ):
        replace(obs, landmark_g_m=L)
    p = replace(obs, landmark_g_m=L, check_geometry=False).write(tmp_path / "behind.ecsv")
    _refused(p, r"row 1: landmark 'M2' in image 0 is behind the camera")


def test_outside_the_field_in_memory_and_in_a_file(obs, tmp_path):
    xy = obs.xy_m.copy()
    xy[0, 4 * 4 + 2, 1] = (
        0.07  # image 4, landmark M3 (a complete set: row 4 n + m); half-width F tan(1.7°) = 65.3 mm; 1 % margin → 65.9 mm
    )
    with pytest.raises(
        ObservationError, match=r"landmark 'M3' in image 4 is outside the field of view \(y = 0.07 m, half-width 0.0652945"
    ):
        replace(obs, xy_m=xy)
    p = replace(obs, xy_m=xy, check_geometry=False).write(tmp_path / "out.ecsv")
    _refused(p, r"column 'y' row 18: landmark 'M3' in image 4 is outside the field of view \(y = 0.07 m")


# ---------------------------------------------------------------------------- units


@pytest.mark.parametrize(
    "cols, unit, factor",
    [(("x", "y"), "mm", 1e3), (("r_x", "r_y", "r_z"), "km", 1e-3), (("t",), "ms", 1e3), (("X", "Y", "Z"), "km", 1e-3)],
)
def test_convertible_units_are_converted(path, obs, cols, unit, factor):
    """Issue 14 'correct input refused': x in mm, positions in km, t in ms are converted."""

    def f(t):
        for c in cols:
            t[c] = t[c] * factor
            t[c].unit = unit

    _edit_table(path, f)
    back = ObservationSet.read(path)
    for name in ("xy_m", "r_sc_i_m", "t_s", "landmark_g_m"):
        assert np.allclose(getattr(back, name), getattr(obs, name), rtol=1e-14, atol=0), name


@pytest.mark.parametrize("col, unit", [("x", "deg"), ("r_x", "s"), ("t", "m"), ("v_x", "m")])
def test_wrong_dimension_is_refused(path, col, unit):
    _edit_table(path, lambda t: setattr(t[col], "unit", unit))
    _refused(path, rf"column '{col}' has unit '{unit}', which is not convertible to '[^']+' \(wrong dimension\)")


@pytest.mark.parametrize("col", ["q1", "cgi12", "image", "run"])
def test_unit_on_a_unitless_column_is_refused(path, col):
    _edit_table(path, lambda t: setattr(t[col], "unit", "m"))
    _refused(path, rf"column '{col}' is unitless, got unit 'm'")


# ---------------------------------------------------------------------------- header


def test_duplicate_yaml_key_is_refused(path):
    text = path.read_text()
    text = text.replace("# - {focal_length_m: 2.2}", "# - {focal_length_m: 2.2}\n# - {focal_length_m: 22.0}", 1)
    assert "22.0" in text
    path.write_text(text)
    _refused(path, r"header line \d+: key 'focal_length_m' appears twice")


def test_duplicate_key_inside_a_metadata_mapping_is_refused(path):
    text = path.read_text()
    text = re.sub(r"(# - noise:\n(?:#.*\n)*?#     gnss: \{)", r"\1sigma_m: 1.0, ", text, count=1)
    path.write_text(text)
    _refused(path, r"key 'sigma_m' appears twice")


def test_duplicate_column_name_is_refused(path):
    text = path.read_text()
    header = next(ln for ln in text.splitlines() if not ln.startswith("#"))
    assert header.endswith(" x y")
    path.write_text(text.replace(header, header[:-1] + "x", 1).replace("name: y,", "name: x,", 1))
    _refused(path, r"column 'x' appears twice in the header line")


# ---------------------------------------------------------------------------- indices and landmarks


def test_huge_image_index_is_refused_before_allocating(path):
    """Issue 14: an image index of 10¹⁰ asked for 298 GiB."""
    _edit_table(path, lambda t: t["image"].__setitem__(5, 10**10))
    _refused(path, r"column 'image' row 5: index 10000000000 but the file has 80 rows")


def test_fractional_index_is_refused(path):
    def f(t):
        t["image"] = t["image"].astype(float)
        t["image"][3] = 3.75

    _edit_table(path, f)
    _refused(path, r"column 'image' row 3: index 3.75 is not a whole number")


def test_landmark_listed_but_never_seen_is_accepted(path, obs):
    _edit_table(path, lambda t: t.meta["landmark_order"].insert(1, "NEVER"))
    back = ObservationSet.read(path)
    assert back.landmark_ids.tolist() == obs.landmark_ids.tolist()


# ---------------------------------------------------------------------------- the simulator's own files


def test_simulate_never_writes_a_file_its_reader_refuses(tmp_path):
    """Issue 14: 7 of 20 000 simulated runs fell outside the 1 % field margin, and a never-seen
    landmark stayed in landmark_order. A grid wider than the field (some landmarks never seen) and
    σθ0 = 1800″ (points pushed across the field edge) over 12 runs: the file reads back."""
    sc = orbits.load_scenario(KALMAN20)
    grid = orbits.scenario.LandmarkSpec(layout="grid", n=6, half_width_km=30.0)
    sc = replace(sc, landmarks=grid, theta_true_arcsec=None, theta_sigma0_arcsec=1800.0)
    with pytest.warns(UserWarning, match="dropped from every run"):  # said, not silent
        obs = boresight.simulate(sc, np.random.default_rng(8), runs=12)
    raw = orbits.simulate_passes(sc, np.random.default_rng(8), runs=12)
    seen = np.bincount(obs.target_index, minlength=obs.n_targets) > 0
    assert (~seen).any(), "the test needs a never-seen landmark"
    assert obs.n_observations < raw.n_observations, "the test needs observations pushed beyond the field edge"
    back = ObservationSet.read(obs.write(tmp_path / "edge.ecsv"))
    assert back.landmark_ids.tolist() == obs.landmark_ids[seen].tolist()
    assert np.array_equal(back.xy_m, obs.xy_m) and np.array_equal(
        back.landmark_ids[back.target_index], obs.landmark_ids[obs.target_index]
    )


@pytest.mark.slow
def test_simulate_files_read_back_over_many_runs(tmp_path):
    """20 000 runs (200 seeds × 100 runs) across the field edge: every simulated set passes the
    shared geometry check (its constructor runs it) and every 20th seed's file reads back."""
    sc = orbits.load_scenario(KALMAN20)
    grid = orbits.scenario.LandmarkSpec(layout="grid", n=6, half_width_km=30.0)
    sc = replace(sc, landmarks=grid, theta_true_arcsec=None, theta_sigma0_arcsec=600.0)
    for seed in range(200):
        obs = boresight.simulate(sc, np.random.default_rng(seed), runs=100)
        obs = obs.images(obs.rows_per_image > 0)  # as `boresight simulate` does: an image seeing nothing has no row
        if seed % 20 == 0:
            back = ObservationSet.read(obs.write(tmp_path / f"s{seed}.ecsv", overwrite=True))
            assert back.n_observations == obs.n_observations


def test_simulate_cli_leaves_out_images_that_see_nothing(tmp_path, capsys):
    """A nadir image 300 s after the passage sees no landmark: `boresight simulate` says so and
    writes the other images; the file reads back (the writer refuses an empty image by name)."""
    from boresight.cli.main import main

    text = open(KALMAN20).read()
    text = text.replace('attitude = "site_tracking"', 'attitude = "nadir"').replace(
        "t_s = { start = 0.0, stop = 95.0, step = 5.0 }", "t_s = [0.0, 300.0]"
    )
    sc = tmp_path / "gap.toml"
    sc.write_text(text)
    assert main(["simulate", str(sc), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "not written   1 image(s) that saw no landmark in the field (t = [300.] s)" in out
    back = ObservationSet.read(next(tmp_path.glob("*.ecsv")))
    assert back.t_s.tolist() == [0.0]
    obs = boresight.simulate(sc, np.random.default_rng(0))
    with pytest.raises(ObservationError, match=r"x.ecsv: ObservationSet image 1 has no landmark observations"):
        obs.write(tmp_path / "x.ecsv")
