"""Issue 31: the last wrong answers and misleading messages of the command line — noise-free input
(class 8), degree-for-arcsecond slips (class 9), messages naming their culprit (class 5) and a
missing optional library (class 7). Each test failed on the main of 2026-11-27."""

from __future__ import annotations

import numpy as np
import pytest
from cli_run import run_cli

import boresight


def _simulated(tmp_path_factory, scenario: str):
    """``boresight simulate SCENARIO`` into a fresh folder: the file it writes."""
    folder = tmp_path_factory.mktemp(scenario)
    code, out, err = run_cli(["simulate", scenario, "--out", folder])
    assert code == 0, err
    return folder / f"{scenario}.ecsv"


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory):
    """``boresight simulate kiev2012-algorithm1``: every σ of the scenario zero (its truth is exact)."""
    return _simulated(tmp_path_factory, "kiev2012-algorithm1")


def test_noise_free_input_says_residuals_at_round_off_and_sigma_not_meaningful(noise_free):
    """Class 8: a noise-free file printed ``nanσ``, "σ from the residual scatter; from the file's
    noise model", a warning about a ``--weighting unit`` never given and ``-0.24 -4.31 -0.45 σ``
    for a zero error. Now one plain sentence: the residuals are at round-off, σ is not meaningful."""
    code, out, err = run_cli(["estimate", noise_free])
    assert code == 0, err
    assert "nan" not in out, out
    assert "round-off" in out and "not meaningful" in out, out
    assert "--weighting unit" not in out and "from the file's noise model" not in out, out
    truth = next(line for line in out.splitlines() if line.startswith("truth"))
    assert not truth.rstrip().endswith(" σ"), truth
    # the library says it too
    obs = boresight.ObservationSet.read(noise_free)
    est = boresight.estimate(obs)
    assert est.noise_free is True
    assert "not meaningful" in est.sigma_includes
    assert any("round-off" in w for w in est.warnings) and not any("NOT used" in w for w in est.warnings)
    assert est.largest_residuals_json()["meaningful"] is False  # estimate --json's largest_residuals says so too
    assert est.largest_residuals_text().startswith("not meaningful")
    # a noisy file is not called noise-free
    noisy = boresight.simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(3))
    assert not boresight.estimate(noisy).noise_free


@pytest.fixture(scope="module")
def kalman20(tmp_path_factory):
    return _simulated(tmp_path_factory, "kiev2012-kalman20")


def test_a_degree_for_arcsecond_slip_is_the_first_cause_named(kalman20):
    """Class 9: ``--sigma-star-tracker-arcsec 0.0011`` (4″ written in degrees) made χ²/dof = 261,
    and the χ² warning said "outliers? a robust loss" while the unit warning came on stderr only.
    Now the χ² line names the unit slip as its most likely cause, the first warning on stdout is
    the slip, and "outliers" is not suggested before it."""
    code, out, err = run_cli(["estimate", kalman20, "--sigma-star-tracker-arcsec", "0.0011", "--sigma-gnss-m", "0.015"])
    assert code == 0, err
    chi2 = out[out.index("chi2 / dof") : out.index("condition")]
    assert "OUTSIDE" in chi2 and "degrees" in chi2, chi2
    first = out.split("\nwarning")[1]  # the first warning, wrapped lines included
    assert "degrees" in first, out
    assert "outliers?" not in out, out
    # the library says it as well
    obs = boresight.ObservationSet.read(kalman20)
    model = boresight.DisturbanceModel.from_observations(obs)
    from dataclasses import replace

    from orbits.rotations import ARCSEC

    slipped = replace(model, sigma_star_tracker_rad=np.full(3, 0.0011 * ARCSEC), sigma_gnss_m=0.015)
    for algorithm in ("image_plane", "kalman"):
        est = boresight.estimate(obs, algorithm=algorithm, model=slipped)
        assert "degrees" in est.warnings[0] and "degrees" in est.chi2_text(), (algorithm, est.warnings)


