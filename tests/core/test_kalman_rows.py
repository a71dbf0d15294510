"""The Kalman filter and the per-image covariance on the row model: each image's measurement is its
own rows (2m_n), images batched by equal m_n, catalogue states only for the targets seen, and the
filter's state history checked against the memory budget before it is allocated."""

from dataclasses import replace

import numpy as np
import pytest
from oracles import dense_grid, image_covariance

import boresight
from boresight.core.algorithms.kalman import kalman_filter, linearized_measurements
from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.structure import image_covariance_rows, images_by_row_count
from boresight.reproductions.kiev2012 import kalman_scenario
from orbits.limits import MemoryBudgetError


def _uneven(runs=2, seed=0):
    """kalman20 with landmark 1 unseen in images 0-9, landmark 3 in image 4 and image 12 empty: images
    with 4, 3, 2 and 0 rows; the row set of the masked grid."""
    sc = kalman_scenario(sigma0_arcsec=600.0, star_tracker_mode="both", gnss_mode="both")
    obs = dense_grid(boresight.simulate(sc, np.random.default_rng(seed), runs=runs))  # tests/oracles.py
    mask = obs.mask.copy()
    mask[:10, 1] = False
    mask[4, 3] = False
    mask[12] = False
    return DisturbanceModel.from_scenario(sc), replace(obs, mask=mask).to_rows()


def test_image_covariance_rows_is_the_dense_block_on_the_rows():
    """Per group of equal m_n, each image's 2m_n × 2m_n block equals the images × landmarks layout's
    block on the image's own landmarks (the one builder, two layouts) to 1e-15, and the layout's
    unobserved entries are the identity."""
    model, obs = _uneven()
    th = np.full((obs.runs, 3), 3e-5)
    dense = image_covariance(obs, th, model)
    groups = images_by_row_count(obs)
    assert [m for m, _ in groups] == [0, 2, 3, 4]
    for m, ims in groups:
        blk = image_covariance_rows(obs.images(ims), th, model)
        assert blk.shape == (obs.runs, ims.size, 2 * m, 2 * m)
        for j, n in enumerate(ims):
            at = (2 * obs.target_index[obs.row_start[n] : obs.row_start[n + 1]][:, None] + np.arange(2)).ravel()
            np.testing.assert_allclose(blk[:, j], dense[:, n][:, at][:, :, at], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(dense[:, 12], np.broadcast_to(np.eye(8), (obs.runs, 8, 8)))
    with pytest.raises(ValueError, match="equal numbers of rows, got \\[0, 2, 3, 4\\]"):
        image_covariance_rows(obs, th, model)
    with pytest.raises(ValueError, match="images_by_row_count"):
        linearized_measurements(obs, np.zeros(3), model, ("theta",))


def test_catalogue_states_only_for_the_targets_seen():
    """Images 0-9 of the uneven set never see landmark 1: the filter carries 3 catalogue states for
    each of the 3 landmarks seen (n_x = 3 + 9, not 3 + 12), and its θ, P and NIS equal those of the
    same rows with landmark 1 taken out of the target table (bit for bit: the same arithmetic)."""
    model, obs = _uneven()
    part = obs.images(slice(0, 10))
    assert part.n_targets == 4 and np.unique(part.target_index).size == 3
    res = kalman_filter(part, model, states=("theta", "catalogue"))
    ref = kalman_filter(part.observed_targets(), model, states=("theta", "catalogue"))
    assert res.x.shape == (obs.runs, 12) and ref.x.shape == (obs.runs, 12)
    np.testing.assert_array_equal(res.x_history, ref.x_history)
    np.testing.assert_array_equal(res.P_history, ref.P_history)
    np.testing.assert_array_equal(res.dof, 2 * part.rows_per_image)


def test_the_state_history_is_refused_before_allocation(monkeypatch):
    """A budget of 1 MiB: the filter over 20 images with 15 states and 600 runs (P_history alone
    600 × 20 × 15² × 8 B = 21.6 MB) is refused with the estimate and the sizes in the message;
    2 runs fit."""
    model, obs = _uneven(runs=2)
    sc = kalman_scenario(sigma0_arcsec=600.0)
    big = boresight.simulate(sc, np.random.default_rng(1), runs=600)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", str(1 / 1024))
    kalman_filter(obs, model)  # 2 runs × 20 × (18² + 18) × 8 B ≈ 0.1 MB: fits
    with pytest.raises(
        MemoryBudgetError, match=r"state history of 600 run\(s\) × 20 images × 15 states .* would need about 0\.0\d+ GiB"
    ):
        kalman_filter(big, DisturbanceModel.from_scenario(sc))
