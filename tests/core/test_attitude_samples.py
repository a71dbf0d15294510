"""The GLS on rows with the per-image errors on an attitude-sample table (boresight.core.gls.rows).

A pushbroom line is an image whose star-tracker error is the interpolation of its two bracketing tracker samples,
a_n = w_0 a_{s_0(n)} + w_1 a_{s_1(n)}, each sample's error with the prior N(0, E) (docs/architecture.md, "Thinking
ahead: stars and pushbroom lines"). The oracle is the dense full-Σ route written out here from that definition:
Σ = diag(1/w) + Z Zᵀ with Z's row k holding w_i A_k at sample s_i(n(k)), B_k at its pass and C_k at its target, the
GLS (XᵀΣ⁻¹X)⁻¹ XᵀΣ⁻¹q and the MAP nuisances (ZᵀWZ + E)⁻¹ ZᵀW(q − X x̂) — a second, independent route (a test oracle).
Tolerances: 1e-9 relative (the project's figure for two exact routes; the round-off is ~1e-13 on these sizes).
A frame camera is the one-sample case (samples [n, n], weights [1, 0]): through the sample code it equals the
image code to 1e-10 (round-off: the sample code assembles the reduced system sparse, in another order).
"""

import dataclasses

import numpy as np
import pytest
from gls_cases import rel, sample_lines, sample_Z, small_campaign
from oracles import dense_rows, on_grid

from boresight.core.algorithms import image_plane
from boresight.core.gls.rows import (
    RowStructure,
    _image_gram,
    row_gls,
    row_nuisances,
    row_reduced_rows,
    row_residuals,
    row_sandwich_middle,
)


def _oracle(st, cols, w):
    out = []
    for r in range(cols.q.shape[0]):
        Z = sample_Z(st, cols, r)
        Winv = np.repeat(1.0 / w[r], 2)
        Si = np.linalg.inv(np.diag(Winv) + Z @ Z.T)
        X, q = cols.X[r].reshape(-1, cols.X.shape[-1]), cols.q[r].reshape(-1)
        info, vec, wss = X.T @ Si @ X, X.T @ Si @ q, q @ Si @ q
        x = np.linalg.solve(info, vec)
        Wd = np.repeat(w[r], 2)
        nu = np.linalg.solve(Z.T @ (Wd[:, None] * Z) + np.eye(Z.shape[1]), Z.T @ (Wd * (q - X @ x)))
        out.append((info, vec, wss, x, nu))
    return out


@pytest.mark.parametrize("path", ["dense", "sparse"])
def test_two_sample_rows_equal_the_full_covariance(path):
    """Normal equations, the MAP sample/pass/target nuisances and the reduced rows against the full-Σ oracle."""
    st, cols = sample_lines()
    w = np.random.default_rng(5).uniform(0.3, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path=path)
    ne = fit.normal_equations
    sol = ne.solve(check=False)
    na, nb = cols.A.shape[-1], cols.B.shape[-1]
    S, P = st.n_samples, st.n_passes
    nu = row_nuisances(fit, sol.theta)
    for r, (info, vec, wss, x, nu_ref) in enumerate(_oracle(st, cols, w)):
        assert rel(ne.data_information[r], info) < 1e-9
        assert rel(ne.vector[r], vec) < 1e-9
        assert rel(ne.weighted_sum_squares[r], wss) < 1e-9
        assert rel(sol.theta[r], x) < 1e-9
        assert rel(nu.a_samples[r].ravel(), nu_ref[: S * na]) < 1e-9
        assert rel(nu.b[r].ravel(), nu_ref[S * na : S * na + P * nb]) < 1e-9
        assert rel(nu.c[r].ravel(), nu_ref[S * na + P * nb :]) < 1e-9
        # each image's a is its samples' interpolation
        a_img = (
            st.sample_weight[:, :1] * nu.a_samples[r][st.sample_index[:, 0]]
            + st.sample_weight[:, 1:] * nu.a_samples[r][st.sample_index[:, 1]]
        )
        assert rel(nu.a[r], a_img) < 1e-10
    # Σ w z̃ q̃ is the reduced right-hand side; the leverage h_i = z_iᵀ J⁻¹ z_i against the joint information
    h, zt = row_reduced_rows(fit, sol.covariance, leverage=True)
    assert rel(np.einsum("rk,rkj,rkjx->rx", w, cols.q, zt), ne.vector) < 1e-9
    for r in range(cols.q.shape[0]):
        Zr = np.concatenate([cols.X[r].reshape(-1, cols.X.shape[-1]), sample_Z(st, cols, r)], axis=1)  # [x | ν] per component
        n = cols.X.shape[-1]
        J = Zr.T @ (np.repeat(w[r], 2)[:, None] * Zr) + np.diag(np.r_[np.zeros(n), np.ones(Zr.shape[1] - n)])
        h_ref = np.einsum("ij,ji->i", Zr, np.linalg.solve(J, Zr.T))
        assert rel(h[r].ravel(), h_ref) < 1e-9
    # the residuals: q − X x̂ − Z ν̂ (pixel-σ units)
    e = row_residuals(fit, sol.theta)
    for r in range(cols.q.shape[0]):
        Z = sample_Z(st, cols, r)
        ref = cols.q[r].reshape(-1) - cols.X[r].reshape(-1, cols.X.shape[-1]) @ sol.theta[r] - Z @ _oracle(st, cols, w)[r][4]
        assert rel(e[r].reshape(-1), ref) < 1e-9


