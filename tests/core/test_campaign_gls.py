"""The one GLS on rows (boresight.core.gls.rows, its rows built by boresight.core.gls.campaign) against
the dense routes it replaces.

Two independent references: the dense route of the original ``estimate`` (per-image Cholesky
whitening of D_n, shared errors as augmented columns eliminated by a pseudo-inverse Schur
complement) and the full-Σ route of ``boresight.core.crlb`` (one dense Cholesky of all of a run's
residuals). Tolerance 1e-9 relative (max |Δ| / max |reference|), the issue's figure.
"""

import dataclasses

import numpy as np
import pytest
from gls_cases import EACH_DENSE_MODE, EACH_LINEARISER, MODES, full_gls, linearised_campaign, rel, small_campaign
from oracles import dense_gls_reference, dense_grid, dense_rows, on_grid

import orbits
from boresight import simulate
from boresight.core.algorithms import image_plane
from boresight.core.crlb import full_residual_covariance
from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.campaign import fit_rows, sandwich_middle
from boresight.core.gls.rows import row_gls, row_reduced_rows, row_residuals
from boresight.core.gls.structure import residual_variances

SCENARIO = "scenarios/campaign-6pass.toml"


@pytest.fixture(autouse=True)
def _single_threaded_blas():
    """The dense references are many mid-sized factorisations: a threaded BLAS on a shared
    machine makes them erratic, so they run single-threaded."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        yield


def gls(obs, th, G, q, model, L=None, w=None):
    """The GLS on rows of a dense set's G (R, N, M, 2, n), q, L and weights w (R, N, M): its mask's rows."""
    st, cols = dense_rows(obs, th, G, q, model, L)
    return row_gls(st, cols, None if w is None else np.asarray(w, float)[:, st.image_index, st.target_index])


def dense_gls(obs, theta, G, q, model, L=None):
    """The dense route of the original estimate (per-image whitening, shared nuisances eliminated)."""
    return dense_gls_reference(obs, theta, G, q, model, L).solve()


@pytest.mark.parametrize("k", range(len(MODES)), ids=[f"mode{i}-{'shared' if i % 2 else 'own'}" for i in range(len(MODES))])
def test_equal_to_full_covariance_gls(k):
    """Every error mode; odd cases with landmarks shared by two passes; 2 runs; masked landmarks."""
    obs, model = small_campaign(n_img=3, shared=bool(k % 2), runs=2, seed=k)
    assert (~obs.mask).any()
    model = dataclasses.replace(model, **MODES[k])
    th = np.full((2, 3), 5e-5)
    G, q = on_grid(image_plane.linearize, obs, th)
    sol = gls(obs, th, G, q, model).normal_equations.solve()
    theta_ref, cov_ref = full_gls(obs, th, G, q, model)
    assert rel(sol.theta, theta_ref) < 1e-9
    assert rel(sol.covariance, cov_ref) < 1e-9


@EACH_DENSE_MODE
@EACH_LINEARISER
def test_equal_to_dense_gls(alg, kw):
    obs, model, th, G, q, L = linearised_campaign(alg, kw)
    ne = gls(obs, th, G, q, model, L).normal_equations
    a, b = ne.solve(), dense_gls(obs, th, G, q, model, L)
    assert rel(a.theta, b.theta) < 1e-9
    assert rel(a.covariance, b.covariance) < 1e-9
    assert np.allclose(a.chi2, b.chi2, rtol=1e-9)
    assert np.array_equal(a.dof, b.dof)


def test_per_pass_mode_more_accurate_than_dense_route():
    """With per-pass errors only, θ and the pass bias are nearly confounded: the dense route's
    normal-equation Schur complement loses digits (measured ~1e-8), the square-root route not."""
    obs, model = small_campaign(seed=1)
    model = dataclasses.replace(model, star_tracker_mode="per_pass", gnss_mode="per_pass", sigma_catalogue_m=0.0)
    th = np.zeros((1, 3))
    G, q = on_grid(image_plane.linearize, obs, th)
    fast = gls(obs, th, G, q, model).normal_equations.solve()
    dense = dense_gls(obs, th, G, q, model)
    ref, cref = full_gls(obs, th, G, q, model)
    assert rel(fast.covariance, cref) < 1e-11
    assert rel(fast.covariance, cref) < rel(dense.covariance, cref)


@pytest.mark.slow
def test_full_campaign_equal_to_dense_gls():
    """The 120-image campaign itself (both modes, 128 landmarks): the estimate's normal equations."""
    sc = orbits.load_scenario(SCENARIO)
    obs = dense_grid(simulate(sc, np.random.default_rng(0)))
    assert obs.n_images == 120 and 1200 <= obs.n_observations <= 1400
    model = DisturbanceModel.from_scenario(sc)
    th = obs.truth["theta_rad"]
    G, q = on_grid(image_plane.linearize, obs, th)
    a = gls(obs, th, G, q, model).normal_equations.solve()
    b = dense_gls(obs, th, G, q, model)
    assert rel(a.covariance, b.covariance) < 1e-9
    assert rel(a.theta, b.theta) < 1e-9


