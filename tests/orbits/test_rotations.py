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
    A = (
        (q4**2 - np.sum(qv**2, -1))[:, None, None] * np.eye(3)
        + 2 * qv[:, :, None] * qv[:, None, :]
        - 2 * q4[:, None, None] * skew(qv)
    )
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


# ---------------------------------------------------------------------------- SO(3) helpers (one home for the math)


def test_so3_helpers_agree_with_scipy_finite_differences_and_lapack():
    """Round-off bounds of the hand-written SO(3) helpers (the Monte Carlo kernels and the
    estimators use these): Rodrigues vs scipy ``Rotation`` ≤ 1e-15 (unit vectors); J_r vs the
    closed form E − bΦ + cΦ² ≤ 1e-15 and vs central differences ≤ 1e-9 (difference error
    ~h² + ε/h at h = 1e-6); the adjugate inverse vs LAPACK ≤ 1e-13 × cond relative (cond ≤ 1e3)."""
    from orbits.rotations import right_jacobian, rotate, rotate_soa, rotvec_dcm, skew, sym3_inverse, sym3_inverse_soa

    rng = np.random.default_rng(8)
    for scale in (0.0, 1e-6, 3e-3, 0.5):  # series branch, mixed, closed form
        th = rng.normal(size=(200, 3)) * scale
        s = rng.normal(size=(200, 3))
        s /= np.linalg.norm(s, axis=-1, keepdims=True)
        ref = np.einsum("rij,rj->ri", rotvec_dcm(-th), s)
        np.testing.assert_allclose(rotate(-th, s), ref, rtol=0, atol=1e-15)
        sx, sy, sz, *_ = rotate_soa(th.T.copy(), s[:, 0], s[:, 1], s[:, 2])
        np.testing.assert_allclose(np.stack([sx, sy, sz], -1), ref, rtol=0, atol=1e-15)
        phi = np.linalg.norm(th, axis=-1)[:, None, None]
        P = skew(th)
        with np.errstate(invalid="ignore", divide="ignore"):
            closed = np.eye(3) - (1 - np.cos(phi)) / phi**2 * P + (phi - np.sin(phi)) / phi**3 * (P @ P)
        ok = phi[:, 0, 0] > 1e-3
        np.testing.assert_allclose(right_jacobian(th)[ok], closed[ok], rtol=0, atol=1e-15)
    # J_r by central differences of exp(−Φ(θ)) s0: d s = Φ(s(θ)) J_r(θ) dθ
    th, s0, h = np.array([0.3, -0.2, 0.4]), np.array([0.2, -0.5, 1.0]), 1e-6
    num = np.stack([(rotvec_dcm(-(th + h * e)) @ s0 - rotvec_dcm(-(th - h * e)) @ s0) / (2 * h) for e in np.eye(3)], -1)
    np.testing.assert_allclose(skew(rotvec_dcm(-th) @ s0) @ right_jacobian(th), num, rtol=0, atol=1e-9)
    A = rng.normal(size=(500, 3, 3))
    A = A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(3)
    A = A[np.linalg.cond(A) < 1e3]
    inv = np.linalg.inv(A)
    np.testing.assert_allclose(sym3_inverse(A), inv, rtol=1e-13 * 1e3, atol=0)
    comps = sym3_inverse_soa(A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 1, 1], A[:, 1, 2], A[:, 2, 2])
    np.testing.assert_allclose(np.stack(comps, -1), inv[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]], rtol=1e-13 * 1e3, atol=0)
