"""The GLS on rows (boresight.core.gls.rows) against the dense oracles, and its two kernels.

Every case of ``tests/core/test_campaign_gls.py`` (every error mode, landmarks shared by two
passes or not, robust weights, the three linearisers' residual maps) is solved on rows through the
one builder (``gls.campaign.row_problem``, through ``oracles.dense_rows``) and compared with the full-Σ route
(``crlb.full_residual_covariance``) and ``tests/oracles.py:dense_gls_reference`` to 1e-9 relative
(the issue's figure; the round-off is ≤ 5e-13 on these cases, module docstring of ``rows``; the
sandwich middle is checked against the full Σ in ``test_campaign_gls.py``). Then the two
linear-algebra kernels (dense Cholesky, SuperLU) equal to round-off (1e-10) on every case, on a
campaign of single-use targets and on a large synthetic bundle-adjustment structure.
"""

import dataclasses

import numpy as np
import pytest
from gls_cases import EACH_DENSE_MODE, EACH_LINEARISER, MODES, full_gls, linearised_campaign, rel, small_campaign
from oracles import dense_gls_reference, dense_rows, on_grid

from boresight.core.algorithms import image_plane
from boresight.core.gls import rows
from boresight.core.gls.rows import (
    RowColumns,
    RowStructure,
    row_gls,
    row_nuisances,
    row_reduced_rows,
    row_residuals,
)


@pytest.fixture(autouse=True)
def _single_threaded_blas():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        yield


def _ne_equal(a, b, tol=1e-9):
    assert rel(a.data_information, b.data_information) < tol
    assert rel(a.vector, b.vector) < tol
    assert rel(a.weighted_sum_squares, b.weighted_sum_squares) < tol
    assert np.array_equal(a.n_residuals, b.n_residuals)


@pytest.mark.parametrize("k", range(len(MODES)), ids=[f"mode{i}-{'shared' if i % 2 else 'own'}" for i in range(len(MODES))])
def test_rows_equal_full_covariance_and_paths_agree(k, monkeypatch):
    """θ and its covariance against the full-Σ route; with robust weights the reduced rows satisfy
    Σ w z̃ q̃ = the reduced right-hand side, and the sparse kernel equals the dense one (1e-10:
    normal equations, residuals of both kinds, reduced rows, leverage, the latter also by the
    sparse kernel's solves above ``LEVERAGE_MAX``).
    (The slot-layout GLS this replaced agreed to ≤ 2e-10 on the same cases: commit 326a099.)"""
    obs, model = small_campaign(n_pass=3, n_img=4, shared=bool(k % 2), runs=2, seed=k)
    model = dataclasses.replace(model, **MODES[k])
    th = np.full((2, 3), 5e-5)
    G, q = on_grid(image_plane.linearize, obs, th)
    st, cols = dense_rows(obs, th, G, q, model)
    sol = row_gls(st, cols).normal_equations.solve()
    theta_ref, cov_ref = full_gls(obs, th, G, q, model)
    assert rel(sol.theta, theta_ref) < 1e-9 and rel(sol.covariance, cov_ref) < 1e-9
    wr = np.random.default_rng(k).uniform(0.2, 1.0, cols.q.shape[:2])
    fitw = row_gls(st, cols, wr, path="dense")
    cov = fitw.normal_equations.solve().covariance
    h, zt = row_reduced_rows(fitw, cov)
    assert rel(np.einsum("rk,rkj,rkjx->rx", wr, cols.q, zt), fitw.normal_equations.vector) < 1e-9
    assert np.all((h >= 0) & (wr[..., None] * h < 1))
    fits = row_gls(st, cols, wr, path="sparse")
    _ne_equal(fits.normal_equations, fitw.normal_equations, 1e-10)
    for piw in (False, True):
        assert rel(row_residuals(fits, sol.theta, piw), row_residuals(fitw, sol.theta, piw)) < 1e-10
    assert rel(row_reduced_rows(fits, None, leverage=False)[1], zt) < 1e-10
    assert rel(row_reduced_rows(fits, cov)[0], h) < 1e-10  # S⁻¹ from the LU factors
    # above LEVERAGE_MAX the sparse kernel solves S X = Z̄ per residual component (a batch of one row
    # and of several: the batches' bookkeeping)
    # (the band selected inverse, then, with it refused, SuperLU's solves)
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 0)
    for band_bytes in (2.0**28, 0.0):
        monkeypatch.setattr(rows, "SELECTED_INVERSE_MAX_BYTES", band_bytes)
        for batch in (2, 10**6):
            monkeypatch.setattr(rows, "LEVERAGE_SOLVE_ELEMENTS", batch)
            h2, zt2 = row_reduced_rows(row_gls(st, cols, wr, path="sparse"), cov)
            assert rel(h2, h) < 1e-10 and rel(zt2, zt) < 1e-10


