"""``boresight.observations.merge.merge_observations``: several files of one campaign are one set."""

import dataclasses

import numpy as np
import pytest
from builders import campaign_as_flown

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
