"""The campaign GLS for callers on the dense (images × landmarks) set: an adapter onto the GLS on rows.

The one GLS is ``boresight.core.gls.rows`` (its docstring derives it: single-use targets folded
into their rows, shared targets eliminated by a sparse Schur complement, the image/pass system by
a dense or a sparse Cholesky-type factorisation, x last). This module keeps the interface of the
slot-layout GLS it replaced for the callers that still hold dense arrays — ``estimate``,
the robust sandwich, ``diagnose``, ``plan``, ``sensitivity`` —: it takes G (R, N, M, 2, n) and q
(R, N, M, 2) (or the per-image slot layout of ``structure.observed_slots``), builds the rows
``np.nonzero(obs.mask)`` in their canonical (image, landmark) order (``dense_rows``), whitens each
row by its pixel noise σK² L Lᵀ and returns the results in the slot layout (R, N, Mx, 2, …) those
callers read. A caller on the row model calls ``fit_rows`` (``row_problem``: the same whitening on
the set's own rows, then ``rows.row_gls``) and reads ``rows.row_residuals`` / ``row_reduced_rows``;
this adapter shrinks as callers move.

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.normal_equations import NormalEquations
from boresight.core.gls.rows import (
    RowColumns,
    RowFit,
    RowStructure,
    row_gls,
    row_reduced_rows,
    row_residuals,
    row_sandwich_middle,
)
from boresight.core.gls.structure import error_columns, observed_slots, pixel_covariance

__all__ = [
    "CampaignGLS",
    "campaign_gls",
    "solve_nuisances",
    "pixel_residuals",
    "sandwich_middle",
    "reduced_rows",
    "single_threaded_blas",
    "dense_rows",
    "row_problem",
    "fit_rows",
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


@dataclass
class CampaignGLS:
    """The campaign's GLS on rows (``rows``) with the slot layout of its dense caller.

    ``normal_equations`` is a ``NormalEquations`` over x = [θ, extras] (data part only, dof =
    residual components − unknowns); ``rows`` the ``RowFit``; ``slots`` = (landmark index (N, Mx),
    observed (N, Mx)) the per-image slot layout the results below are returned in.
    """

    normal_equations: NormalEquations
    n_params: int
    rows: RowFit
    slots: tuple[np.ndarray, np.ndarray]

    @property
    def image_gram(self) -> np.ndarray:
        """(R, n+1, n+1): the Gram of [X | q] with only the pixel noise and the per-image errors
        eliminated (the information against which ``diagnose`` measures canonical correlations)."""
        return self.rows.image_gram

    @property
    def whitened_columns(self) -> np.ndarray:
        """(R, N, Mx, 2, n+1): [X | q] whitened by the pixel noise, unweighted, in the slot layout."""
        return self.to_slots(self.rows.columns.Y)

    def to_slots(self, a: np.ndarray) -> np.ndarray:
        """Row values (R, K, …) → the slot layout (R, N, Mx, …), 0 on empty slots."""
        idx, valid = self.slots
        out = np.zeros((a.shape[0],) + idx.shape + a.shape[2:])
        out[:, valid] = a
        return out


@_single_threaded
def campaign_gls(
    obs: Any,
    theta_rad: Any,
    G: Any,
    q: Any,
    model: DisturbanceModel,
    residual_map: Any = None,
    obs_weights: Any = None,
    slotted: bool = False,
) -> CampaignGLS:
    """The campaign's GLS normal equations (the nuisances of ``model`` eliminated exactly).

    ``G`` (R, N, M, 2, n) Jacobian of q w.r.t. x (θ first), ``q`` (R, N, M, 2) residuals,
    ``residual_map`` (R, N, M, 2, 2) or None (image plane), ``obs_weights`` (R, N, M) robust
    weights on the pixel noise of each observation (1 = as modelled, 0 = dropped) or None.
    ``slotted``: G (R, N, Mx, 2, n) and q (R, N, Mx, 2) are already in the per-image slot layout
    of ``observed_slots(obs.mask)`` (a caller with many columns saves the images × landmarks array).
    """
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    if not model.sigma_pixel_m > 0:
        raise ValueError(f"campaign_gls: GLS needs model.sigma_pixel_m > 0, got {model.sigma_pixel_m!r}")
    st, cols = dense_rows(obs, theta_rad, G, q, model, residual_map, slotted)
    w = None if obs_weights is None else np.asarray(obs_weights, float)[:, st.image_index, st.target_index]
    fit = row_gls(st, cols, w)
    return CampaignGLS(fit.normal_equations, cols.X.shape[-1], fit, observed_slots(obs.mask))


@_single_threaded
def solve_nuisances(fit: CampaignGLS, dx: Any, per_image_whitened: bool = False) -> np.ndarray:
    """Pixel-level normalised residuals at the correction ``dx`` (R, n), (R, N, Mx, 2) in slots.

    ``rows.row_residuals``: the MAP per-image, per-pass and catalogue errors of the (weighted) fit
    given x = dx removed from the whitened residual q − X dx, in units of the pixel σ, without the
    robust weights; with ``per_image_whitened`` the per-image errors whitened instead of removed.
    """
    return fit.to_slots(row_residuals(fit.rows, np.asarray(dx, float), per_image_whitened))


def sandwich_middle(obs: Any, theta_rad: Any, model: DisturbanceModel, WG: Any, residual_map: Any = None) -> np.ndarray:
    """(WG)ᵀ Σ (WG) for weighted Jacobian columns WG (R, N, M, 2, n), error source by error source
    (``rows.row_sandwich_middle``), (R, n, n)."""
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    img, tgt = np.nonzero(obs.mask)
    st = RowStructure(img, tgt, np.asarray(obs.pass_index), int(obs.n_landmarks))
    L = None if residual_map is None else np.asarray(residual_map, float)[:, img, tgt]
    A, B, C = error_columns(obs, theta_rad, model, L, rows=(img, tgt))
    return row_sandwich_middle(st, np.asarray(WG, float)[:, img, tgt], pixel_covariance(model, L), A, B, C)


def pixel_residuals(
    obs: Any, theta_rad: Any, G: Any, q: Any, model: DisturbanceModel, residual_map: Any = None, obs_weights: Any = None
) -> tuple[np.ndarray, Any]:
    """Pixel-level normalised residual vectors at θ (no correction), dense (R, N, M, 2), 0 where masked.

    The MAP per-image, per-pass and catalogue errors given θ are removed (``solve_nuisances``
    with dx = 0) and the rest divided by the pixel σ: N(0, E₂) per observation under the model,
    up to leverage; with ``obs_weights`` the nuisances are those of the robustly weighted fit (so
    an outlier does not leak into its image's other observations). Also returns the GLS χ²
    minimised over a correction of x (R,), of the weighted fit.
    """
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    fit = campaign_gls(obs, theta_rad, G, q, model, residual_map, obs_weights=obs_weights)
    R = obs.runs
    e = row_residuals(fit.rows, np.zeros((R, G.shape[-1])))
    st = fit.rows.structure
    out = np.zeros(obs.xy_m.shape)
    out[:, st.image_index, st.target_index] = e
    # χ² minimised over a (linearised) correction of x: the noise-model consistency statistic
    # whatever weighting produced θ
    sol = fit.normal_equations.solve(check=False)
    return out, sol.chi2


@_single_threaded
def reduced_rows(fit: CampaignGLS, covariance_x: Any, leverage: bool = True) -> tuple[np.ndarray | None, np.ndarray]:
    """Each residual row's leverage h (R, N, Mx, 2) and reduced x-row z̃ (R, N, Mx, 2, n), in slots.

    ``rows.row_reduced_rows``: for the whitened (unweighted) row z_i of residual component i,
    z̃_i = z_x − J_xν J_νν⁻¹ z_ν and h_i = z_iᵀ J⁻¹ z_i (J the fit's weighted joint information,
    ``covariance_x`` the inverse reduced information). Σ_i w_i z̃_i q̃_i is the reduced right-hand
    side (``tests/core/test_campaign_gls.py``), which the M-estimator sandwich of
    ``boresight.estimate`` needs. ``leverage=False``: z̃ only (both are exact on every path, see ``rows``).
    """
    h, zt = row_reduced_rows(fit.rows, None if covariance_x is None else np.asarray(covariance_x, float), leverage)
    return (None if h is None else fit.to_slots(h)), fit.to_slots(zt)


def row_problem(
    obs: Any, theta_rad: Any, X: Any, q: Any, model: DisturbanceModel, residual_map: Any = None
) -> tuple[RowStructure, RowColumns]:
    """The row structure and the whitened row columns of an observation set on the row model: ``X``
    (R, K, 2, n) the Jacobian of the residuals ``q`` (R, K, 2) w.r.t. x, ``residual_map`` (R, K, 2, 2)
    or None (image plane), one row per observation in the set's canonical order. The nuisance columns
    of ``model`` are ``structure.error_columns`` on the rows; every row is whitened by its pixel noise
    σK² L Lᵀ (a division by σK in the image plane)."""
    if not model.sigma_pixel_m > 0:
        raise ValueError(f"row_problem: the GLS needs model.sigma_pixel_m > 0, got {model.sigma_pixel_m!r}")
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
    sk = model.sigma_pixel_m
    if L is None:
        X, q, A, B, C = (Z / sk for Z in (X, q, A, B, C))
    else:
        Wh = np.linalg.inv(np.linalg.cholesky(sk**2 * (L @ np.swapaxes(L, -1, -2))))
        X, A, B, C = (Wh @ Z for Z in (X, A, B, C))
        q = (Wh @ q[..., None])[..., 0]
    return RowColumns(X=X, q=q, A=A, B=B, C=C)


def dense_rows(
    obs: Any,
    theta_rad: Any,
    G: Any,
    q: Any,
    model: DisturbanceModel,
    residual_map: Any = None,
    slotted: bool = False,
) -> tuple[RowStructure, RowColumns]:
    """The row structure and the whitened row columns of a dense (images × landmarks) set: the
    adapter of callers not yet on rows. Rows are ``np.nonzero(obs.mask)``, the canonical
    (image, landmark) order; G (R, N, M, 2, n), q (R, N, M, 2), ``residual_map`` (R, N, M, 2, 2) or
    None, or with ``slotted`` G and q in the slot layout of ``observed_slots(obs.mask)``. Each row is
    whitened by its pixel noise σK² L Lᵀ (a division by σK in the image plane)."""
    obs = obs.dense_view()  # dense view: not yet on the row model (docs/architecture.md, port status)
    img, tgt = np.nonzero(obs.mask)
    st = RowStructure(img, tgt, np.asarray(obs.pass_index), int(obs.n_landmarks))
    G = np.asarray(G, float)
    q = np.asarray(q, float)
    if slotted:
        idx, valid = observed_slots(obs.mask)
        nn, ss = np.nonzero(valid)  # the same rows, in the same order
        X, qr = G[:, nn, ss], q[:, nn, ss]
    else:
        X, qr = G[:, img, tgt], q[:, img, tgt]
    L = None if residual_map is None else np.asarray(residual_map, float)[:, img, tgt]
    return st, _whitened_columns(obs, theta_rad, st, X, qr, model, L)
