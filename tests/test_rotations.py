"""orbits.rotations: Φ, exact small rotations vs Kiev 2012's first-order forms, quaternions."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from orbits.rotations import ARCSEC, axis_dcm, dcm_from_quat, misalignment_dcm, quat_from_dcm, skew, star_tracker_error_dcm

vec = st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(np.array)


@given(vec, vec)
def test_skew_is_the_cross_product(a, b):
    assert np.allclose(skew(a) @ b, np.cross(a, b), atol=1e-15)


def test_skew_matches_the_seminars_matrix():
    d1, d2, d3 = 1.0, 2.0, 3.0
    assert np.array_equal(skew([d1, d2, d3]), [[0, -d3, d2], [d3, 0, -d1], [-d2, d1, 0]])


def test_misalignment_is_eq24_to_second_order():
    """exp(−Φ(θ)) = E − Φ(θ) + O(θ²): halving θ quarters the remainder (Kiev 2012 eq 24)."""
    rng = np.random.default_rng(3)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    errs = []
    for eps in (600 * ARCSEC, 300 * ARCSEC):
        theta = eps * u
        errs.append(np.abs(misalignment_dcm(theta) - (np.eye(3) - skew(theta))).max())
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=1e-3)
    assert errs[0] == pytest.approx((600 * ARCSEC) ** 2 / 2, rel=0.5)


def test_star_tracker_error_is_e_plus_phi():
    delta = np.array([4.0, -3.0, 2.0]) * ARCSEC
    assert np.abs(star_tracker_error_dcm(delta) - (np.eye(3) + skew(delta))).max() < 1e-9


def test_attitude_matrix_formula_of_the_conventions():
    rng = np.random.default_rng(5)
    q = rng.normal(size=(10, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    qv, q4 = q[:, :3], q[:, 3]
    A = (q4**2 - np.sum(qv**2, -1))[:, None, None] * np.eye(3) + 2 * qv[:, :, None] * qv[:, None, :] - 2 * q4[:, None, None] * skew(qv)
    assert np.allclose(dcm_from_quat(q), A, atol=1e-14)
    assert np.allclose(dcm_from_quat(q), np.swapaxes(Rotation.from_quat(q).as_matrix(), -1, -2), atol=1e-15)


@settings(max_examples=50)
@given(vec)
def test_quaternion_round_trip_and_sign(v):
    C = misalignment_dcm(v)
    q = quat_from_dcm(C)
    assert q[3] >= 0
    assert np.allclose(dcm_from_quat(q), C, atol=1e-14)
    assert np.abs(C @ C.T - np.eye(3)).max() < 1e-12


def test_axis_dcm_is_a_frame_rotation():
    a = 0.3
    assert np.allclose(axis_dcm(2, a), [[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1]])
    for k in range(3):
        e = np.zeros(3)
        e[k] = a
        assert np.allclose(axis_dcm(k, a), misalignment_dcm(e), atol=1e-15)


def test_bad_shapes_name_what_was_expected():
    with pytest.raises(ValueError, match=r"shape \(3,\) or \(\.\.\., 3\), got \(4,\)"):
        skew(np.zeros(4))
    with pytest.raises(ValueError, match=r"scalar last.*got \(3,\)"):
        dcm_from_quat(np.zeros(3))


def test_batches_broadcast():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(2, 5, 3)) * 1e-3
    batch = misalignment_dcm(v)
    one = np.array([[misalignment_dcm(v[i, j]) for j in range(5)] for i in range(2)])
    assert np.array_equal(batch, one)