@EACH_DENSE_MODE
@EACH_LINEARISER
def test_rows_equal_dense_reference(alg, kw):
    """Residual maps (2 × 2 pixel whitening per row)."""
    obs, model, th, G, q, L = linearised_campaign(alg, kw)
    st, cols = dense_rows(obs, th, G, q, model, L)
    a, b = row_gls(st, cols).normal_equations.solve(), dense_gls_reference(obs, th, G, q, model, L).solve()
    assert rel(a.theta, b.theta) < 1e-9 and rel(a.covariance, b.covariance) < 1e-9
    assert np.allclose(a.chi2, b.chi2, rtol=1e-9) and np.array_equal(a.dof, b.dof)


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
    """Single-use targets (step 1's fold) against the dense oracle carrying every catalogue error as
    a column; a zero weight equals deleting the row; the leverage equals the response of the
    pixel-level residual to its own datum, ∂e_i/∂q̃_i = 1 − h_i (e is linear in q: exact
    difference), on both paths for e and on the dense path for h."""
    obs0, model = small_campaign(n_pass=2, n_img=3, seed=7)
    obs = _single_use(obs0)
    th = np.zeros((1, 3))
    G, q = on_grid(image_plane.linearize, obs, th)
    st, cols = dense_rows(obs, th, G, q, model)
    assert np.all(np.bincount(st.target_index) == 1)
    a, b = row_gls(st, cols).normal_equations.solve(), dense_gls_reference(obs, th, G, q, model).solve()
    assert rel(a.theta, b.theta) < 1e-9 and rel(a.covariance, b.covariance) < 1e-9
    assert np.allclose(a.chi2, b.chi2, rtol=1e-9) and np.array_equal(a.dof, b.dof)
    wr = np.ones(cols.q.shape[:2])
    wr[0, 5] = 0.0
    keep = np.arange(st.n_rows) != 5
    st2 = RowStructure(st.image_index[keep], st.target_index[keep], st.pass_index, st.n_targets)
    cols2 = RowColumns(*(Z[:, keep] for Z in (cols.X, cols.q, cols.A, cols.B, cols.C)))
    for path in ("dense", "sparse"):
        _ne_equal(row_gls(st, cols, wr, path=path).normal_equations, row_gls(st2, cols2, path=path).normal_equations, 1e-10)
    fit = row_gls(st, cols)
    sol = fit.normal_equations.solve()
    h, _ = row_reduced_rows(fit, sol.covariance)
    e0 = row_residuals(fit, sol.theta)
    for k, j in [(0, 0), (17, 1), (st.n_rows - 1, 0)]:
        q2 = cols.q.copy()
        q2[0, k, j] += 1.0
        for path in ("dense", "sparse"):
            f2 = row_gls(st, dataclasses.replace(cols, q=q2), path=path)
            de = (row_residuals(f2, f2.normal_equations.solve().theta) - e0)[0, k, j]
            assert abs(de - (1 - h[0, k, j])) < 1e-9


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


def test_condition_bound_bounds_the_reduced_system():
    """``RowFit.condition_bound`` ≥ cond(S) (λ_min(S) ≥ 1 by the prior, Gershgorin above), S formed
    densely from S⁻¹ of the fit; every error mode with an image/pass system."""
    for k in (0, 1, 2, 4):
        obs, model = small_campaign(n_pass=3, n_img=4, shared=bool(k % 2), runs=2, seed=k)
        model = dataclasses.replace(model, **MODES[k])
        th = np.zeros((2, 3))
        G, q = on_grid(image_plane.linearize, obs, th)
        st, cols = dense_rows(obs, th, G, q, model)
        fit = row_gls(st, cols, path="dense")
        lam = np.linalg.eigvalsh(rows._S_inverse(fit))  # eigenvalues of S⁻¹
        assert np.all(lam[:, -1] <= 1 + 1e-9)  # λ_min(S) ≥ 1
        assert np.all(fit.condition_bound >= lam[:, -1] / lam[:, 0] * (1 - 1e-9))  # ≥ cond(S)
        assert np.all(fit.condition_bound < 1e10) and rows.condition_warning(fit) is None
    # a pixel σ 10⁴ times smaller (every nuisance column ×10⁴ in pixel-σ units): the bound grows as 10⁸,
    # past the threshold, and says so
    big = dataclasses.replace(model, sigma_pixel_m=1e-4 * model.sigma_pixel_m)
    fit2 = row_gls(*dense_rows(obs, th, G, q, big), path="dense")
    assert np.all(fit2.condition_bound > 1e10)
    assert "ill-conditioned" in rows.condition_warning(fit2) and "run 0" in rows.condition_warning(fit2)


