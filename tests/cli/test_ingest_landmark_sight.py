"""``boresight ingest --landmark-sight``: what a flight file's landmark rows carry, recorded in the file
(``docs/stars.md``, "One physics for star and landmark rows"; ``docs/data-format.md``, ``landmark_sight``).

The shipped ``flight-pass`` example was made with the geometric projection (``examples/make_flight_example.py``), so
ingested as geometric (the default) it gives the tutorial's θ, and ingested with light time and aberration its θ_y
moves by the aberration of its pass (778 km, ~7.5 km/s: measured −5.09″) — why the default is not flipped before the
examples are regenerated (``docs/stars.md``, "Still to do").
"""

import pytest
from cli_argv import flight_pass_argv
from cli_run import run_cli

import boresight
from orbits.sight import LANDMARK_SIGHTS

SIGHT = "light_time+aberration"


def test_the_option_is_recorded_in_the_file_and_moves_theta_by_the_aberration(tmp_path):
    code, out, err = run_cli(flight_pass_argv(tmp_path / "geometric.ecsv"))
    assert code == 0, err
    assert "landmark sight" not in out  # the default says nothing new: the tutorial's output is unchanged
    code, out, err = run_cli(flight_pass_argv(tmp_path / "corrected.ecsv", "--landmark-sight", SIGHT))
    assert code == 0, err
    assert f"landmark sight {SIGHT}" in out
    text = (tmp_path / "corrected.ecsv").read_text()
    assert "format_version: '1.4'" in text and f"landmark_sight: {SIGHT}" in text
    geometric = boresight.ObservationSet.read(tmp_path / "geometric.ecsv")
    corrected = boresight.ObservationSet.read(tmp_path / "corrected.ecsv")
    assert geometric.landmark_sight == "geometric" and corrected.landmark_sight == SIGHT
    shift = boresight.estimate(corrected).theta.to_value("arcsec") - boresight.estimate(geometric).theta.to_value("arcsec")
    assert -5.4 < shift[1] < -4.8 and abs(shift[0]) < 0.3 and abs(shift[2]) < 0.3, shift


def test_the_choices_are_the_libraries_and_other_inputs_refuse_the_option(tmp_path):
    """The command's choices are ``orbits.sight.LANDMARK_SIGHTS`` (written out there so ``--help`` loads no numpy);
    a value outside them is refused by argparse."""
    code, out, _ = run_cli(["ingest", "--help"])
    assert code == 0 and "--landmark-sight {" + ",".join(LANDMARK_SIGHTS) + "}" in " ".join(out.split()), out
    code, _, err = run_cli(flight_pass_argv(tmp_path / "x.ecsv", "--landmark-sight", "aberration"))
    assert code == 2 and "landmark-sight" in err
    assert not (tmp_path / "x.ecsv").exists()


@pytest.mark.parametrize("example", ["pushbroom-pass"])
def test_a_pushbroom_strip_refuses_it(example, tmp_path):
    code, _, err = run_cli(["ingest", "--example", example, "--out", tmp_path / "s.ecsv", "--landmark-sight", SIGHT])
    assert code != 0 and "--landmark-sight applies to a frame camera" in err, err
