"""``boresight montecarlo --weighting unit|diagonal|gls`` (``mc.montecarlo_study(weighting=)``).

Statistical tests use fixed seeds and the sampling distribution of a sample variance: with n runs
and the true σ, (n − 1) s²/σ² ~ χ²(n − 1), so s²/σ² lies in [χ²₀.₀₀₀₅, χ²₀.₉₉₉₅]/(n − 1)
(99.9 %): [0.899, 1.107] at n = 2000 — a factor of two in a variance (√2 in a σ) fails by far.
"""

from __future__ import annotations

import io
import json
import tomllib

import numpy as np
import pytest
from paths import ROOT
from scipy import stats

import orbits
from boresight import DisturbanceModel, estimate
from boresight.core.algorithms.batched import weighted_kernel
from boresight.errors import ObservabilityError, ResumeError, StudyError
from boresight.observations.model import from_measurements
from boresight.studies import montecarlo as mc
from boresight.studies.montecarlo.seeding import draw_block

K20 = ROOT / "scenarios/kiev2012-kalman20.toml"


def per_pass_doc(**over) -> dict:
    """docs/estimators.md's per-pass case as a scenario dict: the Algorithm 1 geometry with 4 images
    (t = 5..50 s), pixel 3 µm, GNSS 15 m and star tracker 4″ as per-pass biases, catalogue 1 m —
    where GLS beats unit weighting (also used by benchmarks/bench_montecarlo_weighting.py)."""
    with open(ROOT / "scenarios/kiev2012-algorithm1.toml", "rb") as fh:
        d = tomllib.load(fh)
    d["passes"][0]["t_s"] = [5.0, 20.0, 35.0, 50.0]
    d["pixel"] = {"sigma_m": 3e-6}
    d["gnss"] = {"sigma_m": 15.0, "error_mode": "per_pass"}
    d["star_tracker"] = {**d.get("star_tracker", {}), "sigma_arcsec": [4.0, 4.0, 4.0], "error_mode": "per_pass"}
    d["catalogue"] = {"sigma_m": 1.0}
    for k, v in over.items():
        d[k] = {**d.get(k, {}), **v}
    return d


def per_pass_scenario(**over):
    return orbits.scenario_from_dict(per_pass_doc(**over), source="per-pass.toml")


def variance_band(n, level=0.999):
    a = 0.5 * (1 - level)
    return stats.chi2.ppf([a, 1 - a], n - 1) / (n - 1)


@pytest.fixture(scope="module")
def per_pass_studies():
    sc = per_pass_scenario()
    return {
        w: mc.montecarlo_study(sc, ["image_plane"], runs=2000, seed=11, workers=1, weighting=w, image_counts=[4])
        for w in ("unit", "gls")
    }


def test_gls_study_sigma_agrees_with_the_reported_gls_sigma(per_pass_studies):
    r = per_pass_studies["gls"]
    s2 = r.sigma_arcsec("image_plane")[0] ** 2
    p2 = r.reported_sigma_arcsec("image_plane")[0] ** 2
    lo, hi = variance_band(r.runs)
    assert np.all((s2 / p2 > lo) & (s2 / p2 < hi)), (s2 / p2, lo, hi)
    assert int(r.unconverged["image_plane"][0]) == 0
    assert r.weighting == "gls" and r.inputs["weighting"] == "gls"


def test_gls_beats_unit_weighting_where_the_docs_say(per_pass_studies):
    """docs/estimators.md: with per-pass star-tracker and GNSS biases GLS beats unit weighting by a
    factor ≈ 3.4 in variance on θx, θy (the GNSS bias is separable through parallax); θz, seen by
    the landmarks' spread, gains little. Same draws for both (common random numbers)."""
    u, g = per_pass_studies["unit"], per_pass_studies["gls"]
    ratio = (u.sigma_arcsec("image_plane")[0] / g.sigma_arcsec("image_plane")[0]) ** 2
    assert np.all(ratio[:2] > 2.5) and np.all(ratio[:2] < 4.5), ratio
    assert 0.8 < ratio[2] < 1.3, ratio
    # and the unit study's own prediction (linear propagation) agrees with its sample σ
    lo, hi = variance_band(u.runs)
    q = u.sigma_arcsec("image_plane")[0] ** 2 / u.predicted["image_plane"][0] ** 2
    assert np.all((q > lo) & (q < hi)), q


def test_weighted_kernel_is_the_library_estimator_run_by_run():
    sc = orbits.load_scenario(K20)
    arrays = orbits.campaign_arrays(sc)
    obs = from_measurements(orbits.observe(draw_block(sc, arrays, 4, 0, 6), **arrays)).images(slice(0, 8))
    model = DisturbanceModel.from_scenario(sc)
    start = np.array([[3.0, -2.0, 5.0]]) + np.zeros((obs.runs, 1))  # the engine starts from the unit estimate
    for w, th0 in (("gls", None), ("diagonal", None), ("gls", start)):
        th, var, conv = weighted_kernel(obs, "image_plane", w, model, 2, max_iterations=30, theta0_arcsec=th0)
        assert conv.all()
        for k in range(obs.runs):
            ref = estimate(obs.run(k), "image_plane", weighting=w, model=model)
            assert np.abs(th[k] - ref.theta.to_value("arcsec")).max() < 2e-6
            np.testing.assert_allclose(var[k], ref.sigma.to_value("arcsec") ** 2, rtol=1e-6)


