"""``boresight.core.variance_components``: REML scales of the noise sources through the one campaign GLS.

One seed each on the discrepancy tests' 4-pass campaign (40 images, 440 observations, Kiev noise
per image). The tolerances are the estimator's own σ (Fisher information from the Monte Carlo
draws): a scale within 3σ of the truth fails by chance with probability 0.3 % per source, a scale
wrong by the factor simulated (2×) is 8σ or more away for the pixel noise.
"""

import dataclasses

import numpy as np
import pytest
from builders import discrepancy_campaign

from boresight import simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.core.variance_components import variance_components_at


@pytest.fixture(scope="module")
def campaign():
    return discrepancy_campaign()


def _by_source(vc):
    return {c.source: c for c in vc.components}


def test_declared_scales_are_recovered(campaign):
    """Data simulated with the declared model: every determined source's estimate within 3σ of its
    declared σ, χ²/dof after ≈ 1, the model unchanged in structure (per-image star tracker)."""
    model = DisturbanceModel.from_scenario(campaign)
    obs = simulate(campaign, np.random.default_rng(11))
    vc = variance_components_at(obs, obs.truth["theta_rad"][0], model)
    assert vc.converged
    for c in vc.components:
        if c.determined:
            assert abs(c.estimate - c.declared) < 3 * c.sigma, c
    assert abs(vc.chi2_dof_after - 1) < 0.1
    assert not vc.heavy_tailed


def test_a_doubled_pixel_noise_is_found_and_the_others_kept(campaign):
    """Pixel noise 2× the declared (6 µm for 3), the rest as declared: the pixel scale within 3σ of
    6 µm (and > 8σ from 3), GNSS and the star tracker within 3σ of their declared σ; the returned
    model carries the estimate and χ²/dof goes from ≈ 1.6 to ≈ 1."""
    model = DisturbanceModel.from_scenario(campaign)
    obs = simulate(dataclasses.replace(campaign, sigma_pixel_m=2 * campaign.sigma_pixel_m), np.random.default_rng(12))
    vc = variance_components_at(obs, obs.truth["theta_rad"][0], model)
    c = _by_source(vc)
    assert abs(c["pixel"].estimate - 6.0) < 3 * c["pixel"].sigma and (c["pixel"].estimate - 3.0) > 8 * c["pixel"].sigma
    assert vc.model.sigma_pixel_m == pytest.approx(c["pixel"].estimate * 1e-6)
    assert abs(c["gnss"].estimate - 15.0) < 3 * c["gnss"].sigma
    assert vc.chi2_dof_before > 1.3 and abs(vc.chi2_dof_after - 1) < 0.1
    assert "pixel noise: declared 3 µm, the data say" in vc.lines()[0]


def test_an_undeclared_per_pass_rotation_is_added_only_when_asked(campaign):
    """``extra_pass_rotation_rad`` adds a per-pass source (declared 0, ``added``); on data without one
    the data do not ask for it and the model keeps none."""
    model = DisturbanceModel.from_scenario(campaign)
    obs = simulate(campaign, np.random.default_rng(13))
    vc = variance_components_at(obs, obs.truth["theta_rad"][0], model, extra_pass_rotation_rad=4.8e-6)
    added = [c for c in vc.components if c.added]
    assert added and all(c.declared == 0 for c in added)
    assert all(c.estimate == 0 or c.estimate < 3 * c.sigma for c in added)
