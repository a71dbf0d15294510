"""The command line prints what the library returned (docs/architecture.md, "A command": "print what the library
decided ... never a second computation of it"): each printed statistic of the pushbroom commands is read from the
library's result here and found in the output, so a command that computes its own version of it fails."""

import re

import numpy as np

from boresight.cli.main import main


def test_pushbroom_estimate_prints_the_librarys_chi2_test(capsys, tmp_path):
    """``boresight estimate pushbroom-strip`` (seed 1, as the command simulates it) prints ``Estimate.chi2_text()`` of
    the same fit: the band at ``stats.CHI2_LEVEL`` and the verdict, as the frame estimate does (it printed a bare
    χ²/dof with neither); its ``--json`` carries the largest z as numbers (``Estimate.largest_residuals_json``: row,
    detection, z), which the printed ``largest z`` line renders."""
    import json

    import boresight
    from boresight.observations.strip import simulate_strip_scenario, strip_noise_model, strip_unknowns
    from orbits.strip import load_strip_scenario

    assert main(["estimate", "pushbroom-strip", "--json", str(tmp_path / "p.json")]) == 0
    out = capsys.readouterr().out
    sc = load_strip_scenario("pushbroom-strip")
    strips = simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(1)))
    est = boresight.estimate(strips, model=strip_noise_model(sc), unknowns=strip_unknowns(sc))
    assert f"chi2 / dof    {est.chi2_text()}" in out.splitlines(), out
    assert "expected" in est.chi2_text()
    whole = json.loads((tmp_path / "p.json").read_text())
    assert whole["chi2_test"] == json.loads(json.dumps(est.chi2_test_json())) and whole["chi2_test"]["outside"] is False
    assert whole["downweighted"] is None  # least squares: no loss
    doc = whole["largest_residuals"]
    assert doc == json.loads(json.dumps(est.largest_residuals_json())) and len(doc["observations"]) == 5
    z = np.sort(np.asarray(est.whitened_residual_norm))[::-1][:5]
    assert [o["z"] for o in doc["observations"]] == [float(v) for v in z]
    assert all(set(o) == {"row", "detection", "z"} for o in doc["observations"])
    shown = ", ".join(f"{o['detection']} {o['z']:.2f}" for o in doc["observations"][:3])
    assert f"largest z     {shown} (z: {doc['z_definition']})" in out.splitlines(), out
    # each unknown's error in σ is the study's (errors_in_sigma of the fit and the scenario's truth)
    from boresight.studies.montecarlo.line_scan import errors_in_sigma, truth_vector

    fit = est.algorithm_result
    e = errors_in_sigma(fit.x, fit.sigma, truth_vector(sc, fit.names))
    shown = [float(v) for v in re.findall(r"\(([+-]\d+\.\d+) σ\)", out)]
    assert shown == [round(float(v), 2) for v in e[np.isfinite(e)]], (shown, e)
    assert np.isnan(errors_in_sigma([1.0], [0.0], [0.5])[0]) and np.isnan(errors_in_sigma([1.0], [1.0], [np.nan])[0])


def test_pushbroom_montecarlo_prints_the_librarys_counts_and_intervals(capsys):
    """``boresight montecarlo pushbroom-strip``: the runs within 3σ and their 95 % interval are the study's
    (``LineScanMonteCarlo.count_within_3_sigma``, ``within_3_sigma_interval``: ``stats.binomial_interval``), not
    counts the command rebuilt from rounded fractions."""
    from boresight.studies.montecarlo.line_scan import line_scan_montecarlo
    from orbits.strip import load_strip_scenario

    assert main(["montecarlo", "pushbroom-strip", "--runs", "4", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    mc = line_scan_montecarlo(load_strip_scenario("pushbroom-strip"), 4, 3)
    lines = [ln for ln in out.splitlines() if "within 3σ" in ln]
    assert len(lines) == len(mc.names) == 3
    iv = mc.within_3_sigma_interval()
    for line, k, (lo, hi), rate in zip(lines, mc.count_within_3_sigma, iv, mc.within_3_sigma):
        assert f"within 3σ {k}/{mc.runs} ({100 * rate:.2f} %, 95 % interval {100 * lo:.2f}-{100 * hi:.2f} %)" in line, line
    assert np.array_equal(mc.count_within_3_sigma, np.sum(np.abs(mc.errors) <= 3 * mc.sigmas, axis=0))
    assert np.allclose(mc.within_3_sigma, mc.count_within_3_sigma / 4)


def test_down_weighted_means_one_thing_for_frames_and_lines(capsys):
    """ "Down-weighted" is the library's count (``Estimate.downweighted_count``: z above the loss's constant): for a frame
    fit it is the length of ``downweighted``; the pushbroom estimate prints it (it printed its own count of weights below
    0.5, which under Huber said 0 of 302 where the loss had down-weighted 11)."""
    from builders import simulate_with_model

    import boresight
    import orbits
    from boresight.observations.strip import simulate_strip_scenario, strip_noise_model, strip_unknowns
    from orbits.strip import load_strip_scenario

    obs, model = simulate_with_model(orbits.load_scenario("kiev2012-kalman20"), seed=3)
    est = boresight.estimate(obs, model=model, loss="huber")
    assert est.downweighted_count() == len(est.downweighted)
    assert boresight.estimate(obs, model=model).downweighted_count() is None
    assert main(["estimate", "pushbroom-strip", "--loss", "huber"]) == 0
    out = capsys.readouterr().out
    sc = load_strip_scenario("pushbroom-strip")
    strips = simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(1)))
    est = boresight.estimate(strips, model=strip_noise_model(sc), unknowns=strip_unknowns(sc), loss="huber")
    n = est.downweighted_count()
    assert n is not None and n > 0
    assert f": {n} of {np.size(est.whitened_residual_norm)} detections down-weighted (pixel-level z > " in out, out


