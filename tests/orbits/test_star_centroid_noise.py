"""Centroid noise by magnitude on a scenario's star rows (``[stars] centroid_sigma_reference_m``): each star row's
σ follows ``orbits.star_frames.CentroidNoise`` of its magnitude, draws its noise, travels with the rows
(``ObservationSet.sigma_xy_m``, the file's ``sigma_x sigma_y``) and weights the GLS. Synthetic sky (no
optional extra needed)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from paths import SCENARIOS

import boresight
import orbits
from boresight.core.disturbances import DisturbanceModel
from boresight.observations.simulate import nominal_observations
from boresight.studies import montecarlo as mc
from orbits.scenario_schema import ScenarioError
from orbits.star_frames import CentroidNoise

LAW = {"centroid_sigma_reference_m": 1.3e-6, "centroid_reference_mag": 6.0, "centroid_sigma_floor_m": 0.3e-6}


def _doc(segments=None, **stars):
    d = tomllib.loads((SCENARIOS / "star-calibration.toml").read_text())
    d["stars"] = {"catalogue": "synthetic", "mag_limit_hp": 7.5, "seed": 4, **stars}
    if segments is not None:
        d["star_frames"] = [d["star_frames"][k] for k in segments]
    return d


def _magnitudes(obs):
    return obs.stars.magnitude_hp[obs.star_rank()[obs.target_index]]


def test_each_star_row_carries_and_draws_its_magnitudes_sigma():
    """σ per row = the law at the star's catalogue magnitude (x and y alike); the drawn noise divided by it
    is standard normal: over 200 runs × K rows its variance is 1 within 5 % (2/√(2·200K) ≈ 0.4 % SE:
    > 10 SE), and the faintest rows' noise is larger than the brightest rows'."""
    sc = orbits.scenario_from_dict(_doc(**LAW), "stars.toml")
    obs = boresight.simulate(sc, np.random.default_rng(2), runs=200)
    expect = CentroidNoise(
        sigma_reference_m=LAW["centroid_sigma_reference_m"],
        reference_mag=LAW["centroid_reference_mag"],
        sigma_floor_m=LAW["centroid_sigma_floor_m"],
    ).sigma_m(_magnitudes(obs))
    np.testing.assert_allclose(obs.sigma_xy_m, np.stack([expect, expect], -1), rtol=1e-12)
    assert obs.sigma_xy_m.min() < 0.6e-6 and obs.sigma_xy_m.max() > 2.0e-6  # Hp 1 … 7.5: a wide range
    z = obs.truth["pixel_noise_m"] / obs.sigma_xy_m[None]
    assert abs(z.var() - 1) < 0.05
    noise = np.sqrt((obs.truth["pixel_noise_m"] ** 2).mean(axis=(0, 2)))  # (K,) rms per row
    faint, bright = _magnitudes(obs) > 7.0, _magnitudes(obs) < 4.0
    assert noise[faint].mean() > 2 * noise[bright].mean()


def test_without_the_law_every_star_row_has_the_pixel_sigma():
    sc = orbits.scenario_from_dict(_doc(), "stars.toml")
    obs = boresight.simulate(sc, np.random.default_rng(2))
    assert obs.sigma_xy_m is None and sc.stars.centroid() is None


def test_the_law_travels_through_the_file_and_the_study_engine(tmp_path):
    """simulate → write (format 1.3) → read keeps each row's σ; the study engine's nominal campaign carries
    the same σ on the same rows (``orbits.campaign_arrays``); with ``[[passes]]`` the landmark rows keep the
    scenario's σ (NaN)."""
    sc = orbits.scenario_from_dict(_doc(**LAW), "stars.toml")
    obs = boresight.simulate(sc, np.random.default_rng(5))
    back = boresight.ObservationSet.read(obs.write(tmp_path / "s.ecsv"))
    np.testing.assert_array_equal(back.sigma_xy_m, obs.sigma_xy_m)
    assert "format_version: '1.3'" in (tmp_path / "s.ecsv").read_text()
    nom = nominal_observations(sc, orbits.campaign_arrays(sc))
    assert np.array_equal(nom.image_index, obs.image_index) and np.array_equal(nom.target_index, obs.target_index)
    np.testing.assert_array_equal(nom.sigma_xy_m, obs.sigma_xy_m)
    joint_doc = tomllib.loads((SCENARIOS / "stars-and-landmarks.toml").read_text())
    joint_doc["stars"] = {"catalogue": "synthetic", "mag_limit_hp": 7.5, "seed": 4, **LAW}
    joint = orbits.scenario_from_dict(joint_doc, "joint.toml")
    both = boresight.simulate(joint, np.random.default_rng(5))
    star = both.target_kind[both.target_index] == "star"
    assert np.all(np.isnan(both.sigma_xy_m[~star])) and np.all(np.isfinite(both.sigma_xy_m[star]))
    nom = nominal_observations(joint, orbits.campaign_arrays(joint))
    np.testing.assert_array_equal(np.isnan(nom.sigma_xy_m), np.isnan(both.sigma_xy_m))


