"""``boresight simulate``: summary on the terminal, an ECSV file that reads back."""

import numpy as np

from boresight import ObservationSet
from boresight.cli.main import main


def test_simulate_writes_a_file_that_reads_back(tmp_path, capsys):
    code = main(["simulate", "scenarios/kiev2012-sensitivity.toml", "--seed", "3", "--runs", "2", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "680 km" in out and "F = 2.2 m" in out and "4 observations per run" in out
    obs = ObservationSet.read(tmp_path / "kiev2012-sensitivity.ecsv")
    assert obs.runs == 2 and obs.n_images == 1 and obs.n_landmarks == 4
    assert np.all(np.abs(obs.truth["theta_rad"]) > 0)


def test_bad_scenario_path_is_an_error_not_a_traceback(tmp_path, capsys):
    code = main(["simulate", str(tmp_path / "nope.toml"), "--out", str(tmp_path)])
    assert code == 1
    assert "nope.toml" in capsys.readouterr().err
