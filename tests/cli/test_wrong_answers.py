"""Issue 31: the last wrong answers and misleading messages of the command line — noise-free input
(class 8), degree-for-arcsecond slips (class 9), messages naming their culprit (class 5) and a
missing optional library (class 7). Each test failed on the main of 2026-11-27."""

from __future__ import annotations

import numpy as np
import pytest
from cli_run import run_cli

import boresight


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory):
    """``boresight simulate kiev2012-algorithm1``: every σ of the scenario zero (its truth is exact)."""
    folder = tmp_path_factory.mktemp("noise-free")
    code, out, err = run_cli(["simulate", "kiev2012-algorithm1", "--out", folder])
    assert code == 0, err
    return folder / "kiev2012-algorithm1.ecsv"


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
    assert est.extra.get("noise_free") is True
    assert "not meaningful" in est.sigma_includes
    assert any("round-off" in w for w in est.warnings) and not any("NOT used" in w for w in est.warnings)
    # a noisy file is not called noise-free
    noisy = boresight.simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(3))
    assert not boresight.estimate(noisy).extra.get("noise_free")


@pytest.fixture(scope="module")
def kalman20(tmp_path_factory):
    folder = tmp_path_factory.mktemp("kalman20")
    code, out, err = run_cli(["simulate", "kiev2012-kalman20", "--out", folder])
    assert code == 0, err
    return folder / "kiev2012-kalman20.ecsv"


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
