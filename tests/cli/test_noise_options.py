"""``boresight.cli.noise_options``: the table of noise-model override options is the function's own, and
``montecarlo`` on a scenario refuses each of them by that table."""

import argparse

import pytest

from boresight.cli import montecarlo
from boresight.cli.noise_options import OVERRIDE_OPTIONS, add_noise_model_args
from boresight.errors import StudyError


def test_the_override_table_names_every_option_the_function_adds():
    p = argparse.ArgumentParser(add_help=False)
    add_noise_model_args(p, scenario_help="a scenario")
    written = {s for a in p._actions for s in a.option_strings}
    assert set(OVERRIDE_OPTIONS.values()) == written - {"--scenario"}
    assert set(OVERRIDE_OPTIONS) == set(vars(p.parse_args([]))) - {"scenario"}
    assert "--sigma-pixel-px" in OVERRIDE_OPTIONS.values() and "--gnss-mode" in OVERRIDE_OPTIONS.values()


@pytest.mark.parametrize("option", ["--sigma-pixel-px", "--sigma-gnss-m", "--sigma-catalogue-m"])
def test_montecarlo_refuses_a_noise_override_with_a_scenario(tmp_path, option):
    p = argparse.ArgumentParser()
    montecarlo.register(p.add_subparsers())
    argv = ["montecarlo", "scenarios/kiev2012-sensitivity.toml", option, "2", "--runs", "10", "--out", str(tmp_path / "o")]
    args = p.parse_args(argv)
    with pytest.raises(StudyError, match=f"{option} applies to a study on an observation file"):
        args.func(args)
    assert not (tmp_path / "o").exists()
