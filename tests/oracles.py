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

The images × landmarks grid (``DenseGrid``, ``dense_grid``; the library's transitional dense view,
retired from the library once every consumer was on rows) lives here too, for the tests whose oracle
or whose construction is a grid: ``dense_grid(obs)`` scatters a row set into ``xy_m`` (R, N, M, 2)
and ``mask`` (N, M), ``DenseGrid.to_rows()`` (``from_grid``) goes back, ``scatter`` puts row values
(R, K, …) into the grid and ``on_grid`` calls a library function on the rows and scatters what it
returns. The library itself takes rows only.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel, error_jacobians
from boresight.core.gls.normal_equations import NormalEquations
from boresight.core.gls.structure import modes
from boresight.observations.model import ObservationSet, _ImageDerived, _SetFields
from orbits.records import ImagesAndTargets

#: truth arrays with one entry per row, (R, K, 2) on rows, (R, N, M, 2) on the grid
_ROW_TRUTH = ("xy_true_m", "pixel_noise_m")


def from_grid(*, xy_m, mask, truth: dict | None = None, **fields_) -> ObservationSet:
    """A validated row set from images × landmarks arrays: ``xy_m`` (R, N, M, 2) and ``mask`` (N, M)
    (True where landmark m was observed in image n); every other field as in ``ObservationSet``. Rows are
    the True cells of ``mask`` in (image, landmark) order, the canonical order."""
    mask = np.asarray(mask, bool)
    ii, tt = np.nonzero(mask)
    xy = np.asarray(xy_m, float)
    assert xy.ndim == 4 and xy.shape[1:3] == mask.shape and xy.shape[3] == 2, (xy.shape, mask.shape)
    if truth is not None:
        truth = dict(truth)
        for key in _ROW_TRUTH:
            if key in truth and np.ndim(truth[key]) == 4:
                truth[key] = np.asarray(truth[key])[:, ii, tt]
    return ObservationSet(xy_m=xy[:, ii, tt], image_index=ii, target_index=tt, truth=truth, **fields_)


@dataclass(frozen=True)
class DenseGrid(_ImageDerived, _SetFields, ImagesAndTargets):
    """A row set's images × landmarks grid: the image and target tables and the other fields of an
    ``ObservationSet``, declared once in the library (``orbits.records.ImagesAndTargets``,
    ``observations.model._SetFields``) and inherited here, so the grid carries every field a set has
    beyond its rows; ``xy_m`` (R, N, M, 2), 0 where ``mask`` (N, M) is False, row truth likewise.
    The run slicing and the attitudes are the set's own too (``observations.model._ImageDerived``:
    ``run(k)`` through ``_subset``, ``nominal_camera_attitude``). Test-only (the library takes rows):
    ``to_rows()`` goes back; ``images(sel)`` slices the grid by its own route (the row model's tests compare
    it with the set's ``images``)."""

    xy_m: np.ndarray = field(kw_only=True)
    mask: np.ndarray = field(kw_only=True)

    @property
    def runs(self) -> int:
        return int(self.xy_m.shape[0])

    @property
    def n_observations(self) -> int:
        return int(self.mask.sum())

    def to_rows(self) -> ObservationSet:
        """The validated row set of this grid (cached per grid)."""
        cached = self.__dict__.get("_rows")
        if cached is None:
            kw = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("xy_m", "mask", "truth")}
            if kw["target_kind"] is not None and np.shape(kw["target_kind"]) != np.shape(self.landmark_ids):
                kw["target_kind"] = None  # the landmark table was replaced: every target a landmark
                kw["stars"] = None
            cached = from_grid(xy_m=self.xy_m, mask=self.mask, truth=self.truth, **kw)
            pos = self.__dict__.get("_star_position_i_m")  # a simulated set's star positions (model.from_measurements)
            if pos is not None:
                object.__setattr__(cached, "_star_position_i_m", pos)
            object.__setattr__(self, "_rows", cached)
        return cached

    def landmarks_i_m(self) -> np.ndarray:
        """Catalogue landmarks in the inertial frame at each image, (R, N, M, 3)."""
        return np.einsum("nij,rmj->rnmi", self.C_GI, self.landmark_g_m)

    def _subset(self, **changes: Any) -> "DenseGrid":
        """The library's ``run(k)`` (``observations.model._ImageDerived``, the run slicing of the tables it
        shares with the set) builds the sliced grid through this."""
        return replace(self, **changes)

    def images(self, sel) -> "DenseGrid":
        idx = np.arange(self.n_images)[sel]
        truth = None
        if self.truth is not None:
            truth = dict(self.truth)
            for key in ("delta_rad", "gnss_error_m") + _ROW_TRUTH:
                if key in truth:
                    truth[key] = truth[key][:, idx]
            for key in ("C_IS", "r_sc_i_m"):
                if key in truth:
                    truth[key] = truth[key][idx]
        return replace(
            self,
            t_s=self.t_s[idx],
            pass_index=self.pass_index[idx],
            q_is=self.q_is[:, idx],
            r_sc_i_m=self.r_sc_i_m[:, idx],
            C_GI=self.C_GI[idx],
            xy_m=self.xy_m[:, idx],
            mask=self.mask[idx],
            truth=truth,
            v_sc_i_m_s=None if self.v_sc_i_m_s is None else self.v_sc_i_m_s[:, idx],
        )

    def write(self, path, overwrite: bool = False, image_columns: str = "xy"):
        """Write the row set (``to_rows().write``)."""
        return self.to_rows().write(path, overwrite=overwrite, image_columns=image_columns)