# ---------------------------------------------------------------------------- class 5: messages naming the culprit


def test_a_file_size_limit_names_the_path_and_the_option(kalman20, tmp_path):
    """``[Errno 27] File too large`` came with no path (the write's OSError carried none)."""
    import subprocess
    import sys

    from paths import ROOT

    code = (
        "import resource, sys; resource.setrlimit(resource.RLIMIT_FSIZE, (4000, 4000))\n"
        "from boresight.cli.main import main; sys.exit(main(sys.argv[1:]))"
    )
    out = tmp_path / "big"
    r = subprocess.run(
        [sys.executable, "-c", code, "estimate", str(kalman20), "--out", str(out), "--no-plots"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1, r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert "File too large" in line and str(out) in line and "--out" in line, line
    assert not [p for p in out.iterdir() if ".tmp-" in p.name], list(out.iterdir())


def test_ingest_names_out_when_it_cannot_write(tmp_path):
    """An unwritable ``--out`` named a temporary file (``.pass.tmp-123.ecsv``), not ``--out``; a
    ``--out`` under a file is refused before the inputs are read."""
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    code, out, err = run_cli(["ingest", "--example", "flight-pass", "--out", blocker / "pass.ecsv"])
    assert code == 1 and "--out" in err and str(blocker) in err and ".tmp-" not in err, err
    assert "orbit" not in out, out  # refused before any work
    code, out, err = run_cli(["ingest", "--example", "flight-pass", "--out", tmp_path])  # a folder
    assert code == 1 and "--out" in err and ".tmp-" not in err, err


def test_plan_exit_5_names_the_requirement_no_campaign_meets(tmp_path):
    """``plan`` exit 5 said "no campaign meets every requirement" and never which one."""
    from paths import ROOT

    text = (
        (ROOT / "plans" / "kiev680.toml")
        .read_text()
        .replace("sigma_theta_arcsec = [3.5, 3.5, 3.5]", "sigma_theta_arcsec = [0.01, 0.01, 0.01]")
    )
    plan = tmp_path / "tight.toml"
    plan.write_text(text)
    code, out, err = run_cli(["plan", plan, "--out", tmp_path / "p", "--no-plots", "--quiet"])
    assert code == 5, err
    assert "sigma_theta_arcsec" in out + err and "0.01" in out + err, out + err


def test_an_empty_ecsv_is_refused_without_a_misleading_directory_error(tmp_path):
    empty = tmp_path / "empty.ecsv"
    empty.write_text("")
    code, out, err = run_cli(["estimate", empty])
    assert code == 1 and str(empty) in err and "empty" in err and "IsADirectoryError" not in err, err


def test_out_pointing_at_a_file_is_refused_before_any_work_is_printed(kalman20, tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    for argv in (
        ["estimate", kalman20, "--out", blocker],
        ["diagnose", kalman20, "--out", blocker],
        ["plan", "kiev680", "--out", blocker, "--no-plots"],
        ["pointing", "sea-sky", "--out", blocker],
    ):
        code, out, err = run_cli(argv)
        assert code == 1 and "--out" in err and str(blocker) in err, (argv, err)
        assert out.strip() == "", (argv, out)


def test_json_dash_writes_the_json_alone_on_standard_output(kalman20, tmp_path, monkeypatch):
    """``--json -`` wrote a file named ``-``; now the JSON document alone goes to standard output
    (the command's other lines to standard error), wherever ``--json`` exists."""
    import json

    monkeypatch.chdir(tmp_path)
    for argv, key in (
        (["estimate", kalman20, "--json", "-"], "theta_arcsec"),
        (["check", kalman20, "--json", "-"], "verdict"),
        (["pointing", "sea-sky", "--out", tmp_path / "sea", "--no-plots", "--json", "-"], None),
    ):
        code, out, err = run_cli(argv)
        assert code == 0, (argv, err)
        doc = json.loads(out)
        assert key is None or key in doc, (argv, sorted(doc))
        assert not (tmp_path / "-").exists()