def test_leverage_above_leverage_max_equals_the_whole_inverse(monkeypatch):
    """A strip with D = 700·6 + 4·6 = 4 224 > ``LEVERAGE_MAX`` image/pass unknowns, shared and
    single-use targets, 2 runs, robust weights: the leverage from the band selected inverse (the
    default above 4 000) and by SuperLU solves (the fallback) equal the one from S⁻¹ formed whole
    (``LEVERAGE_MAX`` raised for the comparison) to 1e-9 relative, and every leverage is in [0, 1/w)."""
    st, cols = _synthetic_ba(n_images=700, n_targets=900, seen=3, runs=2, seed=5)
    # targets 0 … 59 single-use: keep only the first row of each
    k0 = np.flatnonzero(st.target_index < 60)
    _, first = np.unique(st.target_index[k0], return_index=True)
    keep = np.ones(st.n_rows, bool)
    keep[np.setdiff1d(k0, k0[first])] = False
    st = RowStructure(st.image_index[keep], st.target_index[keep], st.pass_index, st.n_targets)
    cols = RowColumns(*(Z[:, keep] for Z in (cols.X, cols.q, cols.A, cols.B, cols.C)))
    D = st.n_images * 6 + st.n_passes * 6
    assert D > rows.LEVERAGE_MAX == 4000
    w = np.random.default_rng(4).uniform(0.2, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path="sparse")
    cov = fit.normal_equations.solve(check=False).covariance
    h, zt = row_reduced_rows(fit, cov)  # the band selected inverse (half-width 29 after reverse Cuthill–McKee)
    assert rows._selected_inverse(fit) is not None
    monkeypatch.setattr(rows, "SELECTED_INVERSE_MAX_BYTES", 0.0)
    h_solves, _ = row_reduced_rows(fit, cov)  # SuperLU's solves
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 10**6)
    h_ref, zt_ref = row_reduced_rows(row_gls(st, cols, w, path="sparse"), cov)
    assert rel(h, h_ref) < 1e-9 and rel(h_solves, h_ref) < 1e-9 and rel(zt, zt_ref) < 1e-9
    assert np.all((h >= 0) & (w[..., None] * h < 1))


def _islands(n_pass=5):
    """Passes that share no target: each its own 50 targets seen 3 times within the pass (40 images), targets
    0 … 19 single-use (their first row kept); 2 runs, random whitened columns (``_synthetic_ba``)."""
    parts = [_synthetic_ba(n_images=40, n_targets=50, seen=3, n_pass=1, runs=2, seed=10 + p) for p in range(n_pass)]
    img = np.concatenate([st_p.image_index + 40 * p for p, (st_p, _) in enumerate(parts)])
    tgt = np.concatenate([st_p.target_index + 50 * p for p, (st_p, _) in enumerate(parts)])
    st = RowStructure(img, tgt, np.repeat(np.arange(n_pass), 40), 50 * n_pass)
    cols = RowColumns(*(np.concatenate([getattr(c, n) for _, c in parts], axis=1) for n in ("X", "q", "A", "B", "C")))
    k0 = np.flatnonzero(st.target_index < 20)
    _, first = np.unique(st.target_index[k0], return_index=True)
    keep = np.ones(st.n_rows, bool)
    keep[np.setdiff1d(k0, k0[first])] = False
    st = RowStructure(st.image_index[keep], st.target_index[keep], st.pass_index, st.n_targets)
    return st, RowColumns(*(Z[:, keep] for Z in (cols.X, cols.q, cols.A, cols.B, cols.C)))


