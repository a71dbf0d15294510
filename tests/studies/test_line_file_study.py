"""``montecarlo FILE`` and ``sensitivity`` on a pushbroom file (``studies/montecarlo/line_scan.py``
``line_scan_file_study``, ``studies/sensitivity.py`` ``line_scan_sensitivities``): the resimulation's truth is the
file's own fit (a noise-free resimulation refits to it), the sensitivities' contributions add up to the GLS σ, the
finite differences agree with the linear propagation, and the commands print and write what they computed."""

import argparse
import json

import numpy as np
import pytest

from boresight.cli.main import main
from boresight.core.line_scan import LineScanUnknowns, estimate_line_scan
from boresight.observations.flight.shipped import example_dir
from boresight.observations.strip import line_noise_model
from boresight.studies.montecarlo.line_scan import resimulate_lines, true_lines
from boresight.studies.sensitivity import line_scan_sensitivities


@pytest.fixture(scope="module")
def strip_file(tmp_path_factory):
    """The tutorial's pushbroom file: ``ingest --example pushbroom-pass`` (0.3 px, 0.3″ per sample; the example's
    KVN files are read without the optional extras)."""
    out = tmp_path_factory.mktemp("pb") / "strip.ecsv"
    assert example_dir("pushbroom-pass").is_dir()
    args = ["ingest", "--example", "pushbroom-pass", "--sigma-pixel-px", "0.3", "--sigma-star-tracker-arcsec", "0.3"]
    assert main(args + ["--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def lines(strip_file):
    from boresight.cli.pushbroom_inputs import read_file

    return read_file(strip_file, argparse.Namespace())


def test_a_noise_free_resimulation_refits_to_the_files_own_fit(lines):
    """The truth of the resimulation is the fit: lines located at the fitted θ, δt and κ on the file's trajectory, then
    drawn with (almost) no noise, refit to the fitted values — to the inverse location's 1e-8-line floor (θ to 1e-6″;
    a resimulation about anything else, e.g. θ = 0, would be off by the 50″ of θ)."""
    sf, model, _ = lines
    unknowns = LineScanUnknowns(line_time_offset=True, focal_scale=True)
    base = estimate_line_scan(sf.obs, unknowns, model)
    L, p = true_lines(sf.obs, unknowns.parameters(base.x, 3))
    quiet = line_noise_model(1e-9, 0.0, sf.obs.line_scan.sensor.pixel_pitch_m)
    again = estimate_line_scan(resimulate_lines(sf.obs, L, p, quiet, np.random.default_rng(0)), unknowns, model)
    np.testing.assert_allclose(again.theta_arcsec, base.theta_arcsec, rtol=0, atol=1e-6)
    assert abs(again.x[3] - base.x[3]) < 1e-8 and abs(again.x[4] - base.x[4]) < 1e-10


def test_the_sources_contributions_add_up_to_the_gls_sigma_and_fd_agrees(lines):
    """Linear propagation through the GLS gain: pixel² + tracker² = σθ² (the optimal gain's split, to round-off:
    measured 5e-15); 40 resimulations with common random numbers (each σ doubled) agree with it within 4 of their own
    standard errors on every axis and source (the FD's SE is its per-run spread over √40)."""
    sf, model, unknowns = lines
    r = line_scan_sensitivities(sf.obs, unknowns, model, runs=40, seed=5)
    total = np.sqrt(r.contribution["pixel"] ** 2 + r.contribution["star_tracker"] ** 2)
    np.testing.assert_allclose(total, r.sigma_theta_arcsec, rtol=1e-10)
    np.testing.assert_allclose(r.share("pixel") + r.share("star_tracker"), 1.0, rtol=1e-10)
    for s in ("pixel", "star_tracker"):
        assert np.all(np.abs(r.fd_coef[s] - r.coef[s]) < 4 * r.fd_se[s]), (s, r.fd_coef[s], r.coef[s], r.fd_se[s])
    # the tracker holds θx and θy (0.3″ a sample), the pixels θz (the weak axis about the boresight)
    assert r.share("star_tracker")[0] > 0.9 and r.share("pixel")[2] > 0.9


def test_montecarlo_and_sensitivity_commands_on_the_file(strip_file, tmp_path, capsys):
    assert main(["montecarlo", str(strip_file), "--runs", "20", "--seed", "2", "-q"]) == 0
    out = capsys.readouterr().out
    assert "line_scan (gls weighting)" in out and "20 runs on the file's geometry" in out
    assert sum(ln.split()[0] in "xyz" for ln in out.splitlines() if ln[:2] in ("x ", "y ", "z ")) == 3
    assert main(["sensitivity", str(strip_file), "--runs", "0", "--out", str(tmp_path / "s")]) == 0
    out = capsys.readouterr().out
    assert "error budget" in out and "FD (" not in out
    doc = json.loads((tmp_path / "s" / "sensitivity.json").read_text())
    assert set(doc["sources"]) == {"pixel", "star_tracker"} and doc["sources"]["pixel"]["fd_coef"] is None


def test_montecarlo_names_a_line_file_s_unknowns_by_quantity(tmp_path, capsys):
    """A strip whose file floats line unknowns: ``montecarlo FILE`` lists them as the line estimate prints them
    (``line_time_offset``, ``chip1_along``: ``core.line_scan.quantity_and_unit``), not by their SI names."""
    assert main(["simulate", "pushbroom-campaign", "--out", str(tmp_path), "-q"]) == 0
    strip = sorted(tmp_path.glob("*.ecsv"))[0]
    capsys.readouterr()
    assert main(["montecarlo", str(strip), "--runs", "3", "--seed", "2", "-q"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("estimate"))
    floated = line.split("floated: ", 1)[1].split(":", 1)[0].split(", ")
    assert "line_time_offset" in floated and "chip1_along" in floated, line
    assert not any(n.endswith(("_rad", "_s", "_m")) for n in floated), line


@pytest.mark.slow
def test_montecarlo_file_sigma_is_honest_on_the_example(lines):
    """400 resimulations of the example strip: the reported σ within the 99.73 % χ² interval of the scatter on every
    axis (the interval at 400 runs spans about 0.91-1.11 × the scatter)."""
    from boresight.studies.montecarlo.file_study import file_study

    sf, model, unknowns = lines
    fs = file_study(sf.obs, model, runs=400, seed=20261127, unknowns=unknowns)
    assert fs.inside().all(), (fs.reported_sigma_arcsec, fs.sigma_arcsec, fs.interval())
