"""boresight.core.disturbances: the first-order residual covariance against Monte Carlo."""

from dataclasses import replace

import numpy as np
import pytest
from oracles import image_covariance
from scipy import stats

import boresight
import orbits
from boresight.core.algorithms.image_plane import linearize
from boresight.core.disturbances import DisturbanceModel


@pytest.mark.parametrize("source", ["pixel", "star_tracker", "gnss", "catalogue", "all", "both_modes"])
def test_image_covariance_matches_monte_carlo(source):
    sc = orbits.load_scenario("scenarios/kiev2012-sensitivity.toml")
    sc = replace(sc, theta_true_arcsec=(30.0, -20.0, 50.0), theta_sigma0_arcsec=0.0)
    keep = {
        "pixel": dict(sigma_star_tracker_arcsec=(0.0, 0.0, 0.0), sigma_gnss_m=0.0, sigma_catalogue_m=0.0),
        "star_tracker": dict(sigma_pixel_m=0.0, sigma_gnss_m=0.0, sigma_catalogue_m=0.0),
        "gnss": dict(sigma_pixel_m=0.0, sigma_star_tracker_arcsec=(0.0, 0.0, 0.0), sigma_catalogue_m=0.0),
        "catalogue": dict(sigma_pixel_m=0.0, sigma_star_tracker_arcsec=(0.0, 0.0, 0.0), sigma_gnss_m=0.0),
        "all": {},
        # per-pass + per-image parts, each σ: one image sees variance 2σ² (include_per_pass=True)
        "both_modes": dict(star_tracker_error_mode="both", gnss_error_mode="both"),
    }[source]
    sc = replace(sc, **keep)
    n = 4000
    obs = boresight.simulate(sc, np.random.default_rng(77), runs=n)
    theta = obs.truth["theta_rad"]
    _, q = linearize(obs, theta)
    q = q[:, obs.image_index == 0].reshape(n, -1)  # the rows of one image, 4 landmarks → 8 residuals
    cov = image_covariance(obs.run(0), theta[0], DisturbanceModel.from_scenario(sc))[0, 0]
    var_mc = q.var(axis=0, ddof=1)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n - 1) / (n - 1)
    ratio = var_mc / np.diag(cov)
    assert np.all((ratio > lo) & (ratio < hi)), ratio  # 99.9% χ² interval per residual
    # correlations: the common star-tracker / GNSS errors make the image's residuals correlated
    corr_model = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    corr_mc = np.corrcoef(q.T)
    assert np.abs(corr_mc - corr_model).max() < 5 * (1 - 0) / np.sqrt(n)


def test_disturbance_model_validation():
    with pytest.raises(ValueError, match=r"star_tracker_mode must be one of .* got 'hourly'"):
        DisturbanceModel(star_tracker_mode="hourly")
    with pytest.raises(ValueError, match=r"sigma_gnss_m must be a finite number ≥ 0, got -1"):
        DisturbanceModel(sigma_gnss_m=-1.0)
    with pytest.raises(ValueError, match=r"unknown disturbance source 'wind'"):
        DisturbanceModel().scaled(wind=2.0)


def test_image_covariance_without_per_pass_parts():
    """include_per_pass=False keeps only the per-image parts: a per-pass source drops out, a
    "both" source keeps one σ² (not 2σ²). Deterministic, against models built by hand."""
    sc = orbits.load_scenario("scenarios/kiev2012-sensitivity.toml")
    obs = boresight.simulate(sc, np.random.default_rng(3))
    th = obs.truth["theta_rad"][0]
    full = DisturbanceModel.from_scenario(sc)
    assert full.sigma_gnss_m > 0 and max(full.sigma_star_tracker_rad) > 0
    per_pass = replace(full, star_tracker_mode="per_pass", gnss_mode="per_pass")
    both = replace(full, star_tracker_mode="both", gnss_mode="both")
    no_shared = replace(full, sigma_star_tracker_rad=(0.0, 0.0, 0.0), sigma_gnss_m=0.0)
    np.testing.assert_allclose(
        image_covariance(obs, th, per_pass, include_per_pass=False), image_covariance(obs, th, no_shared), rtol=1e-12, atol=0
    )
    np.testing.assert_allclose(
        image_covariance(obs, th, both, include_per_pass=False), image_covariance(obs, th, full), rtol=1e-12, atol=0
    )
    # with the per-pass parts included, a per-pass source is the per-image one (one image)
    np.testing.assert_allclose(image_covariance(obs, th, per_pass), image_covariance(obs, th, full), rtol=1e-12, atol=0)
    assert not np.allclose(image_covariance(obs, th, both), image_covariance(obs, th, full), rtol=1e-3, atol=0)
