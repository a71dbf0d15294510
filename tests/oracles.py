"""Test oracles: the slow, dense routes the fast library paths are checked against.

The library carries the error structure once (``boresight.core.gls.structure``) and solves the GLS
once (``boresight.core.gls.rows``, on rows; ``dense_rows`` below feeds it a dense set's arrays). The routes here are the dense ones those
replaced, kept ONLY to check them (and by ``benchmarks/bench_gls.py`` as its baseline):

* ``dense_error_structure``: Σ = blockdiag(D_n) + U diag(v) Uᵀ, with the per-image blocks D_n
  (2M × 2M) and one dense column per shared error (per pass, per landmark);
* ``dense_gls_reference``: each image whitened with the Cholesky factor of its D_n, the shared
  errors carried as dense nuisance columns with prior E and eliminated at the end by a
  pseudo-inverse Schur complement (``NormalEquations.eliminate``).

``LIBRARY_ORACLES`` names the deliberately independent routes that live in the library itself
(``tests/core/test_one_gls.py`` pins the list): ``boresight.core.crlb`` builds the dense covariance of a
whole run draw by draw and whitens with its Cholesky factor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from boresight.core.disturbances import DisturbanceModel, error_jacobians
from boresight.core.gls.normal_equations import NormalEquations
from boresight.core.gls.structure import modes

#: library functions that recompute, on purpose by another route, what the fast path computes
LIBRARY_ORACLES = (
    "boresight.core.crlb.full_residual_covariance",
    "boresight.core.crlb.fisher_information",
    "boresight.core.crlb.cramer_rao_bound",
)


@dataclass(frozen=True)
class DenseErrorStructure:
    """Residual covariance of a run as blockdiag(D) + U diag(variance) Uᵀ.

    ``D`` (R, N, 2M, 2M) per-image covariance (unit variance on masked rows); ``U``
    (R, N, 2M, p) columns of the shared errors; ``variance`` (p,) their prior variances;
    ``labels`` (p,) which error each column is (e.g. ``'star_tracker pass 0 axis 1'``).
    """

    D: np.ndarray
    U: np.ndarray
    variance: np.ndarray
    labels: tuple


def dense_error_structure(obs, theta_rad, model: DisturbanceModel, residual_map=None) -> DenseErrorStructure:
    """The per-image blocks and the dense shared columns (the route ``crlb.error_structure`` was)."""
    obs = obs.dense_view()  # issue 27: this oracle is the dense route
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    J = error_jacobians(obs, theta_rad)
    if residual_map is not None:
        J = {k: residual_map @ v for k, v in J.items()}
    Jst = J["star_tracker"].reshape(R, N, 2 * M, 3)
    Jg = J["gnss"].reshape(R, N, 2 * M, 3)
    blocks = (
        np.broadcast_to(np.eye(2), (R, N, M, 2, 2)) if residual_map is None else residual_map @ np.swapaxes(residual_map, -1, -2)
    )
    D = np.zeros((R, N, M, 2, M, 2))
    idx = np.arange(M)
    D[:, :, idx, :, idx, :] = model.sigma_pixel_m**2 * np.moveaxis(blocks, 2, 0)
    D = D.reshape(R, N, 2 * M, 2 * M)
    st_var = np.asarray(model.sigma_star_tracker_rad) ** 2
    st_img, st_pass = modes(model.star_tracker_mode)
    g_img, g_pass = modes(model.gnss_mode)
    if st_img:
        D = D + np.einsum("rnik,k,rnjk->rnij", Jst, st_var, Jst)
    if g_img:
        D = D + model.sigma_gnss_m**2 * np.einsum("rnik,rnjk->rnij", Jg, Jg)
    mask2 = np.repeat(obs.mask, 2, axis=1)  # (N, 2M)
    D = np.where((~(mask2[:, :, None] & mask2[:, None, :]))[None], 0.0, D)
    diag = np.arange(2 * M)
    D[..., diag, diag] = np.where(mask2[None], D[..., diag, diag], 1.0)

    cols, var, labels = [], [], []
    for on, Jx, v, name in ((st_pass, Jst, st_var, "star_tracker"), (g_pass, Jg, np.full(3, model.sigma_gnss_m**2), "gnss")):
        if not on:
            continue
        for p in np.unique(obs.pass_index):
            sel = (obs.pass_index == p)[None, :, None, None]
            for k in range(3):
                if v[k] > 0:
                    cols.append(np.where(sel, Jx[..., k : k + 1], 0.0))
                    var.append(v[k])
                    labels.append(f"{name} pass {int(p)} axis {k}")
    if model.sigma_catalogue_m > 0:
        Jc = J["catalogue"]  # (R, N, M, 2, 3)
        for m in range(M):
            if not obs.mask[:, m].any():
                continue
            for k in range(3):
                c = np.zeros((R, N, M, 2))
                c[:, :, m, :] = Jc[:, :, m, :, k]
                cols.append(c.reshape(R, N, 2 * M, 1))
                var.append(model.sigma_catalogue_m**2)
                labels.append(f"catalogue {obs.landmark_ids[m]} axis {k}")
    U = np.concatenate(cols, axis=-1) if cols else np.zeros((R, N, 2 * M, 0))
    return DenseErrorStructure(D=D, U=U, variance=np.asarray(var, float), labels=tuple(labels))


def dense_gls_reference(obs, theta_rad, G, q, model: DisturbanceModel, residual_map=None) -> NormalEquations:
    """The dense route the GLS on rows replaced: per-image Cholesky whitening of D_n, the shared
    errors as dense nuisance columns with prior E, eliminated at the end. Memory and time grow as
    N·M·(passes + landmarks): use only for checks."""
    R = obs.runs
    es = dense_error_structure(obs, theta_rad, model, residual_map)
    n = G.shape[-1]
    Gf = G.reshape(R, obs.n_images, -1, n)
    qf = q.reshape(R, obs.n_images, -1)
    p = es.U.shape[-1]
    ne = NormalEquations(n + p, R)
    Us = es.U * np.sqrt(es.variance)
    ne.update(np.concatenate([Gf, Us], axis=-1), qf, covariance=es.D, valid=np.any(Gf != 0, axis=-1))
    if p:
        info = np.zeros((n + p, n + p))
        info[n:, n:] = np.eye(p)
        ne.add_prior(information=info)
        ne = ne.eliminate(n)
    return ne


def dense_rows(obs, theta_rad, G, q, model: DisturbanceModel, residual_map=None):
    """The GLS's rows (``RowStructure``, whitened ``RowColumns``) of a dense (images × landmarks) set:
    G (R, N, M, 2, n), q (R, N, M, 2) and ``residual_map`` (R, N, M, 2, 2) or None gathered at the
    rows of its mask (``np.nonzero(obs.mask)``, the canonical order) and handed to the one builder,
    ``boresight.core.gls.campaign.row_problem``: how the tests feed their dense oracles' inputs to
    the GLS on rows."""
    from boresight.core.gls.campaign import row_problem

    obs = obs.dense_view()
    img, tgt = np.nonzero(obs.mask)
    L = None if residual_map is None else np.asarray(residual_map, float)[:, img, tgt]
    rows = obs.to_rows()  # the same rows, in the same (canonical) order
    return row_problem(rows, theta_rad, np.asarray(G, float)[:, img, tgt], np.asarray(q, float)[:, img, tgt], model, L)


def row_sigma_gls_reference(obs, model: DisturbanceModel, theta0_rad=None, iterations: int = 8):
    """θ̂ (3,) rad and its covariance (3, 3) rad² of one run whose rows carry their own pixel σ
    (``obs.sigma_xy_m``, NaN: ``model.sigma_pixel_m``), by a route independent of the library's
    per-row σ: each row's σ is read here (not through ``gls.structure.row_pixel_sigma``), the shared
    errors' covariance U V Uᵀ is the dense ``crlb.full_residual_covariance`` of the model without pixel
    noise gathered at the rows, Σ = diag(σ_k²) + U V Uᵀ is inverted whole, and Gauss–Newton iterates
    θ ← θ + (GᵀΣ⁻¹G)⁻¹ GᵀΣ⁻¹ q on Algorithm 3's rows (``measurement.linearize``: q ≈ G (θ − θ0))."""
    from dataclasses import replace

    from boresight.core.crlb import full_residual_covariance
    from boresight.core.measurement import linearize

    assert obs.runs == 1, "one run"
    img, tgt = np.asarray(obs.image_index), np.asarray(obs.target_index)
    own = np.full((img.size, 2), np.nan) if obs.sigma_xy_m is None else np.asarray(obs.sigma_xy_m, float)
    var = np.where(np.isnan(own), model.sigma_pixel_m, own).reshape(-1) ** 2  # (2K,) x, y of row 0, then row 1, …
    plain = replace(obs, sigma_xy_m=None)
    at = ((img * obs.n_landmarks + tgt)[:, None] * 2 + np.arange(2)).reshape(-1)  # each row's x, y in the dense layout
    theta = np.zeros(3) if theta0_rad is None else np.asarray(theta0_rad, float).reshape(3)
    for _ in range(iterations):
        shared = full_residual_covariance(plain, theta[None], replace(model, sigma_pixel_m=0.0))[0]
        S = shared[np.ix_(at, at)] + np.diag(var)
        G, q = linearize(obs, theta[None])
        Gf, qf = G[0].reshape(-1, 3), q[0].reshape(-1)
        SiG = np.linalg.solve(S, Gf)
        info = Gf.T @ SiG
        theta = theta + np.linalg.solve(info, SiG.T @ qf)
    return theta, np.linalg.inv(info)
