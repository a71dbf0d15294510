"""A star tracker's Gauss–Markov error in the one GLS: per-sample nuisances with the AR(1) prior (boresight.core.gls.rows).

A per-sample nuisance column with ``RowStructure.sample_correlation`` φ_s = exp(−Δt_s/τ) is a unit-variance AR(1)
over the samples, whose prior information is tridiagonal (``gls.rows`` module docstring). The oracle here is the dense
full-Σ route written from the *covariance*, not from φ: Σ = diag(1/w) + Z K_ν Zᵀ with K_ν's correlated column
exp(−|t_s − t_m|/τ) within a segment of samples (0 across segments), E on the white columns, the pass and target
blocks — the GLS (XᵀΣ⁻¹X)⁻¹XᵀΣ⁻¹q, the MAP nuisances K_ν Zᵀ Σ⁻¹ (q − X x̂), the leverage against the joint information
with the prior K_ν⁻¹ (a second, independent route: a test oracle). Tolerance 1e-9 relative, the project's figure for
two exact routes (round-off ~1e-13 at these sizes; K_ν's condition ~1e3 at the shortest τ).
"""

import dataclasses

import numpy as np
import pytest
from gls_cases import rel, sample_lines, sample_Z

from boresight.core.gls.rows import (
    _image_gram,
    _image_sample_scale,
    row_gls,
    row_nuisances,
    row_reduced_rows,
    row_residuals,
    row_sandwich_middle,
)
from boresight.errors import InputValueError

#: sample times (s, uneven) of the 9 samples of ``sample_lines``, and the segment each belongs to (two processes)
T_S = np.cumsum([0.0, 0.5, 0.3, 0.9, 0.25, 0.0, 0.6, 0.4, 0.7]) + np.array([0, 0, 0, 0, 0, 10, 10, 10, 10])
SEGMENT = np.array([0, 0, 0, 0, 0, 1, 1, 1, 1])
#: correlation time of each per-sample column (inf: white)
TAU_S = (np.inf, 2.0, 0.7)


def _correlated(st):
    """The structure with φ_s = exp(−Δt_s/τ_j) per column (0 at each segment's first sample, and on white columns)."""
    dt = np.diff(T_S, prepend=T_S[0])
    new = np.r_[True, SEGMENT[1:] != SEGMENT[:-1]]
    phi = np.stack([np.zeros(T_S.size) if np.isinf(tau) else np.exp(-dt / tau) for tau in TAU_S], axis=1)
    phi[new] = 0.0
    return dataclasses.replace(st, sample_correlation=phi)


def _prior_covariance(S, na, nb, P, T):
    """K_ν (S·na + P·nb + 3T square) from the times: exp(−|t_s − t_m|/τ) within a segment, E elsewhere (the oracle)."""
    D = S * na + P * nb + 3 * T
    K = np.eye(D)
    same = SEGMENT[:, None] == SEGMENT[None, :]
    for j, tau in enumerate(TAU_S):
        if np.isfinite(tau):
            idx = np.arange(S) * na + j
            K[np.ix_(idx, idx)] = np.where(same, np.exp(-np.abs(T_S[:, None] - T_S[None, :]) / tau), 0.0)
    return K


@pytest.mark.parametrize("path", ["dense", "sparse"])
def test_correlated_samples_equal_the_full_covariance(path):
    """Normal equations, θ, the MAP sample/pass/target nuisances, leverage, reduced rows and residuals against Σ."""
    st, cols = sample_lines(seed=11)
    st = _correlated(st)
    w = np.random.default_rng(6).uniform(0.3, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path=path)
    ne = fit.normal_equations
    sol = ne.solve(check=False)
    nu = row_nuisances(fit, sol.theta)
    h, zt = row_reduced_rows(fit, sol.covariance, leverage=True)
    e = row_residuals(fit, sol.theta)
    na, nb, n = cols.A.shape[-1], cols.B.shape[-1], cols.X.shape[-1]
    S, P = st.n_samples, st.n_passes
    Kv = _prior_covariance(S, na, nb, P, st.n_targets)
    for r in range(cols.q.shape[0]):
        Z = sample_Z(st, cols, r)
        Si = np.linalg.inv(np.diag(np.repeat(1.0 / w[r], 2)) + Z @ Kv @ Z.T)
        X, q = cols.X[r].reshape(-1, n), cols.q[r].reshape(-1)
        info, vec = X.T @ Si @ X, X.T @ Si @ q
        x = np.linalg.solve(info, vec)
        assert rel(ne.data_information[r], info) < 1e-9
        assert rel(ne.vector[r], vec) < 1e-9
        assert rel(ne.weighted_sum_squares[r], q @ Si @ q) < 1e-9
        assert rel(sol.theta[r], x) < 1e-9
        nu_ref = Kv @ Z.T @ Si @ (q - X @ x)
        assert rel(nu.a_samples[r].ravel(), nu_ref[: S * na]) < 1e-9
        assert rel(nu.b[r].ravel(), nu_ref[S * na : S * na + P * nb]) < 1e-9
        assert rel(nu.c[r].ravel(), nu_ref[S * na + P * nb :]) < 1e-9
        assert rel(e[r].reshape(-1), q - X @ x - Z @ nu_ref) < 1e-9
        # the leverage against the joint information of [x | ν] with the prior K_ν⁻¹
        Zr = np.concatenate([X, Z], axis=1)
        J = Zr.T @ (np.repeat(w[r], 2)[:, None] * Zr)
        J[n:, n:] += np.linalg.inv(Kv)
        assert rel(h[r].ravel(), np.einsum("ij,ji->i", Zr, np.linalg.solve(J, Zr.T))) < 1e-9
    assert rel(np.einsum("rk,rkj,rkjx->rx", w, cols.q, zt), ne.vector) < 1e-9