def test_weighted_study_is_chunk_and_worker_invariant():
    kw = dict(runs=40, seed=2, block_runs=16, weighting="gls", image_counts=[1, 20])
    rs = [
        mc.montecarlo_study(K20, ["image_plane", "unit_vector"], chunk_runs=c, workers=w, **kw)
        for c, w in ((40, 1), (7, 1), (5, 2))
    ]
    for r in rs[1:]:
        assert set(r.moments) == set(rs[0].moments) == {"image_plane", "image_plane#var", "unit_vector", "unit_vector#var"}
        assert all(r.moments[k] == rs[0].moments[k] for k in r.moments)


def test_weighted_study_counts_unconverged_runs():
    r = mc.montecarlo_study(
        per_pass_scenario(),
        ["image_plane"],
        runs=20,
        workers=1,
        weighting="gls",
        image_counts=[4],
        iterations=1,
        max_iterations=1,
    )
    assert int(r.unconverged["image_plane"][0]) == 20 and r.any_unconverged
    assert np.all(np.isfinite(r.sigma_arcsec("image_plane")))


def test_weighted_study_refusals():
    with pytest.raises(StudyError, match=r"weighting must be one of \['unit', 'diagonal', 'gls'\], got 'GLS'"):
        mc.montecarlo_study(K20, ["image_plane"], runs=10, workers=1, weighting="GLS")
    with pytest.raises(
        StudyError, match=r"per-pass\.toml: --weighting gls .* needs pixel noise \(\[pixel\] sigma_m > 0, got 0 m\)"
    ):
        mc.montecarlo_study(per_pass_scenario(pixel={"sigma_m": 0.0}), ["image_plane"], runs=10, workers=1, weighting="gls")
    sc = per_pass_scenario(landmarks={"layout": "explicit", "enu_km": [[1.0, 2.0, 0.0]]})
    with pytest.raises(ObservabilityError, match=r"per-pass\.toml: image_plane with the first 1 image\(s\): θ is not observable"):
        mc.montecarlo_study(sc, ["image_plane"], runs=10, workers=1, weighting="gls", image_counts=[1])


def test_resume_with_another_weighting_is_refused(tmp_path):
    ck = tmp_path / ".checkpoint"
    mc.montecarlo_study(
        K20, ["image_plane"], runs=4, block_runs=2, workers=1, image_counts=[2], checkpoint=ck
    )  # leaves its blocks
    with pytest.raises(ResumeError, match=r"\(--weighting unit → gls\)"):
        mc.montecarlo_study(
            K20, ["image_plane"], runs=4, block_runs=2, workers=1, image_counts=[2], checkpoint=ck, resume=True, weighting="gls"
        )
    # the same weighting resumes
    r = mc.montecarlo_study(K20, ["image_plane"], runs=4, block_runs=2, workers=1, image_counts=[2], checkpoint=ck, resume=True)
    assert r.resumed_blocks == 2


def _cli(argv):
    from cli_run import run_cli

    return run_cli(argv)


def test_cli_weighting_round_trip(tmp_path):
    out = tmp_path / "o"
    code, text, err = _cli(
        [
            "montecarlo",
            per_pass_scenario_file(tmp_path),
            "--runs",
            "30",
            "--seed",
            "3",
            "--workers",
            "1",
            "--weighting",
            "gls",
            "--algorithm",
            "image_plane",
            "--image-counts",
            "4",
            "--no-plots",
            "--quiet",
            "--out",
            out,
        ]
    )
    assert code == 0, err
    assert "least squares: GLS under the scenario's noise model" in text
    assert "predicted σ: the GLS covariance the estimator reports" in text
    meta = json.loads((out / "montecarlo.json").read_text())
    assert meta["weighting"] == "gls"
    from astropy.table import Table

    t = Table.read(out / "montecarlo.ecsv", format="ascii.ecsv")
    assert t.meta["weighting"] == "gls" and "sigma_reported" in t.meta["note"]
    r = mc.montecarlo_study(
        per_pass_scenario_file(tmp_path), ["image_plane"], runs=30, seed=3, workers=1, weighting="gls", image_counts=[4]
    )
    np.testing.assert_array_equal(np.asarray(t["sigma_reported_x"]), r.reported_sigma_arcsec("image_plane")[:, 0])
    np.testing.assert_array_equal(np.asarray(t["sigma_theta_y"]), r.sigma_arcsec("image_plane")[:, 1])
    assert max(len(line) for line in text.splitlines()) <= 100
    code, _, err = _cli(["montecarlo", K20, "--weighting", "optimal"])
    assert code == 2 and "invalid choice: 'optimal'" in err