def test_simulate_prints_the_librarys_descriptions_of_its_rows(capsys, tmp_path):
    """``boresight simulate`` prints the landmarks' range, the field angles and the star rows' own σ as the library
    returns them for the set it wrote (``ObservationSet.landmark_range_span_m``, ``field_angle_span_deg``,
    ``sigma_xy_span_m``; None: the line or its part is not printed); it computed them from the rows itself. The file
    read back gives the same printed digits: ``stars-and-landmarks`` (landmark rows with light time and aberration,
    star rows), ``star-calibration`` (star rows only, centroid σ by magnitude)."""
    from paths import ROOT

    import boresight

    for name in ("stars-and-landmarks", "star-calibration"):
        assert main(["simulate", str(ROOT / "scenarios" / f"{name}.toml"), "--out", str(tmp_path)]) == 0
        out = capsys.readouterr().out
        obs = boresight.ObservationSet.read(tmp_path / f"{name}.ecsv")
        span = obs.landmark_range_span_m()
        assert (span is None) == (name == "star-calibration")
        assert (span is None) == ("(range " not in out), out
        if span is not None:
            assert f"(range {span[0] / 1e3:.1f}..{span[1] / 1e3:.1f} km)" in out, out
            assert 500e3 < span[0] < span[1] < 700e3  # a 600 km orbit's nadir passes
        passes = [ln for ln in out.splitlines() if ln.startswith("pass ")]  # each pass's images: pass_time_span_s
        assert len(passes) == (3 if name == "stars-and-landmarks" else 0), out
        for k, line in enumerate(passes):
            t = obs.pass_time_span_s(k)
            assert line.endswith(f" t = {t[0]:g}..{t[1]:g} s"), (k, t, line)
        lo, hi = obs.field_angle_span_deg()
        assert f"field angles  {lo:.3f}..{hi:.3f} deg off the boresight" in out.splitlines(), out
        assert 0 <= lo < hi < 1.7 * 1.01 * 2**0.5  # inside the 3.4° field's corner, the reader's 1 % margin
        own = obs.sigma_xy_span_m()
        assert (own is None) == (name == "stars-and-landmarks") == ("star centroids by magnitude" not in out), out
        if own is not None:
            assert f"(star centroids by magnitude: {own[0] * 1e6:.3g}..{own[1] * 1e6:.3g} um, each row its own)" in out


def test_a_pushbroom_file_header_prints_the_librarys_line_span(capsys, tmp_path):
    """The pushbroom commands' file header prints the first and last measured line as ``ObservationSet.line_span``
    returns them (it took np.min/np.max of the lines itself); a frame set has none."""
    import boresight
    from boresight.observations.strip_file import read_strip_file

    assert main(["simulate", "pushbroom-strip", "--out", str(tmp_path)]) == 0
    (path,) = sorted(tmp_path.glob("*.ecsv"))
    assert main(["estimate", str(path)]) == 0
    out = capsys.readouterr().out
    lo, hi = read_strip_file(path).obs.line_span()
    assert f", lines {lo:.1f} … {hi:.1f}, " in out, out
    assert 0 <= lo < hi
    assert boresight.simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(0)).line_span() is None
