"""Star frames in scenarios: ``[stars]`` and ``[[star_frames]]`` (orbits.star_campaign), simulated as rows.

The shipped scenarios use Hipparcos (the optional extra ``stars``); these tests swap in the
synthetic sky (``[stars] catalogue = "synthetic"``) so they run without it.
"""

import tomllib

import numpy as np
import pytest
from astropy import units as u
from paths import SCENARIOS

import boresight
import orbits
from orbits.rotations import ARCSEC
from orbits.scenario_schema import ScenarioError


def star_doc(name="star-calibration", noise_free=False, **changes):
    d = tomllib.loads((SCENARIOS / f"{name}.toml").read_text())
    d["stars"] = {"catalogue": "synthetic", "mag_limit_hp": 7.5, "seed": 4}
    if noise_free:
        for table in ("star_tracker", "gnss", "pixel", "catalogue"):
            if table in d:
                d[table]["sigma_m" if table != "star_tracker" else "sigma_arcsec"] = 0.0 if table != "star_tracker" else [0.0] * 3
    d.update(changes)
    return d


def test_star_calibration_simulates_star_rows():
    sc = orbits.scenario_from_dict(star_doc(), "star-calibration")
    assert sc.passes == () and len(sc.star_frames) == 3
    obs = boresight.simulate(sc, np.random.default_rng(0), runs=3)
    assert set(obs.target_kind.tolist()) == {"star"} and obs.runs == 3
    assert set(np.unique(obs.pass_index).tolist()) == {0, 1, 2}
    assert np.all(obs.rows_per_image > 0) and obs.n_observations > 200
    # the rows' truth is the one projection of the apparent directions at the true θ, plus the drawn noise
    xy = boresight.core.measurement.predict_rows(obs, obs.truth["theta_rad"], (obs.image_index, obs.target_index))
    tracker_free = obs.truth["delta_rad"]
    assert np.abs(tracker_free).max() > 0  # the star tracker's error moves the prediction, not the truth
    assert np.allclose(obs.xy_m - obs.truth["pixel_noise_m"], obs.truth["xy_true_m"], atol=1e-18)
    assert np.abs(xy - obs.truth["xy_true_m"]).max() > 1e-6  # the reported attitude differs from the true one


def test_night_only_frames_are_in_the_earth_shadow():
    from orbits.star_campaign import star_frame_geometry

    sc = orbits.scenario_from_dict(star_doc(), "star-calibration")
    g = star_frame_geometry(sc)
    night = g["pass_index"] == 2
    assert 0 < night.sum() < 96  # part of the 96 zenith frames of one orbit
    assert np.all(np.diff(g["t_s"][night]) > 0)


def test_a_noise_free_star_only_file_recovers_theta_to_1e_6_arcsec(tmp_path):
    """Issue 28's must-show: simulate → write (format 1.2) → read → estimate, θ to 1e-6″."""
    sc = orbits.scenario_from_dict(star_doc(noise_free=True), "star-calibration")
    obs = boresight.simulate(sc, np.random.default_rng(1))
    back = boresight.ObservationSet.read(obs.write(tmp_path / "stars.ecsv"))
    est = boresight.estimate(back, "image_plane")
    err = est.theta.to_value(u.arcsec) - np.asarray(sc.theta_true_arcsec)
    assert np.max(np.abs(err)) < 1e-6, err


@pytest.mark.parametrize(
    "change, message",
    [
        ({"star_frames": [{"attitude": "tumble", "t_s": [0.0]}]}, r"star_frames\[0\].attitude must be one of"),
        ({"star_frames": [{"attitude": "zenith"}]}, r"star_frames\[0\] is missing t_s"),
        ({"star_frames": [{"attitude": "zenith", "t_s": [0.0], "ra": 3.0}]}, r"star_frames\[0\].*unknown key.*'ra'"),
        ({"stars": {"catalogue": "tycho"}}, r"\[stars\] catalogue must be 'hipparcos' or 'synthetic'"),
        ({"star_frames": [{"attitude": "inertial_hold", "dec_deg": 95.0, "t_s": [0.0]}]}, r"dec_deg must be a finite number"),
    ],
)
def test_star_tables_are_checked_by_name(change, message):
    with pytest.raises(ScenarioError, match=message):
        orbits.scenario_from_dict(star_doc(**change), "x.toml")