def test_the_gls_weights_each_star_by_its_sigma():
    """χ²/dof of the GLS is ~1 with each row's σ and far from it when the rows are weighted by the one
    pixel σ (the law's stars span 0.3–2.6 µm about the scenario's 1.3 µm): the column is what makes the
    noise model right. 20 runs: the mean χ²/dof over 20 × ~800 dof has SE ~0.01."""
    sc = orbits.scenario_from_dict(_doc(**LAW), "stars.toml")
    obs = boresight.simulate(sc, np.random.default_rng(9), runs=20)
    model = DisturbanceModel.from_observations(obs)
    right = boresight.estimate(obs, "image_plane", weighting="gls", model=model)
    import dataclasses

    wrong = boresight.estimate(dataclasses.replace(obs, sigma_xy_m=None), "image_plane", weighting="gls", model=model)
    rd, wd = np.mean(right.chi2_model / right.dof_model), np.mean(wrong.chi2_model / wrong.dof_model)
    assert abs(rd - 1) < 0.05, rd
    assert abs(wd - 1) > 0.1, wd


@pytest.mark.parametrize(
    "change, message",
    [
        ({"centroid_sigma_reference_m": -1e-6}, r"centroid_sigma_reference_m must be a finite number"),
        ({"centroid_sigma_floor_m": "a"}, r"centroid_sigma_floor_m must be a finite number"),
        ({"centroid_magnitude": 6}, r"unknown key"),
        ({"centroid_sigma_ref_m": 1e-6}, r"unknown key 'centroid_sigma_ref_m' — did you mean 'centroid_sigma_reference_m'"),
    ],
)
def test_the_law_is_checked_by_name(change, message):
    with pytest.raises(ScenarioError, match=message):
        orbits.scenario_from_dict(_doc(**change), "x.toml")


def test_montecarlo_of_a_mixed_sigma_star_campaign_reports_the_scatter():
    """The scenario study engine (GLS weighting, ``boresight.estimate`` per chunk) on star rows whose σ spans
    0.3–2.6 µm by magnitude: 600 runs, the mean reported σ within the 99.73 % χ² interval of the scatter
    (599 dof: about ±9 %) on every axis (false-failure chance < 1 % over three axes), and > 98.5 % of the
    runs within 3σ (expected 99.73 %, binomial SE 0.2 %)."""
    from boresight.stats import sigma_interval

    sc = orbits.scenario_from_dict(_doc(segments=[0, 1], **LAW), "stars.toml")
    n = orbits.campaign_arrays(sc)["t_s"].size
    r = mc.montecarlo_study(sc, ["image_plane"], runs=600, seed=28, workers=1, weighting="gls", image_counts=[n])
    scatter = r.sigma_arcsec("image_plane").reshape(-1)
    reported = np.asarray(r.reported_sigma_arcsec("image_plane")).reshape(-1)
    lo, hi = sigma_interval(scatter, 600, 0.9973)
    assert np.all((lo <= reported) & (reported <= hi)), (reported, scatter)
    err = np.asarray(r.samples["image_plane"]).reshape(600, 3)
    print(f"\n{n} frames, 600 runs: reported σ {reported} ″, scatter {scatter} ″, ratio {reported / scatter}")
    assert np.all(np.mean(np.abs(err) <= 3 * reported, axis=0) > 0.985)


def test_sensitivity_splits_the_rows_own_sigma_into_the_pixel_source():
    """The linear propagation per source (``sensitivity.linear_sensitivities``) on star rows with their own σ:
    the sources' contributions add up to the sandwich σθ of the unit-weight fit under the full model
    (``estimate(..., weighting="unit", model=)`` on the nominal rows) to 1e-9, and the pixel source carries
    the rows' own σ (its contribution is that σθ without the tracker). A unit model of another source must not
    carry the rows' pixel σ (it did once: the pixel share read 0 % and every source carried a pixel term)."""
    from boresight.studies.sensitivity import linear_sensitivities

    sc = orbits.scenario_from_dict(_doc(segments=[0, 1], **LAW), "stars.toml")
    t = linear_sensitivities(sc, ["image_plane"])
    nom = nominal_observations(sc)
    model = DisturbanceModel.from_scenario(sc)
    full = boresight.estimate(nom, "image_plane", weighting="unit", model=model, iterate=False).sigma.to_value("arcsec")
    np.testing.assert_allclose(t.meta["sigma_theta_arcsec"]["image_plane"][:3], full.reshape(3), rtol=1e-9)
    import dataclasses

    pixel_only = dataclasses.replace(model, sigma_star_tracker_rad=(0.0, 0.0, 0.0))
    pix = boresight.estimate(nom, "image_plane", weighting="unit", model=pixel_only, iterate=False).sigma.to_value("arcsec")
    row = [r for r in t if r["method"] == "analytic" and r["source"] == "K"][0]
    got = np.array([row["contribution_x"], row["contribution_y"], row["contribution_z"]])
    np.testing.assert_allclose(got, pix.reshape(3), rtol=1e-9)
