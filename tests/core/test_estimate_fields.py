"""``Estimate``'s diagnostics are typed fields; the old untyped ``extra`` dict is deprecated but still
readable (one release), under its old keys and with the same values as the fields."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import boresight
from boresight.core.algorithms.kalman import KalmanResult
from boresight.core.result import _EXTRA_KEYS, Estimate


@pytest.fixture(scope="module")
def obs():
    return boresight.simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(5))


def test_every_old_key_is_a_field():
    """Each key ``extra`` used to hold maps to a field of ``Estimate`` (a renamed field left out of
    the map, or a typo in it, fails here)."""
    names = {f.name for f in dataclasses.fields(Estimate)}
    assert set(_EXTRA_KEYS.values()) <= names
    assert "extra" not in names  # no longer a constructor argument


def test_robust_fit_fills_the_typed_fields_and_extra_warns_with_the_same_values(obs):
    est = boresight.estimate(obs, weighting="gls", loss="huber", effects=["focal_scale"])
    assert est.loss == "huber"
    assert est.chi2_model is not None and est.dof_model is not None
    assert est.chi2_kept_observations is not None
    assert est.whitened_residual_norm is not None and est.robust_weights is not None
    assert est.joint_labels[:3] == ("theta_x", "theta_y", "theta_z") and "focal_scale" in est.effect_status
    assert np.shape(est.joint_covariance) == (len(est.joint_labels),) * 2
    assert isinstance(est.unit_slips, tuple)
    with pytest.warns(DeprecationWarning, match="Estimate.extra is deprecated"):
        extra = est.extra
    assert extra["loss"] == "huber"
    assert extra["normalised_residuals"] is est.whitened_residual_norm
    assert extra["joint_covariance"] is est.joint_covariance
    assert extra["chi2_model"] is est.chi2_model
    assert "noise_free" not in extra  # only what is set, as before


def test_kalman_result_and_gate_are_fields(obs):
    est = boresight.estimate(obs, algorithm="kalman")
    assert isinstance(est.algorithm_result, KalmanResult)
    assert est.rejected is not None and est.rejected.dtype == bool
    assert est.nees is not None  # a simulated set carries its truth
    with pytest.warns(DeprecationWarning):
        assert est.extra["kalman"] is est.algorithm_result
