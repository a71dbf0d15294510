"""Eq 28 sensitivities: FD Monte Carlo (common random numbers) vs linear propagation vs CRLB."""

from __future__ import annotations

import json

import numpy as np
import pytest

import orbits
from boresight.core.crlb import cramer_rao_bound
from boresight.core.disturbances import DisturbanceModel
from boresight.reproductions.kiev2012.published import SEMINAR_EQ28
from boresight.studies import sensitivity as se

SENS = "scenarios/kiev2012-sensitivity.toml"


@pytest.fixture(scope="module")
def study():
    return se.sensitivity_study(SENS, ["image_plane", "unit_vector"], runs=6000, seed=3, workers=1)


def test_fd_and_analytic_agree_within_monte_carlo_uncertainty(study):
    """|FD − analytic| ≤ 4 SE for every source and axis (SE from the per-run spread of e²_scaled − e²_base)."""
    for name in ("image_plane", "unit_vector"):
        fd = study.fd[study.fd["algorithm"] == name]
        lin = study.linear[study.linear["algorithm"] == name]
        for s in se.SOURCES:
            f = fd[fd["source"] == s][0]
            a = lin[lin["source"] == s][0]
            for ax in "xyz":
                tol = 4.0 * f[f"coef_se_{ax}"] + 1e-9 * abs(a[f"coef_{ax}"])
                assert abs(f[f"coef_{ax}"] - a[f"coef_{ax}"]) <= tol, (name, s, ax, f[f"coef_{ax}"], a[f"coef_{ax}"], tol)
        assert study.agreement[name] < 4.0


def test_linear_contributions_add_up_to_monte_carlo_sigma(study):
    """σθ from linear propagation inside the χ² interval of the Monte Carlo σθ."""
    from boresight.studies.montecarlo import sigma_interval

    mo = study.mc.moments["image_plane"]
    lo, hi = sigma_interval(mo.std[0], mo.count, 0.9973)
    lin = np.array(study.linear.meta["sigma_theta_arcsec"]["image_plane"][:3])
    assert np.all((lo < lin) & (lin < hi)), (lo, lin, hi)


def test_crlb_matches_crlb_module_and_bounds_the_algorithms():
    t = se.linear_sensitivities(SENS, ["image_plane", "ground_plane"])
    crlb = np.array(t.meta["crlb_sigma_arcsec"][:3])
    sc = orbits.load_scenario(SENS)
    from boresight.studies.montecarlo import nominal_observations

    ref = np.sqrt(np.diag(cramer_rao_bound(nominal_observations(sc), DisturbanceModel.from_scenario(sc)).value))
    np.testing.assert_allclose(crlb, ref, rtol=1e-8)
    for name in ("image_plane", "ground_plane"):
        assert np.all(np.array(t.meta["sigma_theta_arcsec"][name][:3]) >= crlb * (1 - 1e-9))


def test_one_image_star_tracker_rows_have_unit_norm_like_the_seminar():
    """One image: a star-tracker error is a rotation of the camera frame, a_βj = |C_SK column j|."""
    t = se.linear_sensitivities(SENS, ["image_plane"])
    for s in ("beta1", "beta2", "beta3"):
        row = t[(t["algorithm"] == "image_plane") & (t["source"] == s)][0]
        assert abs(row["coef_norm"] - 1.0) < 1e-3
        sem = SEMINAR_EQ28[s]
        np.testing.assert_allclose([row["coef_x"], row["coef_y"], row["coef_z"]], sem[:3], atol=0.01)


def test_error_budget_shares_sum_to_one():
    b = se.error_budget(se.linear_sensitivities(SENS, ["image_plane"]))
    for ax in "xyz":
        assert abs(sum(b[f"share_{ax}"][:6]) - 1.0) < 1e-12


def test_scaled_scenario_and_bad_source():
    sc = se.scaled_scenario(SENS, "K", 2.0)
    assert sc.sigma_pixel_m == 6e-6
    with pytest.raises(ValueError, match="unknown disturbance source .Q.; expected one of"):
        se.scaled_scenario(SENS, "Q", 2.0)
    with pytest.raises(ValueError, match="rel_step must be"):
        se.fd_sensitivities(SENS, ["image_plane"], runs=10, rel_step=0.0)


