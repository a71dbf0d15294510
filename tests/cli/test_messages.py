"""Honest mistakes (issue 22; 24 here, with the unit slip below): each answered by ONE error line that names what the user wrote and
the fix — the closest valid spelling, or the kind of file given and the command that takes it.

Every case runs the real command line in-process (``boresight.cli.main.main``) and checks the exit
code, that the error is a single line, and the words that name the culprit and the next step.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from paths import ROOT

from boresight.cli.main import main


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("mistakes")
    assert main(["simulate", "kiev2012-kalman20", "--seed", "1", "--runs", "1", "--out", str(d)]) == 0
    obs = d / "kiev2012-kalman20.ecsv"
    assert obs.exists()
    (d / "spreadsheet.csv").write_text("u_px,v_px,landmark\n512.3,400.1,M1\n130.0,77.5,M2\n")
    (d / "orbit.oem").write_text("CCSDS_OEM_VERS = 2.0\nCREATION_DATE = 2026-01-01T00:00:00\nORIGINATOR = X\n")
    scen = d / "my.toml"
    shutil.copy(ROOT / "scenarios" / "kiev2012-kalman20.toml", scen)
    text = scen.read_text()
    (d / "typo.toml").write_text(text.replace("sigma0_arcsec =", "sigma0_arcsecs =", 1))
    return {
        "obs": str(obs),
        "csv": str(d / "spreadsheet.csv"),
        "oem": str(d / "orbit.oem"),
        "toml": str(scen),
        "typo": str(d / "typo.toml"),
        "dir": d,
    }


#: (id, argv with {obs}/{csv}/… placeholders, exit code, words the error line must contain)
MISTAKES = [
    ("command typo", ["estimat", "{obs}"], 2, ["'estimat'", "did you mean 'estimate'"]),
    ("option typo", ["estimate", "{obs}", "--sigma-pixl", "3"], 2, ["--sigma-pixl 3", "did you mean '--sigma-pixel-m'"]),
    ("nested option typo", ["pointing", "sea-sky", "--outt", "x"], 2, ["--outt", "did you mean '--out'"]),
    ("nested command typo", ["pointing", "sea-skyy"], 2, ["'sea-skyy'", "did you mean 'sea-sky'"]),
    (
        "shipped name typo",
        ["simulate", "kiev2012-kalman2", "--out", "{dir}"],
        1,
        ["kiev2012-kalman2", "did you mean 'kiev2012-kalman20'"],
    ),
    (
        "algorithm typo",
        ["estimate", "{obs}", "--algorithm", "image_plan", "--out", "{dir}/e"],
        1,
        ["'image_plan'", "did you mean 'image_plane'"],
    ),
    ("CSV given to estimate", ["estimate", "{csv}"], 1, ["spreadsheet.csv", "CSV table", "boresight ingest --detections"]),
    ("scenario given to estimate", ["estimate", "{toml}"], 1, ["my.toml", "TOML", "boresight simulate"]),
    (
        "observation file given to simulate",
        ["simulate", "{obs}", "--out", "{dir}"],
        1,
        ["kiev2012-kalman20.ecsv", "observation file (ECSV)", "boresight estimate"],
    ),
    (
        "observation file given to sensitivity",
        ["sensitivity", "{obs}", "--out", "{dir}/s"],
        1,
        ["kiev2012-kalman20.ecsv", "observation file (ECSV)", "`montecarlo` (a study on its own geometry)"],
    ),
    ("observation file given to plan", ["plan", "{obs}", "--out", "{dir}/p"], 1, ["observation file (ECSV)", "not a plan file"]),
    ("CCSDS OEM given to check", ["check", "{oem}"], 1, ["orbit.oem", "OEM", "boresight ingest --oem"]),
    (
        "TOML key typo, table as written",
        ["simulate", "{typo}", "--out", "{dir}"],
        1,
        ["[misalignment]", "'sigma0_arcsecs'", "did you mean 'sigma0_arcsec'"],
    ),
    (
        "two star-tracker σ instead of 1 or 3",
        ["estimate", "{obs}", "--sigma-star-tracker-arcsec", "4", "4"],
        1,
        ["--sigma-star-tracker-arcsec", "1 or 3 values", "got 2"],
    ),
    (
        "a study of 0 runs",
        ["montecarlo", "kiev2012-sensitivity", "--runs", "0", "--out", "{dir}/mc"],
        1,
        ["--runs", "≥ 2", "got 0"],
    ),
    ("weighting typo", ["estimate", "{obs}", "--weighting", "gsl"], 2, ["'gsl'", "did you mean 'gls'"]),
    ("loss typo", ["estimate", "{obs}", "--loss", "hubber"], 2, ["'hubber'", "did you mean 'huber'"]),
    ("effect typo", ["estimate", "{obs}", "--effects", "time_tagg"], 2, ["--effects", "'time_tagg'", "did you mean 'time_tag'"]),
    (
        "montecarlo FILE: an effect typo, refused at parsing with the valid names",
        ["montecarlo", "{obs}", "--effects", "time_tag,focal_scal", "--runs", "4", "--out", "{dir}/mcf"],
        2,
        ["--effects", "'focal_scal'", "did you mean 'focal_scale'", "valid names"],
    ),
    (
        "an effect not in the catalogue",
        ["diagnose", "{obs}", "--candidates", "bogus_effect", "--out", "{dir}/d"],
        2,
        ["--candidates", "bogus_effect", "valid names"],
    ),
    ("zero images to check", ["check", "{obs}", "--max-images", "0"], 2, ["--max-images", "got '0'"]),
    ("shipped plan name typo", ["plan", "kiev68"], 1, ["kiev68", "did you mean 'kiev680'"]),
    ("a missing observation file", ["estimate", "{dir}/missing.ecsv"], 1, ["missing.ecsv", "no such observation file"]),
    ("negative runs", ["simulate", "kiev2012-kalman20", "--runs", "-1", "--out", "{dir}"], 1, ["--runs", "≥ 1", "got -1"]),
    ("document name typo", ["docs", "convention"], 1, ["'convention'", "did you mean 'conventions'"]),
    (
        "finite-difference step of 0",
        ["sensitivity", "kiev2012-sensitivity", "--rel-step", "0", "--out", "{dir}/s"],
        1,
        ["--rel-step", "got 0"],
    ),
    (
        "a robust loss for a non-least-squares algorithm",
        ["estimate", "{obs}", "--algorithm", "homography", "--loss", "huber"],
        1,
        ["--loss huber", "--algorithm homography", "image_plane"],
    ),
    (
        "floated effects for a non-least-squares algorithm",
        ["estimate", "{obs}", "--algorithm", "kalman", "--effects", "time_tag"],
        1,
        ["--effects time_tag", "--algorithm kalman", "image_plane"],
    ),
]


@pytest.mark.parametrize("argv, code, words", [m[1:] for m in MISTAKES], ids=[m[0] for m in MISTAKES])
def test_a_mistake_gets_one_line_naming_the_culprit_and_the_fix(files, capsys, argv, code, words):
    argv = [a.format(**files) for a in argv]
    try:
        got = main(argv)
    except SystemExit as exc:  # argparse
        got = exc.code
    err = capsys.readouterr().err
    assert got == code, err
    lines = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], f"{w!r} not in {lines[0]!r}"
    assert "loss='" not in err and "model=" not in err, "CLI text never gives Python syntax"


def test_a_unit_slip_is_warned_with_the_unit_that_fits(files, capsys, tmp_path):
    """0.0011″ for a star tracker is 0.0011° written in the wrong unit: a warning naming the option
    and the unit that fits; the run goes on (an unusual sensor is allowed)."""
    assert main(["estimate", files["obs"], "--sigma-star-tracker-arcsec", "0.0011", "--out", str(tmp_path / "e")]) == 0
    err = capsys.readouterr().err
    assert "warning: --sigma-star-tracker-arcsec: 0.0011 arcsec is 455× below" in err and "degrees = 3.96 arcsec" in err
    slip = tmp_path / "slip.toml"
    text = Path(files["toml"]).read_text()
    assert "sigma_m = 3e-6" in text
    slip.write_text(text.replace("sigma_m = 3e-6", "sigma_m = 0.05", 1))
    assert main(["simulate", str(slip), "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "[pixel] sigma_m: 0.05 m is 500× above" in err and "if it was in millimetres" in err


def test_shipped_scenarios_and_their_files_print_no_warning(capsys, tmp_path):
    import orbits

    for name in orbits.scenario_names():
        assert main(["simulate", name, "--seed", "1", "--out", str(tmp_path)]) == 0
        assert "warning" not in capsys.readouterr().err.lower(), name


def test_check_writes_its_verdict_as_json(files, tmp_path, capsys):
    import json

    assert main(["check", files["obs"], "--json", str(tmp_path / "c.json")]) == 0
    doc = json.loads((tmp_path / "c.json").read_text())
    rms = doc["rms_residual_m"]
    assert doc["verdict"] == "conventions_fit"
    # the declared conventions fit best (a symmetric mount makes 'mount_transposed' tie, to round-off)
    assert rms["declared"] <= (1 + 1e-9) * min(v for k, v in rms.items() if k != "declared")
    assert rms["x_mirrored"] > 100 * rms["declared"]
