"""ObservationSet and its ECSV file: lossless round trip; every kind of bad file is named."""

import re

import numpy as np
import pytest
from astropy.table import Table
from observation_arrays import assert_same_arrays

import boresight
from boresight import ObservationError, ObservationFileError, ObservationSet


@pytest.fixture(scope="module")
def obs():
    return boresight.simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(11), runs=2)


@pytest.fixture()
def good_file(obs, tmp_path):
    return obs.write(tmp_path / "good.ecsv")


def test_write_read_is_lossless(obs, good_file):
    back = ObservationSet.read(good_file)
    assert_same_arrays(back, obs)  # bit for bit
    assert back.focal_length_m == obs.focal_length_m and back.fov_deg == obs.fov_deg
    assert np.array_equal(back.truth["theta_rad"], obs.truth["theta_rad"])
    units = {c: str(Table.read(good_file)[c].unit) for c in ("x", "r_x", "X", "t")}
    assert units == {"x": "m", "r_x": "m", "X": "m", "t": "s"}


def test_wgs84_file_without_earth_rotation_columns_uses_astropy(tmp_path):
    import orbits

    sc = orbits.load_scenario("scenarios/kiev2012-algorithm1.toml")
    from dataclasses import replace

    sc = replace(sc, earth_model="wgs84", epoch_utc="2020-06-01T12:00:00")
    obs = boresight.simulate(sc, np.random.default_rng(0))
    path = obs.write(tmp_path / "w.ecsv")
    t = Table.read(path)
    t.remove_columns([c for c in t.colnames if c.startswith("cgi")])
    t.write(path, overwrite=True)
    back = ObservationSet.read(path)
    assert np.abs(back.C_GI - obs.C_GI).max() < 1e-15
    assert back.frames == {"inertial": "GCRS", "earth_fixed": "ITRS"}


def _edit(path, fn):
    t = Table.read(path)
    t = fn(t) or t
    t.write(path, overwrite=True)
    return path


def test_missing_column(good_file):
    _edit(good_file, lambda t: t.remove_column("y"))
    with pytest.raises(ObservationFileError, match=r"missing required column 'y'"):
        ObservationSet.read(good_file)


def test_wrong_unit_dimension_is_refused(good_file):
    def f(t):
        t["x"].unit = "deg"

    _edit(good_file, f)
    with pytest.raises(
        ObservationFileError, match=r"column 'x' has unit 'deg', which is not convertible to 'm' \(wrong dimension\)"
    ):
        ObservationSet.read(good_file)


def test_nan_names_column_and_row(good_file):
    def f(t):
        t["X"][7] = np.nan

    _edit(good_file, f)
    with pytest.raises(ObservationFileError, match=r"column 'X' row 7: non-finite value nan"):
        ObservationSet.read(good_file)


def test_duplicate_observation(good_file):
    _edit(good_file, lambda t: t.add_row(t[3]))
    with pytest.raises(ObservationFileError, match=r"duplicate observation of landmark 'M4' in image 0 run 0 \(rows 3 and \d+\)"):
        ObservationSet.read(good_file)


def test_landmark_behind_the_camera(good_file):
    def f(t):
        sel = (t["landmark"] == "M2") & (t["run"] == 0)
        # lift M2 to three Earth radii, far above the spacecraft: behind a downward-looking camera
        for c in "XYZ":
            t[c][sel] = 3 * t[c][sel]

    _edit(good_file, f)
    with pytest.raises(ObservationFileError, match=r"row \d+: landmark 'M2' in image 0 is behind the camera"):
        ObservationSet.read(good_file)


def test_landmark_outside_the_field_of_view(good_file):
    def f(t):
        t["x"][5] = 0.5  # F = 1 m, 20° field: half-width 0.176 m

    _edit(good_file, f)
    with pytest.raises(
        ObservationFileError,
        match=r"column 'x' row 5: landmark 'M2' in image 1 is outside the field of view \(x = 0.5 m, half-width 0.176327 m",
    ):
        ObservationSet.read(good_file)


