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
