"""``boresight ingest --landmark-sight``: what a flight file's landmark rows carry, recorded in the file
(``docs/stars.md``, "One physics for star and landmark rows"; ``docs/data-format.md``, ``landmark_sight``).

The shipped ``flight-pass`` example is simulated with light time and aberration (``examples/make_flight_example.py``
projects through ``orbits.sight.apparent_sight_i``), so ingested with the default (``light_time+aberration``: flight
data are real light) it gives the tutorial's θ, and ingested ``--landmark-sight geometric`` its θ_y moves by the
aberration of its pass (778 km, ~7.5 km/s: measured +5.09″, θ_y −39.51″ → −34.42″).
"""

import pytest
from cli_argv import flight_pass_argv
from cli_run import run_cli

import boresight
from orbits.sight import LANDMARK_SIGHTS

SIGHT = "light_time+aberration"


def test_the_default_is_corrected_recorded_in_the_file_and_geometric_moves_theta_by_the_aberration(tmp_path):
    code, out, err = run_cli(flight_pass_argv(tmp_path / "corrected.ecsv"))
    assert code == 0, err
    assert f"landmark sight {SIGHT} (the default)" in out  # the terminal says which sight was applied
    text = (tmp_path / "corrected.ecsv").read_text()
    assert "format_version: '1.4'" in text and f"landmark_sight: {SIGHT}" in text
    code, out, err = run_cli(flight_pass_argv(tmp_path / "geometric.ecsv", "--landmark-sight", "geometric"))
    assert code == 0, err
    assert "landmark sight geometric (--landmark-sight)" in out
    assert "landmark_sight" not in (tmp_path / "geometric.ecsv").read_text()  # absent = geometric (format 1.4)
    geometric = boresight.ObservationSet.read(tmp_path / "geometric.ecsv")
    corrected = boresight.ObservationSet.read(tmp_path / "corrected.ecsv")
    assert geometric.landmark_sight == "geometric" and corrected.landmark_sight == SIGHT
    theta_corrected = boresight.estimate(corrected).theta.to_value("arcsec")
    shift = boresight.estimate(geometric).theta.to_value("arcsec") - theta_corrected
    assert 4.8 < shift[1] < 5.4 and abs(shift[0]) < 0.3 and abs(shift[2]) < 0.3, shift
    # read as it was simulated, the hidden θ = (25, −40, 60)″ is recovered as the geometric example was before its
    # regeneration: (24.78, −39.51, 56.69)″, within 1σ on x, y (0.90″) and 1.1σ on z (3.07″)
    assert abs(theta_corrected[1] + 40.0) < 0.9 and abs(theta_corrected[1] - shift[1] + 40.0) > 4.0, theta_corrected


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
