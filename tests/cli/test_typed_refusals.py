"""The command line's own refusals raise the typed ``InputValueError`` (exit 1, one line naming the option as the
user wrote it and its value); ``--traceback`` prints the exception's type, so each case checks both."""

import pytest
from paths import ROOT

from boresight.cli.main import main

FRAME = str(ROOT / "scenarios" / "kiev2012-kalman20.toml")


@pytest.mark.parametrize(
    "argv, named",
    [
        (["estimate", FRAME, "--max-iterations", "0"], "--max-iterations must be ≥ 1, got 0"),
        (["estimate", "pushbroom-campaign", "--join", FRAME], "--join merges frame-camera observation files; pushbroom-campaign"),
        (["estimate", FRAME, "--strip", FRAME], f"--strip applies to a pushbroom observation file; {FRAME} is not one"),
        (["estimate", "pushbroom-campaign", "--effects", "thermal"], "--effects thermal: a pushbroom fit floats"),
        (["estimate", "pushbroom-campaign", "--strip", FRAME], f"--strip {FRAME}: --strip adds pushbroom observation files"),
    ],
)
def test_estimate_option_refusals_are_typed(argv, named, capsys):
    assert main(argv + ["--traceback"]) == 1
    err = capsys.readouterr().err
    assert "orbits.errors.InputValueError: " in err, err
    assert named in err.splitlines()[-1], err
