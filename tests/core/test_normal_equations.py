"""NormalEquations: recursive = batch (Kiev 2012 eq 18), weights, whitening, nuisance elimination."""

import numpy as np
import pytest

from boresight.core.gls.normal_equations import NormalEquations, ObservabilityError


def _problem(rng, R=5, k=40, n=3):
    G = rng.normal(size=(R, k, n))
    theta = rng.normal(size=(R, n))
    q = np.einsum("rkn,rn->rk", G, theta) + 0.1 * rng.normal(size=(R, k))
    return G, q


def test_recursive_updates_equal_one_batch_solve():
    rng = np.random.default_rng(1)
    G, q = _problem(rng)
    w = rng.uniform(0.5, 2.0, size=q.shape)
    batch = NormalEquations()
    batch.update(G, q, w)
    rec = NormalEquations()
    for i in range(G.shape[1]):  # one residual at a time, as eq 18 writes it
        rec.update(G[:, i : i + 1], q[:, i : i + 1], w[:, i : i + 1])
    a, b = batch.solve(), rec.solve()
    scale = np.abs(a.theta).max()
    assert np.max(np.abs(a.theta - b.theta)) <= 1e-12 * scale
    assert np.max(np.abs(a.covariance - b.covariance)) <= 1e-12 * np.abs(a.covariance).max()
    assert np.allclose(a.chi2, b.chi2, rtol=1e-10, atol=0)
    assert np.array_equal(a.dof, b.dof) and a.dof[0] == 40 - 3


def test_batch_solve_matches_scipy_lstsq_and_sum_of_accumulators():
    from scipy import linalg

    rng = np.random.default_rng(2)
    G, q = _problem(rng, R=3)
    ne = NormalEquations()
    ne.update(G, q)
    sol = ne.solve()
    for r in range(3):
        ref, res, *_ = linalg.lstsq(G[r], q[r])
        assert np.allclose(sol.theta[r], ref, rtol=1e-12, atol=1e-14)
        assert np.isclose(sol.chi2[r], res, rtol=1e-9)
    a, b = NormalEquations(), NormalEquations()
    a.update(G[:, :20], q[:, :20])
    b.update(G[:, 20:], q[:, 20:])
    assert np.allclose((a + b).solve().theta, sol.theta, rtol=1e-12, atol=0)


def test_full_weights_equal_whitening_by_covariance():
    rng = np.random.default_rng(3)
    G, q = _problem(rng, R=4, k=6)
    A = rng.normal(size=(4, 6, 6))
    S = A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(6)
    w = NormalEquations()
    w.update(G, q, np.linalg.inv(S))
    c = NormalEquations()
    c.update(G, q, covariance=S)
    sw, sc = w.solve(), c.solve()
    _assert_same_solution(sw, sc, atol_theta=1e-12)
    # diagonal weights differ from unit weights (the test would catch ignored weights)
    u = NormalEquations()
    u.update(G, q)
    assert not np.allclose(u.solve().theta, sw.theta, rtol=1e-3)


def _assert_same_solution(a, b, atol_theta):
    """Two solves agree in θ, covariance and χ² to rel 1e-10 (round-off of 6×6 factorisations)."""
    assert np.allclose(a.theta, b.theta, rtol=1e-10, atol=atol_theta)
    assert np.allclose(a.covariance, b.covariance, rtol=1e-10, atol=0)
    assert np.allclose(a.chi2, b.chi2, rtol=1e-10)


def test_local_nuisance_elimination_equals_gls_with_inflated_covariance():
    """Woodbury: eliminating a block nuisance with prior P equals GLS with Σ + H P⁻¹ Hᵀ."""
    rng = np.random.default_rng(4)
    R, B, k, p = 3, 7, 8, 3
    G = rng.normal(size=(R, B, k, 3))
    H = rng.normal(size=(R, B, k, p))
    q = rng.normal(size=(R, B, k))
    sigma2, tau = 0.3**2, np.array([2.0, 0.5, 1.0])
    nu = NormalEquations()
    nu.update(G, q, np.full(q.shape, 1 / sigma2), nuisance=H, nuisance_information=np.diag(1 / tau**2))
    S = sigma2 * np.eye(k) + np.einsum("rbip,p,rbjp->rbij", H, tau**2, H)
    gls = NormalEquations()
    gls.update(G, q, covariance=S)
    a, b = nu.solve(), gls.solve()
    _assert_same_solution(a, b, atol_theta=1e-13)
    assert np.array_equal(a.dof, b.dof)


def test_shared_nuisance_eliminate_equals_full_solution():
    rng = np.random.default_rng(5)
    G = rng.normal(size=(2, 30, 5))
    q = rng.normal(size=(2, 30))
    ne = NormalEquations(n_params=5)
    ne.update(G, q)
    ne.add_prior(information=np.diag([0, 0, 0, 4.0, 9.0]) + 1e-300 * 0)
    full = ne.solve(check=False)
    red = ne.eliminate(3).solve()
    assert np.allclose(red.theta, full.theta[:, :3], rtol=1e-11, atol=1e-14)
    assert np.allclose(red.covariance, full.covariance[:, :3, :3], rtol=1e-10, atol=0)
    assert np.allclose(red.chi2, full.chi2, rtol=1e-10)


def test_prior_is_initial_information():
    rng = np.random.default_rng(6)
    G, q = _problem(rng, R=2, k=10)
    ne = NormalEquations()
    ne.add_prior(0.5, mean=[0.1, 0.2, 0.3])
    ne.update(G, q)
    sol = ne.solve()
    P = np.eye(3) / 0.25
    B = np.swapaxes(G, 1, 2) @ G + P
    y = np.einsum("rkn,rk->rn", G, q) + P @ np.array([0.1, 0.2, 0.3])
    assert np.allclose(sol.theta, np.linalg.solve(B, y[..., None])[..., 0], rtol=1e-12)
    assert sol.dof.tolist() == [10, 10]


def test_bad_input_messages():
    ne = NormalEquations()
    with pytest.raises(ValueError, match=r"G must have shape \(R, \.\.\., k, 3\), got \(4, 3\)"):
        ne.update(np.zeros((4, 3)), np.zeros(4))
    with pytest.raises(ValueError, match=r"q must have shape \(1, 4\)"):
        ne.update(np.zeros((1, 4, 3)), np.zeros((1, 5)))
    with pytest.raises(ValueError, match="diagonal weights must be ≥ 0"):
        ne.update(np.ones((1, 4, 3)), np.zeros((1, 4)), -np.ones((1, 4)))
    with pytest.raises(ObservabilityError, match="no observations"):
        NormalEquations().solve()
    assert issubclass(ObservabilityError, ValueError)
