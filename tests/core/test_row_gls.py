"""The GLS on rows (boresight.core.gls.rows) against the slot-layout GLS and the dense oracles.

Every case of ``tests/core/test_campaign_gls.py`` (every error mode, landmarks shared by two
passes or not, robust weights, the three linearisers' residual maps) is solved on rows through the
dense adapter (``gls.campaign.dense_rows``) and compared with ``campaign_gls`` (square-root form)
and ``tests/oracles.py:dense_gls_reference``: normal equations, MAP-nuisance residuals (plain and
per-image whitened), leverages, reduced rows and the sandwich middle, all to 1e-9 relative (the
issue's figure; the information form's round-off is ≤ 3e-11 on these cases, module docstring of
``rows``). Then the two linear-algebra kernels (dense Cholesky, SuperLU) equal to round-off (1e-10)
on a campaign of single-use targets and on a large synthetic bundle-adjustment structure.
"""

import dataclasses

import numpy as np
import pytest
from oracles import dense_gls_reference
from test_campaign_gls import MODES, full_gls, rel, small_campaign

from boresight.core.algorithms import ground_plane, image_plane, unit_vector
from boresight.core.gls.campaign import (
    campaign_gls,
    dense_rows,
    pixel_residuals,
    reduced_rows,
    sandwich_middle,
    solve_nuisances,
)
from boresight.core.gls.rows import (
    RowColumns,
    RowStructure,
    row_gls,
    row_nuisances,
    row_reduced_rows,
    row_residuals,
    row_sandwich_middle,
)
from boresight.core.gls.structure import error_columns, pixel_covariance
from boresight.errors import UnsupportedComputationError


@pytest.fixture(autouse=True)
def _single_threaded_blas():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        yield


def _slots_to_rows(fit, a):
    idx, valid = fit.slots
    nn, ss = np.nonzero(valid)
    return a[:, nn, ss]


def _ne_equal(a, b, tol=1e-9):
    assert rel(a.data_information, b.data_information) < tol
    assert rel(a.vector, b.vector) < tol
    assert rel(a.weighted_sum_squares, b.weighted_sum_squares) < tol
    assert np.array_equal(a.n_residuals, b.n_residuals)


@pytest.mark.parametrize("k", range(len(MODES)), ids=[f"mode{i}-{'shared' if i % 2 else 'own'}" for i in range(len(MODES))])
def test_rows_equal_slot_gls_and_full_covariance(k):
    """Normal equations, residuals (both kinds), leverages and reduced rows; weights; 2 runs."""
    obs, model = small_campaign(n_pass=3, n_img=4, shared=bool(k % 2), runs=2, seed=k)
    model = dataclasses.replace(model, **MODES[k])
    th = np.full((2, 3), 5e-5)
    G, q = image_plane.linearize(obs, th)
    st, cols = dense_rows(obs, th, G, q, model)
    fit = row_gls(st, cols)
    old = campaign_gls(obs, th, G, q, model)
    _ne_equal(fit.normal_equations, old.normal_equations)
    sol = fit.normal_equations.solve()
    theta_ref, cov_ref = full_gls(obs, th, G, q, model)
    assert rel(sol.theta, theta_ref) < 1e-9 and rel(sol.covariance, cov_ref) < 1e-9
    assert rel(fit.image_gram, old.image_gram) < 1e-9
    for piw in (False, True):
        e_old = _slots_to_rows(old, solve_nuisances(old, sol.theta, per_image_whitened=piw))
        assert rel(row_residuals(fit, sol.theta, per_image_whitened=piw), e_old) < 1e-9
    w = np.where(obs.mask, np.random.default_rng(k).uniform(0.2, 1.0, (2,) + obs.mask.shape), 0.0)
    wr = w[:, st.image_index, st.target_index]
    fitw, oldw = row_gls(st, cols, wr), campaign_gls(obs, th, G, q, model, obs_weights=w)
    _ne_equal(fitw.normal_equations, oldw.normal_equations)
    cov = oldw.normal_equations.solve().covariance
    h, zt = row_reduced_rows(fitw, cov)
    h_old, zt_old = reduced_rows(oldw, cov)
    assert rel(h, _slots_to_rows(oldw, h_old)) < 1e-9
    assert rel(zt, _slots_to_rows(oldw, zt_old)) < 1e-9
    e_old = _slots_to_rows(oldw, solve_nuisances(oldw, sol.theta))
    assert rel(row_residuals(fitw, sol.theta), e_old) < 1e-9
    # the sparse kernel: same normal equations, nuisances and reduced rows; the leverage refused
    fits = row_gls(st, cols, wr, path="sparse")
    _ne_equal(fits.normal_equations, fitw.normal_equations, 1e-10)
    assert rel(row_residuals(fits, sol.theta), row_residuals(fitw, sol.theta)) < 1e-10
    assert rel(row_reduced_rows(fits, None, leverage=False)[1], zt) < 1e-10
    if cols.A.shape[-1] + cols.B.shape[-1]:  # an image/pass system to factorise sparsely
        with pytest.raises(UnsupportedComputationError, match="selected inverse"):
            row_reduced_rows(fits, cov)
    else:
        assert rel(row_reduced_rows(fits, cov)[0], h) < 1e-10