def dense_grid(obs) -> DenseGrid:
    """The images × landmarks grid of a row set (a grid is returned as it is)."""
    if isinstance(obs, DenseGrid):
        return obs
    assert not obs.has_samples, "a set with an attitude-sample table has no grid"
    R, N, T = obs.runs, obs.n_images, obs.n_targets
    ii, tt = obs.image_index, obs.target_index
    xy = np.zeros((R, N, T, 2))
    xy[:, ii, tt] = obs.xy_m
    mask = np.zeros((N, T), bool)
    mask[ii, tt] = True
    truth = None
    if obs.truth is not None:
        truth = dict(obs.truth)
        for key in _ROW_TRUTH:
            if key in truth:
                v = np.asarray(truth[key])
                d = np.zeros(v.shape[:1] + (N, T) + v.shape[2:])
                d[:, ii, tt] = v
                truth[key] = d
    kw = {f.name: getattr(obs, f.name) for f in fields(DenseGrid) if f.name not in ("xy_m", "mask", "truth")}
    grid = DenseGrid(xy_m=xy, mask=mask, truth=truth, **kw)
    pos = obs.__dict__.get("_star_position_i_m")
    if pos is not None:
        object.__setattr__(grid, "_star_position_i_m", pos)
    object.__setattr__(grid, "_rows", obs)
    return grid


def rows_of(obs):
    """The row set of a grid (``DenseGrid.to_rows``) or of a row set (itself)."""
    return obs.to_rows() if isinstance(obs, DenseGrid) else obs


def scatter(grid, values) -> np.ndarray:
    """Row values (R, K, …) → the grid layout (R, N, M, …), 0 where ``grid.mask`` is False."""
    mask = grid.mask
    img, tgt = np.nonzero(mask)
    values = np.asarray(values)
    out = np.zeros((values.shape[0],) + mask.shape + values.shape[2:], dtype=values.dtype)
    out[:, img, tgt] = values
    return out


def on_grid(func, grid, *args, **kwargs):
    """``func(grid.to_rows(), *args, **kwargs)`` with every array it returns (R, K, …) scattered onto
    the grid (a tuple element by element, a dict value by value): how a test whose oracle is a grid
    calls a library function on rows."""
    grid = dense_grid(grid)
    out = func(grid.to_rows(), *args, **kwargs)
    if isinstance(out, tuple):
        return tuple(None if v is None else scatter(grid, v) for v in out)
    if isinstance(out, dict):
        return {k: scatter(grid, v) for k, v in out.items()}
    return scatter(grid, out)


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
    """The per-image blocks and the dense shared columns (the route ``crlb.error_structure`` was),
    on the images × landmarks grid of ``obs`` (a row set or a ``DenseGrid``); ``residual_map`` on the grid."""
    obs = dense_grid(obs)
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    J = on_grid(error_jacobians, obs, theta_rad)
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

    obs = dense_grid(obs)
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
    own = np.full((obs.n_observations, 2), np.nan) if obs.sigma_xy_m is None else np.asarray(obs.sigma_xy_m, float)
    var = np.where(np.isnan(own), model.sigma_pixel_m, own).reshape(-1) ** 2  # (2K,) x, y of row 0, then row 1, …
    plain = replace(obs, sigma_xy_m=None)
    theta = np.zeros(3) if theta0_rad is None else np.asarray(theta0_rad, float).reshape(3)
    for _ in range(iterations):
        shared = full_residual_covariance(plain, theta[None], replace(model, sigma_pixel_m=0.0))[0]  # (2K, 2K), rows' order
        S = shared + np.diag(var)
        G, q = linearize(obs, theta[None])
        Gf, qf = G[0].reshape(-1, 3), q[0].reshape(-1)
        SiG = np.linalg.solve(S, Gf)
        info = Gf.T @ SiG
        theta = theta + np.linalg.solve(info, SiG.T @ qf)
    return theta, np.linalg.inv(info)


def image_covariance(obs, theta_rad, model: DisturbanceModel, include_per_pass: bool = True) -> np.ndarray:
    """The per-image covariances of ``gls.structure.image_covariance_rows`` in the images × landmarks layout,
    (R, N, 2M, 2M): landmark m of image n at 2m, 2m + 1; unobserved entries get unit variance and no
    correlation (the layout the library had before the row model; the tests' per-image oracles and the
    Monte Carlo benchmark's per-run loop read it). Refused with its memory estimate
    (``orbits.limits.MemoryBudgetError``: three 2T × 2T float64 blocks per run and image) before anything
    is allocated."""
    from boresight.core.gls.structure import image_covariance_rows, images_by_row_count
    from orbits.limits import check_memory

    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    check_memory(
        f"image_covariance: the per-image 2T × 2T covariance blocks of {R} run(s) × {N} images × {M} targets",
        3 * 8 * float(R) * float(N) * (2.0 * M) ** 2,
        hint="image_covariance_rows per group of images (images_by_row_count) holds each image's own rows only",
    )
    cov = np.zeros((R, N, 2 * M, 2 * M))
    diag = np.arange(2 * M)
    cov[:, :, diag, diag] = 1.0
    theta = np.broadcast_to(np.asarray(theta_rad, float), (R, 3))
    for m, ims in images_by_row_count(obs):
        if not m:
            continue
        sub = obs.images(ims)
        blk = image_covariance_rows(sub, theta, model, include_per_pass)  # (R, u, 2m, 2m)
        at = (2 * sub.target_index.reshape(ims.size, m)[:, :, None] + np.arange(2)).reshape(ims.size, 2 * m)
        cov[:, ims[:, None, None], at[:, :, None], at[:, None, :]] = blk
    return cov
