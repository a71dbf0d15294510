"""Issue 14: option and noise-model errors are one clean line naming what the user wrote, with no
Python warning on stderr (a warning leaking from a user-input path is a bug).

The CLI runs in-process: pytest turns a RuntimeWarning from boresight/orbits into an error
(pyproject ``filterwarnings``), which the CLI would report as an internal error (exit 70), and any
other warning is caught here."""

import re
import warnings

import numpy as np
import pytest
from paths import ROOT

from boresight import simulate


@pytest.fixture(scope="module")
def obs_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("msg") / "k20.ecsv"
    simulate(ROOT / "scenarios" / "kiev2012-kalman20.toml", np.random.default_rng(1)).write(path)
    return path


@pytest.fixture(autouse=True)
def _capsys(capsys):
    global _CAP
    _CAP = capsys
    yield


def run_cli(*argv):
    from boresight.cli import main as cli

    _CAP.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = cli.main([str(a) for a in argv])
    out, err = _CAP.readouterr()
    err += "".join(f"{w.category.__name__}: {w.message}\n" for w in caught)
    return code, out, err


def one_clean_line(err):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert not re.search(r"\w+Warning", err) and "Traceback" not in err, err
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("value", ["0", "1e-320", "-1", "nan", "inf"])
def test_prior_sigma_refused_in_one_line_without_a_warning(obs_file, value):
    code, _, err = run_cli("estimate", obs_file, "--sigma-prior-arcsec", value)
    assert code == 1
    assert one_clean_line(err).startswith(f"boresight estimate: error: --sigma-prior-arcsec {value}")


def test_a_huge_prior_is_no_prior_and_no_warning(obs_file):
    code, out, err = run_cli("estimate", obs_file, "--sigma-prior-arcsec", "1e300")
    assert code == 0 and not re.search(r"\w+Warning", err), err
    _, ref, _ = run_cli("estimate", obs_file)
    th = [ln for ln in out.splitlines() if ln.startswith("theta_")]
    assert th == [ln for ln in ref.splitlines() if ln.startswith("theta_")]


@pytest.mark.parametrize(
    "argv, expect",
    [
        (["--sigma-pixel-m", "-1"], "--sigma-pixel-m -1: must be a finite number ≥ 0"),
        (["--sigma-pixel-m", "5"], "--sigma-pixel-m 5: must be ≤ 1 m"),
        (["--sigma-pixel-m", "1e-300"], "--sigma-pixel-m 1e-300: must be 0 or ≥ 1e-100 m"),  # was a LinAlgError traceback
        (["--sigma-gnss-m", "nan"], "--sigma-gnss-m nan: must be a finite number ≥ 0"),
        (["--sigma-star-tracker-arcsec", "-1", "2", "3"], "--sigma-star-tracker-arcsec -1 2 3: must be 3 finite numbers ≥ 0"),
        (["--sigma-star-tracker-arcsec", "1e9"], "--sigma-star-tracker-arcsec 1e+09: must be ≤ 10°"),
        (["--sigma-catalogue-m", "-3"], "--sigma-catalogue-m -3: must be a finite number ≥ 0"),
    ],
)
def test_noise_model_options_named_as_written(obs_file, argv, expect):
    code, _, err = run_cli("estimate", obs_file, *argv)
    assert code == 1
    line = one_clean_line(err)
    assert expect in line and "DisturbanceModel" not in line, line


def test_noise_model_file_key_named_as_written(obs_file, tmp_path):
    text = obs_file.read_text()
    bad = tmp_path / "bad.ecsv"
    bad.write_text(re.sub(r"#     pixel: \{sigma_m: [^}]*\}", "#     pixel: {sigma_m: 5.0}", text))
    code, _, err = run_cli("estimate", bad)
    assert code == 1
    line = one_clean_line(err)
    assert f"{bad}: metadata 'noise'.pixel.sigma_m = 5.0: must be ≤ 1 m" in line, line


def test_sigma_pixel_px_named_as_written(flight_obs, tmp_path):
    """An invalid σK converted from --sigma-pixel-px names that option (not --sigma-pixel-m)."""
    pytest.importorskip("oem")
    pytest.importorskip("ccsds_ndm")
    from flight_camera import CAMERA

    from boresight.observations import flight as bio

    p = bio.export_flight_files(flight_obs, tmp_path, CAMERA)
    out = tmp_path / "px.ecsv"
    code, _, _ = run_cli(
        "ingest",
        "--oem",
        p["orbit"],
        "--aem",
        p["attitude"],
        "--landmarks",
        p["landmarks"],
        "--detections",
        p["detections"],
        "--camera",
        p["camera"],
        "--sigma-pixel-px",
        "0.5",
        "--sigma-star-tracker-arcsec",
        "4",
        "--out",
        out,
    )
    assert code == 0
    code, _, err = run_cli("estimate", out, "--sigma-pixel-px", "1e6")
    assert code == 1
    line = one_clean_line(err)
    assert "--sigma-pixel-px 1e+06 (= " in line and "must be ≤ 1 m" in line, line