def test_cli_sensitivity(tmp_path, capsys):
    from boresight.cli.main import main

    rc = main(
        [
            "sensitivity",
            SENS,
            "--runs",
            "2000",
            "--algorithm",
            "image_plane",
            "--out",
            str(tmp_path),
            "--workers",
            "1",
            "--quiet",
            "--no-plots",
        ]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "seminar" in out and "error budget" in out
    meta = json.loads((tmp_path / "sensitivity.json").read_text())
    assert meta["runs"] == 2000 and set(meta["variants"]) == set(se.SOURCES)
    from astropy.table import Table

    assert len(Table.read(tmp_path / "sensitivity_fd.ecsv", format="ascii.ecsv")) == 6


def _small_campaign():
    """Two passes of campaign-6pass (a site-tracking and a nadir one), 4 images each: per-pass and
    per-image star-tracker/GNSS errors and catalogue errors shared across images."""
    from dataclasses import replace

    sc = orbits.load_scenario("scenarios/campaign-6pass.toml")
    passes = [replace(p, t_s=p.t_s[::5]) for p in (sc.passes[0], sc.passes[2])]
    return replace(sc, passes=passes)


def _dense_linear_reference(sc, algorithms):
    """The former dense route: each source's full 2K × 2K residual covariance Σ_s of the K nominal
    observations (``crlb.full_residual_covariance``), the gains K = (GᵀG)⁻¹GᵀL and the CRLB's
    (GᵀΣ⁻¹G)⁻¹GᵀΣ⁻¹; σθ per unit σs = √diag(K Σ_s Kᵀ)."""
    import importlib

    from boresight.core.crlb import full_residual_covariance
    from boresight.core.measurement import linearize
    from boresight.studies.montecarlo import nominal_observations
    from orbits.rotations import ARCSEC

    nom = nominal_observations(sc)
    model = DisturbanceModel.from_scenario(sc)
    gains = {}
    for name in algorithms:
        mod = importlib.import_module(f"boresight.core.algorithms.{name}")
        G, _ = mod.linearize(nom, np.zeros(3))
        L = mod.residual_map(nom, np.zeros(3))[0]
        Gf = G.reshape(-1, 3)
        KA = np.linalg.solve(Gf.T @ Gf, Gf.T).reshape(3, nom.n_observations, 2)
        gains[name] = np.einsum("ika,kab->ikb", KA, L).reshape(3, -1)
    G, _ = linearize(nom, np.zeros(3))
    Gf = G.reshape(-1, 3)
    SiG = np.linalg.solve(full_residual_covariance(nom, np.zeros(3), model)[0], Gf)
    gains["crlb"] = np.linalg.solve(Gf.T @ SiG, SiG.T)
    out = {}
    for s in se.SOURCES:
        S = full_residual_covariance(nom, np.zeros(3), se._unit_model(model, s))[0]
        for name, K in gains.items():
            out[name, s] = np.sqrt(np.einsum("ik,kl,il->i", K, S, K)) / ARCSEC
    return out


def test_linear_propagation_on_a_campaign_equals_the_dense_route():
    """Per-pass, per-image and catalogue errors over several images: the block-by-block sandwich
    (and the CRLB through the campaign GLS) equal the dense covariance route to 1e-9 of each
    row's largest coefficient (a small coefficient is a square root of a difference)."""
    sc = _small_campaign()
    t = se.linear_sensitivities(sc, ["least_squares"])
    ref = _dense_linear_reference(sc, ["image_plane", "ground_plane", "unit_vector"])
    for row in t:
        want = ref[row["algorithm"], row["source"]]
        got = np.array([row[f"coef_{a}"] for a in "xyz"])
        np.testing.assert_allclose(
            got, want, rtol=0, atol=1e-9 * max(want.max(), 1e-300), err_msg=f"{row['algorithm']} {row['source']}"
        )


def test_linear_propagation_memory_is_estimated_before_it_is_spent(monkeypatch):
    """The pre-flight estimate (``linear_bytes``) covers the traced peak, and a budget below it
    refuses up front naming the budget and how to raise it."""
    import tracemalloc

    from boresight.studies.montecarlo import nominal_observations
    from orbits.limits import MemoryBudgetError

    sc = _small_campaign()
    est = se.linear_bytes(nominal_observations(sc))
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        se.linear_sensitivities(sc, ["least_squares"])
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert peak < est, (peak, est)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", str(0.5 * est / 2**30))
    with pytest.raises(MemoryBudgetError, match="BORESIGHT_MEMORY_BUDGET_GB"):
        se.linear_sensitivities(sc, ["least_squares"])


CAMPAIGN = "scenarios/campaign-6pass.toml"


def test_campaign_sensitivity_fits_a_1_gib_budget_and_prints_its_pre_flight(tmp_path, capsys, monkeypatch):
    """Issue 23 item 1: the 6-pass campaign's sensitivity study (it built a 7 GiB dense covariance)
    completes under a 1 GiB budget, and says before it starts what it will cost: runs, memory of
    the budget, time, disk for checkpoints."""
    from boresight.cli.main import main

    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", "1")
    rc = main(["sensitivity", CAMPAIGN, "--runs", "4", "--workers", "1", "--no-plots", "--out", str(tmp_path / "o")])
    assert rc == 0
    err = capsys.readouterr().err
    line = next(ln for ln in err.splitlines() if ln.startswith("pre-flight:"))
    assert (
        "4 runs × 7 cases, 1 worker(s); estimated memory" in line
        and "(budget 1.00 GiB; plus up to 140 MB of loaded libraries)" in line
    )
    assert "time ~" in line and "disk for checkpoints" in line


def test_campaign_study_over_the_budget_is_refused_before_it_runs(tmp_path, capsys, monkeypatch):
    """Above the budget: one line naming the estimate, the budget and how to raise it, before any run
    (no pre-flight, no progress, no output files). The budget, 5 MiB, is below the linear
    propagation's estimate (on rows ~12 MiB for campaign-6pass's 1 320 observations; the images ×
    landmarks layout's was 61 MiB, when this test's budget was 0.05 GiB)."""
    from boresight.cli.main import main

    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", "0.005")
    rc = main(["sensitivity", CAMPAIGN, "--runs", "1000", "--workers", "2", "--no-plots", "--out", str(tmp_path / "o")])
    assert rc != 0
    err = capsys.readouterr().err
    assert "would need about" in err and "over the memory budget of 0.005 GiB" in err and "BORESIGHT_MEMORY_BUDGET_GB" in err
    assert "pre-flight" not in err and "runs " not in err.split("would need")[1]
    assert not list((tmp_path / "o").glob("*.ecsv"))


def test_study_memory_estimate_does_not_multiply_by_the_cases():
    """The cases of a sensitivity study are estimated one after the other on one chunk's draws:
    7 cases cost a few per-run errors more than 1, not 7× (traced: 25 MB vs 28 MB per campaign chunk)."""
    from boresight.studies.montecarlo.preflight import study_bytes

    one = study_bytes(1000, 13, 130, 15360, 7, 3, 1, 100_000, 1)
    seven = study_bytes(1000, 13, 130, 15360, 7, 3, 7, 100_000, 1)
    assert one < seven < 1.01 * one