@pytest.mark.parametrize(
    "effects",
    [{"focal_scale": [2e-4]}, {"thermal": [3.0, -2.0, 1.0, 0.5, 1.5, -1.0]}, {"time_tag": [0.05]}, {"aberration": [1.0]}],
)
def test_hidden_effects_act_on_star_frames_by_their_one_definition(effects):
    """Noise-free star frames simulated with an effect hidden (``observe``'s forward chain) are fitted
    by θ plus that effect (``core.effect_model``'s star branch) to round-off: the two ends of one
    definition. The shipped segments; for a time tag, a hold and a zenith segment of frames 10 s apart
    (the zenith attitude turns at the orbital rate, which the estimator takes from the reported
    attitudes of neighbouring frames; a uniform turn's time shift is a constant rotation, so the hold,
    which a time tag does not move, is what separates it from θ; a slew's ends are kinks no polynomial follows)."""
    extra = {}
    if "time_tag" in effects:
        extra["star_frames"] = [
            {
                "attitude": "inertial_hold",
                "u0_deg": 200.0,
                "ra_deg": 100.0,
                "dec_deg": 20.0,
                "t_s": {"start": 0.0, "stop": 190.0, "step": 10.0},
            },
            {"attitude": "zenith", "u0_deg": 90.0, "t_s": {"start": 0.0, "stop": 600.0, "step": 10.0}},
        ]
    sc = orbits.scenario_from_dict(star_doc(noise_free=True, effects=effects, **extra), "x.toml")
    obs = boresight.simulate(sc, np.random.default_rng(3))
    est = boresight.estimate(obs, "image_plane", effects=list(effects))
    assert np.max(np.abs(est.theta.to_value(u.arcsec) - np.asarray(sc.theta_true_arcsec))) < 1e-6
    name = next(iter(effects))
    value = est.effects[name][0].value
    assert np.allclose(value, effects[name], rtol=1e-6, atol=1e-9), (value, effects[name])


def test_gnss_bias_leaves_star_frames_unchanged():
    """A position-stage effect cannot reach a star: the star rows are the same with and without it."""
    plain = boresight.simulate(orbits.scenario_from_dict(star_doc(), "x"), np.random.default_rng(5))
    biased = boresight.simulate(
        orbits.scenario_from_dict(star_doc(effects={"gnss_bias": [0.0, 50.0, 0.0]}), "x"), np.random.default_rng(5)
    )
    assert np.max(np.abs(plain.xy_m - biased.xy_m)) < 1e-15


def test_stars_and_landmarks_share_one_image_table():
    """The joint scenario: landmark passes first, star segments after (passes renumbered), one set."""
    sc = orbits.scenario_from_dict(star_doc("stars-and-landmarks"), "stars-and-landmarks")
    obs = boresight.simulate(sc, np.random.default_rng(2))
    kinds = obs.target_kind[obs.target_index]
    assert {"star", "landmark"} == set(kinds.tolist())
    star_images = np.unique(obs.image_index[kinds == "star"])
    lm_images = np.unique(obs.image_index[kinds == "landmark"])
    assert not set(star_images) & set(lm_images)
    assert set(obs.pass_index[star_images].tolist()) == {3, 4, 5, 6} and set(obs.pass_index[lm_images].tolist()) == {0, 1, 2}
    assert np.allclose(obs.truth["theta_rad"][0], np.asarray(sc.theta_true_arcsec) * ARCSEC)