def test_inconsistent_image_rows(good_file):
    def f(t):
        t["q1"][1] = t["q1"][1] + 1e-3

    _edit(good_file, f)
    with pytest.raises(ObservationFileError, match=r"row 1: image 0 has differing values"):
        ObservationSet.read(good_file)


def test_bad_quaternion_norm(good_file):
    def f(t):
        sel = (t["image"] == 2) & (t["run"] == 1)
        for c in ("q1", "q2", "q3", "q4"):
            t[c][sel] = 2 * t[c][sel]

    _edit(good_file, f)
    with pytest.raises(ObservationFileError, match=r"quaternion norm 2, expected 1"):
        ObservationSet.read(good_file)


def test_not_an_observation_file(tmp_path):
    p = tmp_path / "other.ecsv"
    Table({"a": [1, 2]}).write(p)
    with pytest.raises(ObservationFileError, match=r"metadata 'format' must be 'boresight-observations', got None"):
        ObservationSet.read(p)
    q = tmp_path / "garbage.ecsv"
    q.write_text("# %ECSV 1.0\n# ---\n# datatype: [oops\nfoo\n")
    with pytest.raises(ObservationFileError, match=r"not a readable ECSV file"):
        ObservationSet.read(q)


def test_future_format_version_is_refused(good_file):
    def f(t):
        t.meta["format_version"] = "2.0"

    _edit(good_file, f)
    with pytest.raises(ObservationFileError, match=r"unsupported format_version '2.0'"):
        ObservationSet.read(good_file)


def test_constructor_validates_shapes_and_values(obs):
    from dataclasses import replace

    with pytest.raises(ObservationError, match=re.escape("ObservationSet.q_is: expected shape (2, 10, 4), got (2, 10, 3)")):
        replace(obs, q_is=obs.q_is[..., :3])
    bad = obs.xy_m.copy()
    bad[1, 3 * 4 + 2, 0] = np.nan  # run 1, image 3, landmark M3 (complete: row = 4 n + m)
    with pytest.raises(
        ObservationError, match=r"xy_m: non-finite value at index \(1, 14, 0\) \(run, row, axis: run 1, image 3, landmark 'M3'\)"
    ):
        replace(obs, xy_m=bad)
    with pytest.raises(ObservationError, match=r"duplicate id 'M1'"):
        replace(obs, landmark_ids=np.array(["M1", "M1", "M3", "M4"]))


@pytest.mark.parametrize("formatted", ["ecsv", "parquet"])
def test_target_ids_that_cannot_come_back_are_refused_before_writing(obs, tmp_path, formatted):
    """An id with spaces at an end, a line break, or empty was written and then refused by our own reader
    (astropy strips the spaces of a cell): the writer refuses it by name and writes nothing; ids with inner
    spaces, quotes, commas or '#' round-trip unchanged."""
    import dataclasses

    if formatted == "parquet":
        pytest.importorskip("pyarrow")
    for bad in ("  sp", "tr ", "a\nb", ""):
        ids = obs.landmark_ids.astype(object)
        ids[0] = bad
        odd = dataclasses.replace(obs, landmark_ids=ids.astype(str))
        path = tmp_path / f"bad.{formatted}"
        with pytest.raises(ObservationFileError, match=r"target id .* \(target 0\) cannot be written"):
            odd.write(path)
        assert not path.exists()
    ids = obs.landmark_ids.astype(object)
    ids[:4] = ["a b", 'q"t', "c,d", "#x"]
    fine = dataclasses.replace(obs, landmark_ids=ids.astype(str))
    back = ObservationSet.read(fine.write(tmp_path / f"fine.{formatted}"))
    assert list(back.landmark_ids[:4]) == ["a b", 'q"t', "c,d", "#x"]