@pytest.mark.parametrize("kw", [MODES[0], MODES[1], MODES[3], MODES[5]], ids=["both", "per_image", "mixed", "catalogue"])
@pytest.mark.parametrize("alg", [image_plane, ground_plane, unit_vector], ids=["image_plane", "ground_plane", "unit_vector"])
def test_rows_equal_dense_reference(alg, kw):
    """Residual maps (2 × 2 pixel whitening per row) and the sandwich middle."""
    obs, model = small_campaign(n_img=3, shared=True, seed=3)
    model = dataclasses.replace(model, **kw)
    th = np.zeros((1, 3))
    G, q = alg.linearize(obs, th)
    L = None if alg is image_plane else alg.residual_map(obs, th)
    st, cols = dense_rows(obs, th, G, q, model, L)
    a, b = row_gls(st, cols).normal_equations.solve(), dense_gls_reference(obs, th, G, q, model, L).solve()
    assert rel(a.theta, b.theta) < 1e-9 and rel(a.covariance, b.covariance) < 1e-9
    assert np.allclose(a.chi2, b.chi2, rtol=1e-9) and np.array_equal(a.dof, b.dof)
    WG = G * np.random.default_rng(0).uniform(0.5, 2.0, size=G.shape[:-1])[..., None]
    nn, mm = st.image_index, st.target_index
    Ld = None if L is None else L[:, nn, mm]
    A, B, C = (None if Z is None else Z[:, nn, mm] for Z in error_columns(obs, th, model, L))
    mid = row_sandwich_middle(st, WG[:, nn, mm], pixel_covariance(model, Ld), A, B, C)
    assert rel(mid, sandwich_middle(obs, th, model, WG, L)) < 1e-11


def _single_use(obs):
    """Every observation its own landmark (a ground-control point seen once)."""
    nn, mm = np.nonzero(obs.mask)
    K = nn.size
    mask = np.zeros((obs.n_images, K), bool)
    mask[nn, np.arange(K)] = True
    xy = np.zeros((obs.runs, obs.n_images, K, 2))
    xy[:, nn, np.arange(K)] = obs.xy_m[:, nn, mm]
    return dataclasses.replace(
        obs,
        landmark_ids=np.array([f"G{k}" for k in range(K)]),
        landmark_g_m=obs.landmark_g_m[:, mm],
        xy_m=xy,
        mask=mask,
        truth=None,
    )


