"""From an observation set to the one GLS on rows (``boresight.core.gls.rows``).

The one GLS is ``boresight.core.gls.rows`` (its docstring derives it: single-use targets folded
into their rows, shared targets eliminated by a sparse Schur complement, the image/pass system by
a dense or a sparse Cholesky-type factorisation, x last). It works on a ``RowStructure`` (which
image, target, pass — and attitude samples — each row belongs to) and ``RowColumns`` (each row's
columns whitened by its pixel noise). This module builds those two from an observation set, once
for every caller: ``row_problem(obs, θ, X, q, model, L)`` takes the rows' Jacobian X (R, K, 2, n),
residuals q (R, K, 2) and residual map L (R, K, 2, 2) or None (image plane), builds the nuisance
columns of ``model`` (``structure.error_columns(..., rows=)``) and whitens each row by its pixel
noise σK² L Lᵀ (its own L diag(σ_x², σ_y²) Lᵀ where the set has a per-row σ: ``structure.row_pixel_sigma``); ``fit_rows`` is ``rows.row_gls`` of that — the GLS of ``estimate``, the robust
sandwich, ``diagnose``, the variance components, the planner and ``sensitivity`` —, whose caller then
reads ``rows.row_residuals`` / ``row_reduced_rows``; ``sandwich_middle`` is (WG)ᵀ Σ (WG) on rows.
The slot-layout adapter of the dense callers (``campaign_gls``, ``solve_nuisances``,
``reduced_rows``, ``dense_rows``) is gone: the tests feed their dense oracles' arrays to
``row_problem`` through ``tests/oracles.py:dense_rows``.

The residuals of one run are q = X x + e with e = ε_pix + Σ_n A_n a_n + Σ_p B_p b_p + Σ_m C_m c_m
(pixel noise, per-image, per-pass and catalogue errors, each nuisance with the prior N(0, E) once
its columns are scaled by σ: ``structure.error_columns``). GLS with Σ = cov(e) equals the x-part of
the joint MAP estimate of [x, a, b, c] (Woodbury); ``tests/core/test_campaign_gls.py`` checks it
against the full-Σ route (``crlb.full_residual_covariance``) and the dense route
(``tests/oracles.py:dense_gls_reference``) to 1e-9.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.rows import RowColumns, RowFit, RowStructure, chol_inv_2x2, row_gls, row_sandwich_middle
from boresight.core.gls.structure import error_columns, has_pixel_noise, pixel_covariance, row_pixel_sigma
from boresight.errors import NoiseModelError

__all__ = [
    "single_threaded_blas",
    "row_problem",
    "fit_rows",
    "sandwich_middle",
]


# DECISION: the GLS's factorisations are small (6 × 6 blocks, a reduced system of a few hundred
# unknowns on the seminar's campaigns); a threaded BLAS on a busy machine makes them erratic
# (2 ms → 2 s for a 520 × 130 QR measured on 2 shared cores), so they run single-threaded
# (threadpoolctl, BSD-3-Clause; without it the BLAS default stands).
try:
    from threadpoolctl import ThreadpoolController

    _POOL = ThreadpoolController()
except ImportError:  # pragma: no cover - optional
    _POOL = None


def single_threaded_blas() -> AbstractContextManager[Any]:
    """A context in which BLAS runs on one thread (the GLS's small factorisations; a no-op without
    threadpoolctl). ``boresight.diagnose`` runs its whole workflow in it."""
    return nullcontext() if _POOL is None else _POOL.limit(limits=1, user_api="blas")


def _single_threaded(func: Any) -> Callable[..., Any]:
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with single_threaded_blas():
            return func(*args, **kwargs)

    return wrapper


def row_problem(
    obs: Any, theta_rad: Any, X: Any, q: Any, model: DisturbanceModel, residual_map: Any = None
) -> tuple[RowStructure, RowColumns]:
    """The row structure and the whitened row columns of an observation set on the row model: ``X``
    (R, K, 2, n) the Jacobian of the residuals ``q`` (R, K, 2) w.r.t. x, ``residual_map`` (R, K, 2, 2)
    or None (image plane), one row per observation in the set's canonical order. The nuisance columns
    of ``model`` are ``structure.error_columns`` on the rows; every row is whitened by its pixel noise
    σK² L Lᵀ (a division by σK in the image plane)."""
    if not has_pixel_noise(obs, model):
        raise NoiseModelError(
            f"row_problem: the GLS needs a pixel σ > 0 on every row (model.sigma_pixel_m = {model.sigma_pixel_m!r}, "
            "or each row's own sigma_xy_m)"
        )
    st = RowStructure.of(obs)
    L = None if residual_map is None else np.asarray(residual_map, float)
    return st, _whitened_columns(obs, theta_rad, st, np.asarray(X, float), np.asarray(q, float), model, L)


@_single_threaded
def fit_rows(
    obs: Any, theta_rad: Any, X: Any, q: Any, model: DisturbanceModel, residual_map: Any = None, weights: Any = None
) -> RowFit:
    """``rows.row_gls`` of ``row_problem(obs, θ, X, q, model, residual_map)`` with robust ``weights``
    (R, K) on each row's information (1 = as modelled, 0 = dropped) or None, BLAS single-threaded:
    the GLS of every caller on the row model (``diagnose``, the variance components, the planner)."""
    st, cols = row_problem(obs, theta_rad, X, q, model, residual_map)
    return row_gls(st, cols, None if weights is None else np.asarray(weights, float))


def _whitened_columns(
    obs: Any, theta_rad: Any, st: RowStructure, X: np.ndarray, q: np.ndarray, model: DisturbanceModel, L: np.ndarray | None
) -> RowColumns:
    """[X, q] and the nuisance columns of ``model`` on the rows of ``st``, whitened by each row's pixel noise."""
    R, K = X.shape[0], st.n_rows
    rows = (st.image_index, st.target_index)
    A, B, C = (np.zeros((R, K, 2, 0)) if Z is None else Z for Z in error_columns(obs, theta_rad, model, L, rows=rows))
    sig = row_pixel_sigma(obs, model)  # (K, 2) each row's own σ, or None: the model's one σK
    if sig is not None and L is None:
        X, A, B, C = (Z / sig[None, :, :, None] for Z in (X, A, B, C))
        q = q / sig[None]
    elif sig is not None:
        Wh = chol_inv_2x2(pixel_covariance(model, L, sig))
        X, A, B, C = (Wh @ Z for Z in (X, A, B, C))
        q = (Wh @ q[..., None])[..., 0]
    elif L is None:
        sk = model.sigma_pixel_m
        X, q, A, B, C = (Z / sk for Z in (X, q, A, B, C))
    else:
        sk = model.sigma_pixel_m
        Wh = chol_inv_2x2(sk**2 * (L @ np.swapaxes(L, -1, -2)))
        X, A, B, C = (Wh @ Z for Z in (X, A, B, C))
        q = (Wh @ q[..., None])[..., 0]
    return RowColumns(X=X, q=q, A=A, B=B, C=C)


def sandwich_middle(obs: Any, theta_rad: Any, model: DisturbanceModel, WG: Any, residual_map: Any = None) -> np.ndarray:
    """(WG)ᵀ Σ (WG) for weighted Jacobian rows WG (R, K, 2, n) and ``residual_map`` (R, K, 2, 2) or
    None, error source by error source (``rows.row_sandwich_middle``), (R, n, n)."""
    WG = np.asarray(WG, float)
    L = None if residual_map is None else np.asarray(residual_map, float)
    st = RowStructure.of(obs)
    A, B, C = error_columns(obs, theta_rad, model, L, rows=(st.image_index, st.target_index))
    sig = row_pixel_sigma(obs, model)
    pix = pixel_covariance(model, L, sig)
    if sig is not None:
        pix = np.broadcast_to(pix, WG.shape[:2] + (2, 2))
    return row_sandwich_middle(st, WG, pix, A, B, C)
