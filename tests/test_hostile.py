"""Hostile inputs of issue 23, one test per class (the fuzz, tests/test_fuzz.py, covers them at scale).

Each test builds the damaged input the issue names and asserts a refusal that names its culprit
(column and row, key, option, image or landmark), never a traceback or a confident answer.
"""

from __future__ import annotations

import contextlib
import copy
import io
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import orbits
from boresight.cli.main import main
from orbits.errors import BoresightError

ROOT = Path(__file__).resolve().parents[1]


def run_cli(argv):
    """(exit code, stdout, stderr) of ``boresight argv`` in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Simulated kalman20 files: one run and three runs (text)."""
    from boresight.observations.simulate import simulate

    d = tmp_path_factory.mktemp("hostile")
    out = {}
    for runs in (1, 3):
        p = d / f"k{runs}.ecsv"
        simulate(ROOT / "scenarios" / "kiev2012-kalman20.toml", np.random.default_rng(3), runs=runs).write(p)
        out[runs] = p
    return out


def mutate(src: Path, dst: Path, column: str, value: str, where=lambda cells, get: get("image") == "3") -> Path:
    """Copy ``src`` to ``dst`` with ``column`` set to ``value`` on the rows ``where`` selects."""
    lines = src.read_text().split("\n")
    head = next(i for i, ln in enumerate(lines) if ln and not ln.startswith("#"))
    names = lines[head].split(" ")
    for k in range(head + 1, len(lines)):
        if lines[k]:
            cells = lines[k].split(" ")
            if where(cells, lambda n, c=cells: c[names.index(n)]):
                cells[names.index(column)] = value
                lines[k] = " ".join(cells)
    dst.write_text("\n".join(lines))
    return dst


# ---------------------------------------------------------------------------- item 1: tracebacks, as a class

@pytest.mark.parametrize("column, value, runs, where", [
    ("r_y", "-1e308", 1, "image 3"),
    ("r_z", "1e308", 1, "image 3"),
    ("Y", "-1e308", 1, "landmark M2"),
    ("cgi12", "-1e308", 3, "run 2"),
    ("t", "1e308", 1, "image 3"),
    ("x", "-1e308", 1, "image 3"),
    ("q1", "1e308", 3, "run 2"),
    ("v_x", "1e300", 3, "run 2"),
])
def test_huge_value_in_any_column_and_run_is_refused_naming_column_and_row(files, tmp_path, column, value, runs, where):
    sel = {
        "image 3": lambda c, get: get("image") == "3",
        "landmark M2": lambda c, get: get("landmark") == "M2",
        "run 2": lambda c, get: get("run") == "2",
    }[where]
    f = mutate(files[runs], tmp_path / "bad.ecsv", column, value, sel)
    for cmd in ("estimate", "check"):
        code, _, err = run_cli([cmd, f])
        assert code == 1, (cmd, err)
        assert "Traceback" not in err and "Warning" not in err, err
        assert re.search(rf"column '{column}' row \d+: value .* is beyond", err), err


def test_cgi_that_differs_between_runs_is_refused(files, tmp_path):
    f = mutate(files[3], tmp_path / "bad.ecsv", "cgi12", "0.5", lambda c, get: get("run") == "2")
    code, _, err = run_cli(["estimate", f])
    assert code == 1 and "cgi11..cgi33' row" in err and "run 2" in err, err


def test_in_memory_set_has_the_same_bounds():
    from dataclasses import replace

    from boresight.observations.model import ObservationError
    from boresight.observations.simulate import simulate

    obs = simulate(ROOT / "scenarios" / "kiev2012-sensitivity.toml", np.random.default_rng(0), runs=1)
    r = obs.r_sc_i_m.copy()
    r[0, 0, 1] = -1e300
    with pytest.raises(ObservationError, match=r"r_sc_i_m: value -1e\+300 m at index \(0, 0, 1\) is beyond"):
        replace(obs, r_sc_i_m=r)


def test_diagnose_unknown_effect_is_a_usage_error_naming_the_option(files, tmp_path):
    code, _, err = run_cli(["diagnose", files[1], "--effects", "bogus_effect", "--out", tmp_path / "d"])
    assert code == 2 and "argument --effects: unknown effect(s) ['bogus_effect']" in err, err
    from boresight.studies.discrepancy.candidates import catalogue_candidates

    with pytest.raises(BoresightError, match="bogus"):  # the library refuses it too (was a KeyError)
        catalogue_candidates(["bogus"])


def _kalman20():
    return tomllib.loads((ROOT / "scenarios" / "kiev2012-kalman20.toml").read_text())


def test_scenario_whole_numbers_written_as_floats_are_accepted():
    d = _kalman20()
    d["passes"][0]["landmarks"] = {"layout": "random", "n": 6.0, "seed": 11.0, "half_width_km": 5.0}
    sc = orbits.scenario_from_dict(d, "x.toml")
    obs = orbits.simulate(sc, np.random.default_rng(0), runs=1)  # was a TypeError in numpy's generator
    d["passes"][0]["landmarks"]["seed"] = 11
    same = orbits.simulate(orbits.scenario_from_dict(d, "x.toml"), np.random.default_rng(0), runs=1)
    assert obs.xy_m.shape == (1, 20, 6, 2)
    np.testing.assert_array_equal(obs.landmark_g_m, same.landmark_g_m)


@pytest.mark.parametrize("where", ["top", "pass"])
def test_scenario_landmark_count_is_bounded(where):
    d = _kalman20()
    table = {"n": 2**62}
    if where == "top":
        d["landmarks"] = table
    else:
        d["passes"][0]["landmarks"] = copy.deepcopy(table)
    with pytest.raises(BoresightError, match=r"landmarks.? ?n = 4611686018427387904: must be ≤ 1000000"):
        orbits.scenario_from_dict(d, "x.toml")


# ---------------------------------------------------------------------------- item 2: options at parse time

@pytest.mark.parametrize("argv, option", [
    (["check", "F", "--max-rotation-deg", "nan"], "--max-rotation-deg"),
    (["check", "F", "--max-rotation-deg", "-1"], "--max-rotation-deg"),
    (["check", "F", "--max-images", "0"], "--max-images"),
    (["check", "F", "--max-images", "-3"], "--max-images"),
    (["diagnose", "F", "--max-steps", "-1", "--out", "o"], "--max-steps"),
    (["diagnose", "F", "--alpha", "1.5", "--out", "o"], "--alpha"),
    (["diagnose", "F", "--power", "nan", "--out", "o"], "--power"),
    (["simulate", "kiev2012-kalman20", "--seed", "-1"], "--seed"),
    (["estimate", "F", "--float", "bogus"], "--float"),
])
def test_invalid_options_are_refused_at_parse_time_naming_the_option(files, argv, option):
    argv = [files[1] if a == "F" else a for a in argv]
    code, out, err = run_cli(argv)
    assert code == 2, err
    assert f"argument {option}: must be" in err or f"argument {option}: unknown effect" in err, err
    assert out == "" and "Warning" not in err