def per_pass_scenario_file(tmp_path):
    from toml_writer import dumps

    p = tmp_path / "per-pass.toml"
    if not p.exists():
        p.write_text(dumps(per_pass_doc()))
    return p


def test_printed_lines_fit_100_columns():
    """Every line the study commands print (the pinned references of tests/project/test_public_outputs.py,
    which hold the whole stdout) is ≤ 100 columns, and long notes are folded, not cut."""
    from boresight.cli.montecarlo import WIDTH, wrap

    for f in (ROOT / "tests/reference_outputs").glob("montecarlo-*/stdout.txt"):
        lines = f.read_text().splitlines()
        assert max(len(line) for line in lines) <= WIDTH, (f, max(lines, key=len))
    note = "note: " + " ".join(f"word{k}" for k in range(80)) + " /a/very/long/path/" + "x" * 120
    folded = wrap(note).splitlines()
    assert " ".join(s.strip() for s in folded) == note  # nothing lost
    assert all(len(s) <= WIDTH for s in folded[:-1]) and folded[-1].strip().startswith("/a/very/long/path/")
    # the progress bar (stderr) shortens a long scenario label instead of overflowing
    buf = io.StringIO()
    bar = mc.ProgressBar(stream=buf, label="a-very-long-scenario-name-" * 4 + "(gls)")
    bar.t0 -= 12345.0
    bar(450, 45000)
    bar(45000, 45000)
    lines = buf.getvalue().replace("\r", "\n").split("\n")
    assert max(len(s) for s in lines) == WIDTH and all("…" in s for s in lines if s)


@pytest.mark.slow
def test_gls_study_on_the_20_image_kalman_scenario_matches_its_reported_sigma():
    """kiev2012-kalman20, 3000 runs, every image count: σθ within the 99.9 % χ² band of the mean
    reported GLS σ (18 comparisons: Bonferroni band at 99.99 %)."""
    r = mc.montecarlo_study(K20, ["image_plane"], runs=3000, seed=21, weighting="gls")
    q = r.sigma_arcsec("image_plane") ** 2 / r.reported_sigma_arcsec("image_plane") ** 2
    lo, hi = variance_band(r.runs, 0.9999)
    assert np.all((q > lo) & (q < hi)), q
    assert int(np.sum(r.unconverged["image_plane"])) == 0


def test_a_run_the_estimator_cannot_solve_is_a_study_error_naming_its_runs(monkeypatch):
    """A drawn run whose weighted normal matrix is singular stops the study with the run range (no NaN)."""
    from boresight.studies.montecarlo import chunks

    def singular(*a, **k):
        raise ObservabilityError("NormalEquations.solve: run 3: weak axis θz, condition number inf > 1e+08")

    monkeypatch.setattr(chunks, "weighted_kernel", singular)
    with pytest.raises(StudyError, match=r"gls weighting: θ is not determined in one of runs 0\.\.9 .* run 3: weak axis θz"):
        mc.montecarlo_study(per_pass_scenario(), ["image_plane"], runs=10, workers=1, weighting="gls", image_counts=[4])


def test_interrupted_gls_study_resumes_to_the_uninterrupted_result(tmp_path):
    kw = dict(runs=6, block_runs=2, chunk_runs=2, workers=1, image_counts=[2, 20], weighting="gls", seed=4)
    whole = mc.montecarlo_study(K20, ["image_plane"], **kw)
    ck = tmp_path / ".checkpoint"
    mc.montecarlo_study(K20, ["image_plane"], checkpoint=ck, **kw)
    (ck / "block-000000002.npz").unlink()  # the study was killed during its last block
    resumed = mc.montecarlo_study(K20, ["image_plane"], checkpoint=ck, resume=True, **kw)
    assert resumed.resumed_blocks == 2
    assert set(resumed.moments) == {"image_plane", "image_plane#var"}
    assert all(resumed.moments[k] == whole.moments[k] for k in whole.moments)


def test_memory_budget_counts_the_weighted_estimator(monkeypatch):
    """The GLS working set (measured, ~0.3 MB per 20-image run here) is in the budget: a chunk that
    fits unit-weighted is refused under GLS, naming the study and the remedy."""
    from orbits.limits import MemoryBudgetError

    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", "0.1")
    kw = dict(runs=1000, chunk_runs=1000, workers=1, image_counts=[20])
    with pytest.raises(
        MemoryBudgetError,
        match=r"the study \(--runs 1000, 80 observations per run, chunks of 1000 runs.*fewer runs, smaller --chunk-runs",
    ):
        mc.montecarlo_study(K20, ["image_plane"], weighting="gls", **kw)
    assert mc.montecarlo_study(K20, ["image_plane"], **kw).runs == 1000
