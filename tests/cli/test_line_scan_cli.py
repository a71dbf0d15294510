"""``boresight simulate``, ``estimate`` and ``diagnose`` on a pushbroom scenario (each command's run_pushbroom, boresight/cli/pushbroom_inputs.py): the
strips' detection tables written, θ and the scenario's unknowns printed with σ and the truth, the line-scanner effects
named; the frame scenarios' route is untouched (their own tests)."""

from astropy.table import Table

from boresight.cli.main import main


def test_simulate_writes_each_strips_detections(tmp_path, capsys):
    assert main(["simulate", "pushbroom-strip", "--seed", "2", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "strip 0" in out and "tracker samples at 4 Hz" in out and "warning" not in out.lower()
    t = Table.read(tmp_path / "pushbroom-strip.strip0.ecsv", format="ascii.ecsv")
    assert {"gcp", "chip", "line", "pixel", "x_g_m"} <= set(t.colnames) and len(t) >= 300 and t.meta["seed"] == 2


def test_estimate_prints_theta_and_the_campaigns_unknowns_against_the_truth(capsys, tmp_path):
    """pushbroom-campaign: θ, δt, κ and chip 1's offsets, each within 4σ of the truth (seed 1; a wrong σ or a
    wrong model would show as tens of σ), the library's χ²/dof test printed as the frame estimate prints it."""
    import json
    import re

    assert main(["estimate", "pushbroom-campaign", "--json", str(tmp_path / "e.json")]) == 0
    out = capsys.readouterr().out
    for name in ("theta_x", "line_time_offset", "focal_scale", "chip1_across"):  # printed without the SI suffix
        assert f"\n  {name} " in out
    assert re.search(
        r"^chi2 / dof    1\.\d{3} \(\d+\.?\d* / 1611\) under the noise model; expected 0\.\d+\.\.1\.\d+", out, re.M
    ), out
    z = [float(v) for v in re.findall(r"\(([+-]\d+\.\d+) σ\)", out)]
    assert len(z) == 7 and max(abs(v) for v in z) < 4
    doc = json.loads((tmp_path / "e.json").read_text())
    assert doc["names"][3] == "line_time_offset_s" and len(doc["sigma"]) == 7
    # θ also under the frame estimate.json's keys, in arcsec: the same numbers as the SI unknowns
    import numpy as np

    arcsec = np.pi / 180 / 3600
    np.testing.assert_allclose(doc["theta_arcsec"], np.array(doc["x"][:3]) / arcsec, rtol=1e-12)
    np.testing.assert_allclose(doc["covariance_arcsec2"], np.array(doc["covariance"])[:3, :3] / arcsec**2, rtol=1e-12)


def test_diagnose_names_nothing_on_the_clean_strip(capsys, tmp_path):
    import json

    assert main(["diagnose", "pushbroom-strip", "--seed", "3", "--out", str(tmp_path / "d")]) == 0
    out = capsys.readouterr().out
    assert "named: nothing" in out and "jitter" in out and "chip_offset[1]" in out
    doc = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert doc["strips"][0]["named"] == [] and len(doc["strips"][0]["candidates"]) == 7
    assert "named: nothing" in (tmp_path / "d" / "diagnosis.md").read_text()


def test_montecarlo_on_a_pushbroom_scenario_is_the_slow_tests_loop(capsys):
    """``boresight montecarlo pushbroom-strip`` (``studies.montecarlo.line_scan``) draws run k from
    ``default_rng([seed, k])`` as ``tests/studies/test_pushbroom_mc.py`` does: its first runs' errors equal that test's
    loop bit for bit; the command prints σ / scatter and the 3σ rate with its interval per unknown."""
    import numpy as np

    from boresight.core.line_scan import estimate_line_scan
    from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns
    from boresight.studies.montecarlo.line_scan import line_scan_montecarlo
    from orbits.strip import load_strip_scenario, simulate_strip

    sc = load_strip_scenario("pushbroom-strip")
    mc = line_scan_montecarlo(sc, 3, 20261127)
    (geo,) = sc.geometries()
    for k in range(3):
        sim = simulate_strip(geo, sc.truth(), np.random.default_rng([20261127, k]), sc.layout, sc.tracker, sc.sigma_pixel_px)
        fit = estimate_line_scan(strip_observations(sim), strip_unknowns(sc), strip_noise_model(sc))
        assert np.array_equal(mc.errors[k], fit.x[:3] - sc.truth().theta_rad)
    assert main(["montecarlo", "pushbroom-strip", "--runs", "4", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert out.count("σ / scatter") == 3 and "within 3σ" in out and "95 % interval" in out


def test_plan_scores_every_subset_of_a_campaigns_strips(capsys):
    """``boresight plan pushbroom-campaign``: 15 subsets of 4 strips, the best of each size marked; one strip leaves
    the line-time offset tied to the pitch (corr > 0.9999, σθ > 10″), strips at different rolls separate them."""
    from boresight.studies.planning.line_scan import plan_strips
    from orbits.strip import load_strip_scenario

    subsets = plan_strips(load_strip_scenario("pushbroom-campaign"))
    assert len(subsets) == 15 and sum(g.best for g in subsets) == 4
    one, allfour = [g for g in subsets if len(g.strips) == 1], subsets[-1]
    assert all(g.corr_pitch_time > 0.9999 and g.worst_theta_arcsec > 10 for g in one)
    assert allfour.corr_pitch_time < 0.998 and allfour.worst_theta_arcsec < 1
    assert main(["plan", "pushbroom-campaign"]) == 0
    assert "the best subset of its size" in capsys.readouterr().out


def test_a_campaigns_strip_files_estimate_as_the_scenario_does(tmp_path, capsys):
    """``simulate pushbroom-campaign`` writes one pushbroom file per strip; ``estimate strip0.ecsv --strip … ×3`` fits
    them as one campaign (θ, δt, κ and chip 1's offsets common, the file's ``estimate`` unknowns) and gives the
    scenario's estimate (the same draw, seed 1): equal to 1e-12 relative (the files hold every digit)."""
    import json

    import numpy as np

    assert main(["simulate", "pushbroom-campaign", "--out", str(tmp_path)]) == 0
    files = [str(tmp_path / f"pushbroom-campaign.strip{k}.ecsv") for k in range(4)]
    argv = ["estimate", files[0]] + [a for f in files[1:] for a in ("--strip", f)]
    assert main(argv + ["--json", str(tmp_path / "f.json")]) == 0
    assert main(["estimate", "pushbroom-campaign", "--json", str(tmp_path / "s.json")]) == 0
    capsys.readouterr()
    f, s = (json.loads((tmp_path / n).read_text()) for n in ("f.json", "s.json"))
    assert f["names"] == s["names"] and len(f["names"]) == 7
    np.testing.assert_allclose(f["x"], s["x"], rtol=1e-12)
    np.testing.assert_allclose(f["sigma"], s["sigma"], rtol=1e-12)
    assert main(["estimate", "pushbroom-campaign", "--strip", files[1]]) == 1
    assert "--strip adds pushbroom observation files to a file" in capsys.readouterr().err
    # montecarlo FILE and sensitivity take the campaign too (strips 0 and 3: rolls -25° and +30°)
    assert main(["montecarlo", files[0], "--strip", files[3], "--runs", "3", "-q"]) == 0
    assert "and 1 more strip file(s)" in capsys.readouterr().out
    assert main(["sensitivity", files[0], "--strip", files[3], "--runs", "0", "--out", str(tmp_path / "s")]) == 0
    doc = json.loads((tmp_path / "s" / "sensitivity.json").read_text())
    total = np.hypot(doc["sources"]["pixel"]["contribution_arcsec"], doc["sources"]["star_tracker"]["contribution_arcsec"])
    np.testing.assert_allclose(total, doc["sigma_theta_arcsec"], rtol=1e-10)


def test_estimate_on_a_pushbroom_scenario_takes_a_robust_loss_and_refuses_frame_options(capsys):
    """``boresight estimate PUSHBROOM --loss huber`` goes to ``boresight.estimate(strips, loss=…)`` (the registry's
    line_scan row) and says so (it was silently ignored before); a frame algorithm or ``--effects`` is refused by name."""
    from cli_run import run_cli

    assert main(["estimate", "pushbroom-strip", "--loss", "huber"]) == 0
    out = capsys.readouterr().out
    assert "loss          huber (iteratively reweighted; σ the M-estimator sandwich)" in out and "\n  theta_x " in out
    code, _, err = run_cli(["estimate", "pushbroom-strip", "--algorithm", "alg2"])
    assert code != 0 and "estimated by 'line_scan'" in err
    code, _, err = run_cli(["estimate", "pushbroom-strip", "--effects", "focal_scale"])
    assert code != 0 and "[estimate] table" in err