def test_robust_weights_drop_rows():
    """A zero weight removes the observation exactly (equal to deleting it from the mask)."""
    obs, model = small_campaign(seed=5)
    th = np.zeros((1, 3))
    G, q = on_grid(image_plane.linearize, obs, th)
    n, m = np.argwhere(obs.mask)[7]
    w = np.ones((1,) + obs.mask.shape)
    w[0, n, m] = 0.0
    a = gls(obs, th, G, q, model, w=w).normal_equations
    mask = obs.mask.copy()
    mask[n, m] = False
    obs2 = dataclasses.replace(obs, mask=mask, xy_m=np.where(mask[None, :, :, None], obs.xy_m, 0.0))
    G2, q2 = on_grid(image_plane.linearize, obs2, th)
    b = gls(obs2, th, G2, q2, model).normal_equations
    assert rel(a.solve().theta, b.solve().theta) < 1e-12
    assert a.n_residuals[0] == b.n_residuals[0] == 2 * mask.sum()


def test_pixel_residuals_flag_an_outlier_and_are_unit_scale():
    """The pixel-level residuals of ``estimate``'s normalised residuals (``fit_rows`` + ``row_residuals``
    at dx = 0, one row per observation) point at an injected 20σ outlier and are unit scale elsewhere."""
    obs, model = small_campaign(n_pass=6, n_img=6, seed=2)
    th = obs.truth["theta_rad"]
    n, m = np.argwhere(obs.mask)[40]
    xy = obs.xy_m.copy()
    xy[0, n, m] += 20 * model.sigma_pixel_m
    rows = dataclasses.replace(obs, xy_m=xy).to_rows()
    G, q = image_plane.linearize(rows, th)
    e = row_residuals(fit_rows(rows, th, G, q, model), np.zeros((1, 3)))
    z = np.linalg.norm(e[0], axis=-1)
    assert (rows.image_index[np.argmax(z)], rows.target_index[np.argmax(z)]) == (n, m)
    zc = e[0][z < 10]
    # clean components: unit variance minus leverage (2·(6 + 6 + 3)·… parameters over the rows)
    assert 0.8 < zc.std() < 1.05


def test_sandwich_and_variances_match_dense_covariance():
    obs, model = small_campaign(seed=4, shared=True)
    rows = obs.to_rows()
    th = np.zeros((1, 3))
    G, _ = image_plane.linearize(rows, th)
    S = full_residual_covariance(rows, th, model)[0]
    var = residual_variances(rows, th, model)
    assert np.allclose(var[0].reshape(-1), np.diagonal(S), rtol=1e-12)
    W = np.random.default_rng(0).uniform(0.5, 2.0, size=G.shape[:-1])
    WG = G * W[..., None]
    mid = sandwich_middle(rows, th, model, WG)[0]
    Wg = WG[0].reshape(-1, 3)
    assert rel(mid, Wg.T @ S @ Wg) < 1e-11


@pytest.mark.parametrize("k", range(len(MODES)))
def test_reduced_rows_and_leverage(k):
    """``row_reduced_rows`` against two independent identities, every error mode, shared landmarks or not.

    (1) Σ_i w_i z̃_i q̃_i is the reduced right-hand side the fit accumulated (any weights w);
    (2) the leverage h_i is the response of the pixel-level residual to its own datum:
        ∂e_i/∂q̃_i = 1 − h_i (finite difference through a refit). Tolerance 1e-9 (round-off ~1e-12).
    """
    obs, model = small_campaign(n_pass=3, n_img=4, shared=bool(k % 2), runs=2)
    model = dataclasses.replace(model, **MODES[k])
    th = np.zeros((2, 3)) if obs.truth is None else obs.truth["theta_rad"]
    G, q = on_grid(image_plane.linearize, obs, th)
    w = np.where(obs.mask, np.random.default_rng(k).uniform(0.2, 1.0, (2,) + obs.mask.shape), 0.0)
    fit = gls(obs, th, G, q, model, w=w)
    h, zt = row_reduced_rows(fit, fit.normal_equations.solve().covariance)  # (R, K, 2), (R, K, 2, n)
    img, tgt = fit.structure.image_index, fit.structure.target_index
    ws = w[:, img, tgt]
    rhs = np.einsum("rk,rkc,rkcx->rx", ws, fit.columns.q, zt)
    assert rel(rhs, fit.normal_equations.vector) < 1e-9
    assert np.all((h >= 0) & (ws[..., None] * h < 1))  # w_i h_i is the weighted hat matrix's diagonal
    fit1 = gls(obs, th, G, q, model)
    sol1 = fit1.normal_equations.solve()
    h1, _ = row_reduced_rows(fit1, sol1.covariance)
    e0 = row_residuals(fit1, sol1.theta)
    d = 1e-3 * model.sigma_pixel_m
    for r_, k_ in [(0, 0), (5, 1), (img.size - 1, 0)]:
        q2 = q.copy()
        q2[:, img[r_], tgt[r_], k_] += d
        f2 = gls(obs, th, G, q2, model)
        e2 = row_residuals(f2, f2.normal_equations.solve().theta)
        de = (e2 - e0)[:, r_, k_] / (d / model.sigma_pixel_m)
        assert np.max(np.abs(de - (1 - h1[:, r_, k_]))) < 1e-9