def test_leverage_of_independent_passes_from_their_blocks(monkeypatch):
    """Passes that share no target (``_islands``): S falls apart into one block per pass (its images and
    its pass unknowns), and above ``LEVERAGE_MAX`` the leverage comes from those blocks inverted whole
    (``_BlockInverse``), equal to S⁻¹ formed whole to 1e-9 relative (2 runs, robust weights); a block above
    ``LEVERAGE_MAX`` falls back to the band selected inverse."""
    st, cols = _islands()
    w = np.random.default_rng(4).uniform(0.2, 1.0, cols.q.shape[:2])
    fit = row_gls(st, cols, w, path="sparse")
    cov = fit.normal_equations.solve(check=False).covariance
    h_ref, zt_ref = row_reduced_rows(fit, cov)  # D = 1 230 ≤ LEVERAGE_MAX: S⁻¹ whole
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 300)  # each pass's block: 40·6 + 6 = 246
    fit = row_gls(st, cols, w, path="sparse")
    blocks = rows._BlockInverse.of(fit)
    # a pass's images and its pass unknowns (an image without rows is a block of its own: its prior)
    assert blocks is not None and blocks.size.max() == 246 and np.sum(blocks.size > 6) == 10  # 5 passes × 2 runs
    h, zt = row_reduced_rows(fit, cov)
    assert rel(h, h_ref) < 1e-9 and rel(zt, zt_ref) < 1e-9
    monkeypatch.setattr(rows, "LEVERAGE_MAX", 200)  # a block too large: the band selected inverse
    fit = row_gls(st, cols, w, path="sparse")
    assert rows._BlockInverse.of(fit) is None
    assert rel(row_reduced_rows(fit, cov)[0], h_ref) < 1e-9


def test_group_grams_are_each_groups_own_gls():
    """``row_group_grams`` on passes that share no target (``_islands``, robust weights, both kernels): each
    group's reduced block and image Gram equal the GLS of that group's rows alone (1e-9 relative), their sum
    the fit's own (``normal_equations``, ``image_gram``); a target seen in two groups is refused."""
    from boresight.core.gls.rows import row_group_grams

    st, cols = _islands(n_pass=3)
    w = np.random.default_rng(6).uniform(0.2, 1.0, cols.q.shape[:2])
    group = np.array([0, 1, 0])[st.pass_of_image]  # passes 0 and 2 one group
    for path in ("dense", "sparse"):
        fit = row_gls(st, cols, w, path=path)
        red, img = row_group_grams(fit, group, 2)
        ne = fit.normal_equations
        assert rel(red.sum(axis=1)[:, :-1, :-1], ne.data_information) < 1e-10
        assert rel(red.sum(axis=1)[:, :-1, -1], ne.vector) < 1e-10 and rel(img.sum(axis=1), fit.image_gram) < 1e-10
        for g in range(2):
            keep = group[st.image_index] == g
            imgs = np.flatnonzero(group == g)
            loc = np.full(st.n_images, -1)
            loc[imgs] = np.arange(imgs.size)
            sub_st = RowStructure(loc[st.image_index[keep]], st.target_index[keep], st.pass_index[imgs], st.n_targets)
            sub = row_gls(sub_st, RowColumns(*(Z[:, keep] for Z in (cols.X, cols.q, cols.A, cols.B, cols.C))), w[:, keep])
            sne = sub.normal_equations
            assert rel(red[:, g, :-1, :-1], sne.data_information) < 1e-9 and rel(red[:, g, :-1, -1], sne.vector) < 1e-9
            assert rel(red[:, g, -1, -1], sne.weighted_sum_squares) < 1e-9 and rel(img[:, g], sub.image_gram) < 1e-9
    with pytest.raises(ValueError, match="spans two groups"):
        row_group_grams(fit, np.arange(st.n_images) % 2, 2)


def test_the_gls_asks_the_memory_budget_first(monkeypatch):
    """``row_gls_bytes`` bounds the traced peak of ``row_gls`` on the strip (10 000 rows, 2 000 shared
    targets, 2 runs, sparse) within a factor 3, and a budget below it refuses with the estimate and the
    sizes before the fit allocates (traced peak < 5 % of the estimate)."""
    import tracemalloc

    from orbits.limits import MemoryBudgetError

    st, cols = _synthetic_ba(runs=2)
    need = rows.row_gls_bytes(st, 2, 4, 6, 6, 3, "sparse")
    tracemalloc.start()
    row_gls(st, cols, path="sparse")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak <= need <= 3 * peak, (peak, need)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", repr(0.5 * need / 2**30))
    tracemalloc.start()
    with pytest.raises(
        MemoryBudgetError,
        match=rf"GLS on rows of 2 run\(s\) × 10000 rows \(400 images, 2000 targets, D = 2424 .* would need about {need / 2**30:.3g} GiB",
    ):
        row_gls(st, cols, path="sparse")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 0.05 * need