def test_sandwich_middle_and_image_gram_with_samples():
    """(WG)ᵀ Σ (WG) with per-sample errors, and the Gram with only the per-sample errors eliminated, against Σ."""
    st, cols = sample_lines(seed=3)
    WG = np.random.default_rng(1).normal(size=cols.X.shape)
    mid = row_sandwich_middle(st, WG, np.eye(2), cols.A, cols.B, cols.C)
    gram = _image_gram(st, cols, None)
    for r in range(cols.q.shape[0]):
        Z = sample_Z(st, cols, r)
        G = WG[r].reshape(-1, WG.shape[-1])
        assert rel(mid[r], G.T @ (np.eye(Z.shape[0]) + Z @ Z.T) @ G) < 1e-9
        Za = sample_Z(st, cols, r, with_b=False, with_c=False)[:, : st.n_samples * cols.A.shape[-1]]
        Y = np.concatenate([cols.X[r], cols.q[r][..., None]], axis=-1).reshape(-1, cols.X.shape[-1] + 1)
        assert rel(gram[r], Y.T @ np.linalg.solve(np.eye(Za.shape[0]) + Za @ Za.T, Y)) < 1e-9


@pytest.mark.parametrize("path", ["dense", "sparse"])
def test_a_frame_camera_is_the_one_sample_case(path):
    """A frame campaign's rows with samples [n, n] and weights [1, 0] (S = N), through the sample code, equal the
    image code: normal equations, nuisances, residuals of both kinds, reduced rows, sandwich middle, image Gram."""
    obs, model = small_campaign(n_pass=3, n_img=4, shared=True, runs=2, seed=1)
    model = dataclasses.replace(model, star_tracker_mode="both", gnss_mode="per_image", sigma_catalogue_m=5.0)
    th = np.full((2, 3), 5e-5)
    G, q = on_grid(image_plane.linearize, obs, th)  # small_campaign is a grid (tests/oracles.py)
    st, cols = dense_rows(obs, th, G, q, model)
    N = st.n_images
    st1 = dataclasses.replace(
        st, sample_index=np.stack([np.arange(N)] * 2, axis=1), sample_weight=np.tile([1.0, 0.0], (N, 1)), n_samples=N
    )
    assert st1.has_samples and not st.has_samples
    w = np.random.default_rng(2).uniform(0.2, 1.0, cols.q.shape[:2])
    f0, f1 = row_gls(st, cols, w, path=path), row_gls(st1, cols, w, path=path)
    for name in ("data_information", "vector", "weighted_sum_squares"):
        assert rel(getattr(f1.normal_equations, name), getattr(f0.normal_equations, name)) < 1e-10
    dx = f0.normal_equations.solve(check=False).theta
    n0, n1 = row_nuisances(f0, dx), row_nuisances(f1, dx)
    for a, b in ((n0.a, n1.a), (n0.a, n1.a_samples), (n0.b, n1.b), (n0.c, n1.c)):
        assert rel(b, a) < 1e-10
    for piw in (False, True):
        assert rel(row_residuals(f1, dx, piw), row_residuals(f0, dx, piw)) < 1e-10
    assert rel(row_reduced_rows(f1, None, leverage=False)[1], row_reduced_rows(f0, None, leverage=False)[1]) < 1e-10
    cov = f0.normal_equations.solve(check=False).covariance
    assert rel(row_reduced_rows(f1, cov)[0], row_reduced_rows(f0, cov)[0]) < 1e-10
    WG = cols.X
    assert (
        rel(
            row_sandwich_middle(st1, WG, np.eye(2), cols.A, cols.B, cols.C),
            row_sandwich_middle(st, WG, np.eye(2), cols.A, cols.B, cols.C),
        )
        < 1e-10
    )
    assert rel(_image_gram(st1, cols, w), _image_gram(st, cols, w)) < 1e-10


def test_sample_table_is_checked():
    """The three sample fields go together, have the images' length and index the samples."""
    img, tgt = np.array([0, 1]), np.array([0, 0])
    with pytest.raises(ValueError, match="all three or none"):
        RowStructure(img, tgt, np.zeros(2), 1, sample_index=np.zeros((2, 2), int))
    with pytest.raises(ValueError, match=r"must be \(2, 2\)"):
        RowStructure(img, tgt, np.zeros(2), 1, sample_index=np.zeros((3, 2), int), sample_weight=np.zeros((3, 2)), n_samples=2)
    with pytest.raises(ValueError, match="image 1's sample_index"):
        RowStructure(
            img, tgt, np.zeros(2), 1, sample_index=np.array([[0, 1], [1, 2]]), sample_weight=np.ones((2, 2)), n_samples=2
        )


def test_leverage_with_samples_by_solves_equals_the_inverse(monkeypatch):
    """Above ``LEVERAGE_MAX`` the sparse kernel's leverage comes from solves with its factor: on the sample system
    it equals the one from S⁻¹ formed whole (1e-9)."""
    from boresight.core.gls import rows

    st, cols = sample_lines(seed=7)
    w = np.random.default_rng(8).uniform(0.3, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path="sparse")
    cov = fit.normal_equations.solve(check=False).covariance
    h0 = row_reduced_rows(fit, cov)[0]
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 0)
    h1 = row_reduced_rows(row_gls(st, cols, w, path="sparse"), cov)[0]
    assert rel(h1, h0) < 1e-9