def test_single_use_targets_folded_into_rows():
    """Single-use targets (step 1's fold) equal the slot GLS carrying each catalogue error; weights."""
    obs0, model = small_campaign(n_pass=2, n_img=3, seed=7)
    obs = _single_use(obs0)
    th = np.zeros((1, 3))
    G, q = image_plane.linearize(obs, th)
    w = np.where(obs.mask, np.random.default_rng(1).uniform(0.0, 1.0, (1,) + obs.mask.shape), 0.0)
    st, cols = dense_rows(obs, th, G, q, model)
    assert np.all(np.bincount(st.target_index) == 1)
    wr = w[:, st.image_index, st.target_index]
    for path in ("dense", "sparse"):
        fit, old = row_gls(st, cols, wr, path=path), campaign_gls(obs, th, G, q, model, obs_weights=w)
        _ne_equal(fit.normal_equations, old.normal_equations)
        cov = old.normal_equations.solve().covariance
        dx = old.normal_equations.solve().theta
        assert rel(row_residuals(fit, dx), _slots_to_rows(old, solve_nuisances(old, dx))) < 1e-9
        h_old, zt_old = reduced_rows(old, cov)
        assert rel(row_reduced_rows(fit, cov, leverage=path == "dense")[1], _slots_to_rows(old, zt_old)) < 1e-9
        if path == "dense":
            assert rel(row_reduced_rows(fit, cov)[0], _slots_to_rows(old, h_old)) < 1e-9
    e, _ = pixel_residuals(obs, th, G, q, model, obs_weights=w)
    assert rel(row_residuals(row_gls(st, cols, wr), np.zeros((1, 3))), e[:, st.image_index, st.target_index]) < 1e-9


def _synthetic_ba(n_images=400, n_targets=2000, seen=5, n_pass=4, n=4, runs=1, seed=0):
    """A strip: target t seen by `seen` consecutive images; random whitened columns (na = nb = 6)."""
    rng = np.random.default_rng(seed)
    first = rng.integers(0, n_images - seen + 1, n_targets)
    img = (first[:, None] + np.arange(seen)).ravel()
    tgt = np.repeat(np.arange(n_targets), seen)
    order = np.lexsort((tgt, img))
    img, tgt = img[order], tgt[order]
    K = img.size
    st = RowStructure(img, tgt, np.arange(n_images) * n_pass // n_images, n_targets)
    cols = RowColumns(
        X=rng.normal(size=(runs, K, 2, n)),
        q=rng.normal(size=(runs, K, 2)),
        A=0.3 * rng.normal(size=(runs, K, 2, 6)),
        B=0.05 * rng.normal(size=(runs, K, 2, 6)),
        C=0.5 * rng.normal(size=(runs, K, 2, 3)),
    )
    return st, cols


def test_dense_and_sparse_paths_equal_on_a_large_structure():
    """2 424 nuisances of images and passes, 2 000 shared targets, 10 000 rows, 2 runs: SuperLU
    (symmetric mode, minimum degree) equal to the batched dense Cholesky to round-off."""
    st, cols = _synthetic_ba(runs=2)
    w = np.random.default_rng(3).uniform(0.0, 1.0, cols.q.shape[:2])
    dense, sparse = row_gls(st, cols, w, path="dense"), row_gls(st, cols, w, path="sparse")
    _ne_equal(sparse.normal_equations, dense.normal_equations, 1e-10)
    dx = dense.normal_equations.solve(check=False).theta
    nd, ns = row_nuisances(dense, dx), row_nuisances(sparse, dx)
    for a, b in ((nd.a, ns.a), (nd.b, ns.b), (nd.c, ns.c)):
        assert rel(b, a) < 1e-10
    assert rel(row_residuals(sparse, dx, per_image_whitened=True), row_residuals(dense, dx, per_image_whitened=True)) < 1e-10
    assert rel(row_reduced_rows(sparse, None, leverage=False)[1], row_reduced_rows(dense, None, leverage=False)[1]) < 1e-10