def test_sandwich_image_gram_and_image_scale_with_correlated_samples():
    """(WG)ᵀ Σ (WG), the Gram with only the per-sample errors eliminated, and each image's interpolated σ, against K_ν."""
    st, cols = sample_lines(seed=12)
    st = _correlated(st)
    na = cols.A.shape[-1]
    S = st.n_samples
    WG = np.random.default_rng(1).normal(size=cols.X.shape)
    mid = row_sandwich_middle(st, WG, np.eye(2), cols.A, cols.B, cols.C)
    gram = _image_gram(st, cols, None)
    Kv = _prior_covariance(S, na, cols.B.shape[-1], st.n_passes, st.n_targets)
    Ka = Kv[: S * na, : S * na]
    for r in range(cols.q.shape[0]):
        Z = sample_Z(st, cols, r)
        G = WG[r].reshape(-1, WG.shape[-1])
        assert rel(mid[r], G.T @ (np.eye(Z.shape[0]) + Z @ Kv @ Z.T) @ G) < 1e-9
        Za = Z[:, : S * na]
        Y = np.concatenate([cols.X[r], cols.q[r][..., None]], axis=-1).reshape(-1, cols.X.shape[-1] + 1)
        assert rel(gram[r], Y.T @ np.linalg.solve(np.eye(Za.shape[0]) + Za @ Ka @ Za.T, Y)) < 1e-9
    scale = _image_sample_scale(st, na)
    for n in range(st.n_images):
        for j in range(na):
            idx = st.sample_index[n] * na + j
            var = st.sample_weight[n] @ Ka[np.ix_(idx, idx)] @ st.sample_weight[n]
            assert abs(scale[n, j] - np.sqrt(var)) < 1e-12


def test_no_correlation_is_the_white_prior_bit_for_bit():
    """φ = 0 on every column (``sample_correlation`` zeros) gives the white prior's normal equations (to round-off), and
    None is the white code itself."""
    st, cols = sample_lines(seed=13)
    f0 = row_gls(st, cols, path="sparse")
    f1 = row_gls(dataclasses.replace(st, sample_correlation=np.zeros((st.n_samples, cols.A.shape[-1]))), cols, path="sparse")
    for name in ("data_information", "vector", "weighted_sum_squares"):
        assert rel(getattr(f1.normal_equations, name), getattr(f0.normal_equations, name)) < 1e-13


def test_sample_correlation_is_checked():
    """φ in [0, 1), 0 at sample 0, one row per sample, and as many columns as A."""
    st, cols = sample_lines(seed=14)
    S, na = st.n_samples, cols.A.shape[-1]
    with pytest.raises(InputValueError, match=r"must be \(9, na\)"):
        dataclasses.replace(st, sample_correlation=np.zeros((S - 1, na)))
    bad = np.zeros((S, na))
    bad[3, 1] = 1.0
    with pytest.raises(InputValueError, match=r"sample_correlation\[3, 1\] = 1.0"):
        dataclasses.replace(st, sample_correlation=bad)
    bad = np.zeros((S, na))
    bad[0, 2] = 0.5
    with pytest.raises(InputValueError, match=r"sample_correlation\[0, 2\]"):
        dataclasses.replace(st, sample_correlation=bad)
    with pytest.raises(InputValueError, match="the per-sample columns A 3"):
        row_gls(dataclasses.replace(st, sample_correlation=np.zeros((S, na + 1))), cols)


def test_leverage_by_solves_with_correlated_samples(monkeypatch):
    """Above ``LEVERAGE_MAX`` the leverage comes from solves with the SuperLU factor: with the AR(1) prior it equals the
    one from S⁻¹ formed whole (1e-9)."""
    from boresight.core.gls import rows

    st, cols = sample_lines(seed=15)
    st = _correlated(st)
    w = np.random.default_rng(9).uniform(0.3, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path="sparse")
    cov = fit.normal_equations.solve(check=False).covariance
    h0 = row_reduced_rows(fit, cov)[0]
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 0)
    assert rel(row_reduced_rows(row_gls(st, cols, w, path="sparse"), cov)[0], h0) < 1e-9
