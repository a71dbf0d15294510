"""Eq 28 sensitivities: FD Monte Carlo (common random numbers) vs linear propagation vs CRLB."""

from __future__ import annotations

import json

import numpy as np
import pytest

import orbits
from boresight.reproductions.kiev2012.published import SEMINAR_EQ28
from boresight.studies import sensitivity as se
from boresight.core.crlb import cramer_rao_bound
from boresight.core.disturbances import DisturbanceModel

SENS = "scenarios/kiev2012-sensitivity.toml"


@pytest.fixture(scope="module")
def study():
    return se.study(SENS, ["image_plane", "unit_vector"], runs=6000, seed=3, workers=1)


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

    rc = main(["sensitivity", SENS, "--runs", "2000", "--algorithm", "image_plane", "--out", str(tmp_path), "--workers", "1", "--quiet", "--no-plots"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "seminar" in out and "error budget" in out
    meta = json.loads((tmp_path / "sensitivity.json").read_text())
    assert meta["runs"] == 2000 and set(meta["variants"]) == set(se.SOURCES)
    from astropy.table import Table

    assert len(Table.read(tmp_path / "sensitivity_fd.ecsv", format="ascii.ecsv")) == 6
