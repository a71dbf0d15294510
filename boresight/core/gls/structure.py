"""The one error-structure builder: the nuisance columns of the disturbance model.

The residuals of a run are perturbed, to first order, by e = ε_pix + Σ_n A_n a_n + Σ_p B_p b_p +
Σ_m C_m c_m (``boresight.core.disturbances.error_jacobians`` gives the sensitivities J):

* pixel noise ε_pix, independent per observation, covariance σK² L Lᵀ (L the algorithm's
  ``residual_map``; the identity in the image plane) — or, for a set with per-row σ
  (``ObservationSet.sigma_xy_m``, a centroid's own σ from its brightness), L diag(σ_k,x², σ_k,y²) Lᵀ
  with the row's σ where it has one and σK where it has NaN (``row_pixel_sigma``). A set without
  the column takes the scalar path unchanged, so its numbers are bit-identical;
* per-image star-tracker / GNSS errors a_n (modes ``per_image`` and ``both``): columns A, 6 per
  image at most (one per star-tracker axis with σ > 0, three for GNSS);
* per-pass star-tracker / GNSS errors b_p (modes ``per_pass`` and ``both``): columns B of the same
  shape, shared by the images of one pass;
* catalogue errors c_m: columns C, 3 per observation, shared by every image that sees landmark m.

Every column is scaled by its σ, so each nuisance has the prior N(0, E). Everything that needs the
error structure builds it here: the block-sparse GLS (``boresight.core.gls.campaign``: estimate,
diagnose, plan, Monte Carlo GLS weighting), the per-image covariance of the Kalman filter
(``image_covariance_rows``: each image's rows, 2m_n × 2m_n, images batched by equal m_n) and of the
Monte Carlo Kalman weights (``studies.montecarlo.preflight.kalman_weight_blocks``, the same) and the
per-residual variances (``residual_variances``); ``tests/oracles.py:image_covariance`` places the same
blocks in an images × landmarks layout for the tests and the Monte Carlo benchmark's per-run loop.
The one deliberately independent route is ``boresight.core.crlb.full_residual_covariance`` (a dense
Σ built error draw by error draw), which the tests compare against (``tests/oracles.py`` lists the
oracles).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel, error_jacobians
from boresight.core.measurement import observation_rows
from boresight.errors import InputValueError

__all__ = [
    "modes",
    "restricted",
    "scaled_columns",
    "error_columns",
    "pixel_covariance",
    "row_pixel_sigma",
    "has_pixel_noise",
    "residual_variances",
    "image_covariance_rows",
    "images_by_row_count",
    "rows_per_image_equal",
    "KINDS",
]

#: the three kinds of shared error, in the order ``scaled_columns`` returns them
KINDS = ("image", "pass", "catalogue")


def modes(mode: str) -> tuple[bool, bool]:
    """(per image?, per pass?) of a star-tracker / GNSS error mode.

    >>> modes("both")
    (True, True)
    """
    return mode in ("per_image", "both"), mode in ("per_pass", "both")


def restricted(model: DisturbanceModel, kinds: Any) -> DisturbanceModel:
    """``model`` with only the errors of ``kinds`` (a subset of ``KINDS``) kept, and the pixel noise.

    E.g. ``restricted(model, ("image",))`` keeps the per-image star-tracker / GNSS errors (mode
    ``both`` becomes ``per_image``) and drops the per-pass and catalogue ones: the whitening of
    ``boresight.diagnose`` and the planner's naming information.
    """
    kinds = set(kinds)
    unknown = kinds - set(KINDS)
    if unknown:
        raise InputValueError(f"restricted: unknown kinds {sorted(unknown)}; expected a subset of {KINDS}")

    def mode_sigma(mode: str, sigma: Any) -> tuple[str, Any]:
        img, pas = modes(mode)
        img, pas = img and "image" in kinds, pas and "pass" in kinds
        if img and pas:
            return "both", sigma
        if img:
            return "per_image", sigma
        if pas:
            return "per_pass", sigma
        return "per_image", np.zeros_like(np.asarray(sigma, float)) if np.ndim(sigma) else 0.0

    st_mode, st_sigma = mode_sigma(model.star_tracker_mode, model.sigma_star_tracker_rad)
    g_mode, g_sigma = mode_sigma(model.gnss_mode, model.sigma_gnss_m)
    return DisturbanceModel(
        sigma_pixel_m=model.sigma_pixel_m,
        sigma_star_tracker_rad=tuple(np.asarray(st_sigma, float)),
        star_tracker_mode=st_mode,
        sigma_gnss_m=float(g_sigma),
        gnss_mode=g_mode,
        sigma_catalogue_m=model.sigma_catalogue_m if "catalogue" in kinds else 0.0,
    )


def scaled_columns(
    J: dict[str, np.ndarray], model: DisturbanceModel
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """Error Jacobians × σ: the (per-image, per-pass, catalogue) column sets, None where absent.

    ``J`` as ``error_jacobians`` returns it (any leading layout, last axes (2, 3)); per-image and
    per-pass sets have one column per star-tracker axis with σ > 0 then the three GNSS columns
    (the per-pass set then one column per axis of the extra per-pass rotation with σ > 0).
    """
    if model.has_correlated_tracker:  # the lines' GLS adds its columns itself (boresight.core.line_scan)
        raise InputValueError(
            "the star tracker's Gauss–Markov error (DisturbanceModel.sigma_star_tracker_correlated_rad) is modelled on "
            "pushbroom lines' tracker samples only; a frame camera's noise model takes white errors (per image / per pass)"
        )
    st_img, st_pass = modes(model.star_tracker_mode)
    g_img, g_pass = modes(model.gnss_mode)
    st_s = np.asarray(model.sigma_star_tracker_rad, float)

    def cols(on_st: Any, on_g: Any) -> np.ndarray | None:
        out = []
        if on_st:
            out += [J["star_tracker"][..., k : k + 1] * st_s[k] for k in range(3) if st_s[k] > 0]
        if on_g and model.sigma_gnss_m > 0:
            out.append(J["gnss"] * model.sigma_gnss_m)
        return np.concatenate(out, axis=-1) if out else None

    cat = J["catalogue"] * model.sigma_catalogue_m if model.sigma_catalogue_m > 0 else None

    # the extra rotations (``DisturbanceModel.sigma_image_rotation_rad`` / ``sigma_pass_rotation_rad``):
    # more per-image / per-pass columns after the sources'
    def more(base: np.ndarray | None, sig: Any) -> np.ndarray | None:
        s = np.asarray(sig, float)
        extra = [J["star_tracker"][..., k : k + 1] * s[k] for k in range(3) if s[k] > 0]
        return np.concatenate(([base] if base is not None else []) + extra, axis=-1) if extra else base

    return (
        more(cols(st_img, g_img), model.sigma_image_rotation_rad),
        more(cols(st_pass, g_pass), model.sigma_pass_rotation_rad),
        cat,
    )


def error_columns(
    obs: Any, theta_rad: Any, model: DisturbanceModel, residual_map: Any = None, rows: Any = None
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """The scaled (per-image, per-pass, catalogue) columns, None where absent.

    ``rows`` = (image_index, target_index) (K,): the observations (default: every one), each (R, K, 2, ·),
    with ``residual_map`` (R, K, 2, 2) or None (the image plane).
    """
    J = error_jacobians(obs, theta_rad, rows=rows)
    if residual_map is not None:
        L = np.asarray(residual_map, float)
        J = {k: L @ v for k, v in J.items()}
    return scaled_columns(J, model)


def row_pixel_sigma(obs: Any, model: DisturbanceModel) -> np.ndarray | None:
    """(K, 2) the pixel σ (m) of each row's x and y: the row's own (``obs.sigma_xy_m``) where it has one,
    ``model.sigma_pixel_m`` where it has NaN; None for a set without per-row σ (every row the model's σK:
    the callers keep their scalar path, bit-identical to before the column existed).

    >>> import numpy as np
    >>> from types import SimpleNamespace
    >>> obs = SimpleNamespace(sigma_xy_m=np.array([[1e-6, 2e-6], [np.nan, np.nan]]))
    >>> row_pixel_sigma(obs, DisturbanceModel(sigma_pixel_m=3e-6)).tolist()
    [[1e-06, 2e-06], [3e-06, 3e-06]]
    """
    own = getattr(obs, "sigma_xy_m", None)
    if own is None:
        return None
    own = np.asarray(own, float)
    out: np.ndarray = np.where(np.isnan(own), model.sigma_pixel_m, own)
    return out


def has_pixel_noise(obs: Any, model: DisturbanceModel | None) -> bool:
    """Every row has a pixel σ > 0 (its own or the model's): the GLS's weights 1/σ² are finite."""
    if model is None:
        return False
    sig = row_pixel_sigma(obs, model)
    return bool(model.sigma_pixel_m > 0) if sig is None else bool(np.all(sig > 0))


def pixel_covariance(model: DisturbanceModel, residual_map: Any = None, sigma_xy_m: Any = None) -> np.ndarray:
    """σK² L Lᵀ per observation ((…, 2, 2)), or σK² E₂ in the image plane; with ``sigma_xy_m`` (K, 2)
    (``row_pixel_sigma``) each row's L diag(σ_x², σ_y²) Lᵀ ((…, K, 2, 2)), or diag(σ_x², σ_y²)."""
    if sigma_xy_m is not None:
        var = np.asarray(sigma_xy_m, float) ** 2  # (K, 2)
        if residual_map is None:
            diag: np.ndarray = var[..., :, None] * np.eye(2)
            return diag
        L = np.asarray(residual_map, float)
        cov_rows: np.ndarray = (L * var[..., None, :]) @ np.swapaxes(L, -1, -2)
        return cov_rows
    if residual_map is None:
        return model.sigma_pixel_m**2 * np.eye(2)
    L = np.asarray(residual_map, float)
    cov: np.ndarray = model.sigma_pixel_m**2 * (L @ np.swapaxes(L, -1, -2))
    return cov


def residual_variances(obs: Any, theta_rad: Any, model: DisturbanceModel, residual_map: Any = None) -> np.ndarray:
    """Marginal variance of each residual component under the model, (R, K, 2) per observation, with
    ``residual_map`` (R, K, 2, 2) or None.

    The diagonal of Σ = blockdiag(D_n) + U V Uᵀ, column set by column set on the observations (rows):
    working memory linear in the observations (no 2M × 2M block, no images × landmarks × columns
    array). A mode ``both`` error counts twice (its per-image and its per-pass draw).
    """
    img, tgt = observation_rows(obs)
    L = None if residual_map is None else np.asarray(residual_map, float)
    pix = pixel_covariance(model, L, row_pixel_sigma(obs, model))
    var = np.broadcast_to(np.diagonal(pix, axis1=-2, axis2=-1), (obs.runs, img.size, 2)).copy()
    for Z in error_columns(obs, theta_rad, model, L, rows=(img, tgt)):
        if Z is not None:
            var = var + np.sum(Z**2, axis=-1)
    return var


def images_by_row_count(obs: Any) -> list[tuple[int, np.ndarray]]:
    """The images of a row-model set grouped by their number of rows m_n: ``[(m, images), …]``, m
    ascending (m = 0 included), ``images`` (u,) ascending — the batches of the per-image consumers
    (``image_covariance_rows``, the Kalman filter: no padding to the largest image)."""
    counts = np.asarray(obs.rows_per_image)
    return [(int(m), np.flatnonzero(counts == m)) for m in np.unique(counts)]


def rows_per_image_equal(obs: Any, who: str) -> int:
    """m, the number of rows every image of ``obs`` has (0 for no image), or an ``InputValueError`` naming
    ``who`` and the counts: the per-image consumers take one ``images_by_row_count`` group at a time."""
    counts = np.asarray(obs.rows_per_image)
    if counts.size and np.any(counts != counts[0]):
        raise InputValueError(
            f"{who}: the images must have equal numbers of rows, got {sorted(set(counts.tolist()))[:5]}"
            " (group them with gls.structure.images_by_row_count)"
        )
    return int(counts[0]) if counts.size else 0


def image_covariance_rows(obs: Any, theta_rad: Any, model: DisturbanceModel, include_per_pass: bool = True) -> np.ndarray:
    """Covariance of each image's stacked rows q_n = [q_k1x, q_k1y, q_k2x, …] (its rows in canonical
    order), (R, N, 2m, 2m), for a row-model set whose N images have m rows each (``images_by_row_count``
    splits a set into such groups, ``obs.images(group)`` takes one).

    Pixel noise σK² E (each row's own σ², ``row_pixel_sigma``, for a set with per-row σ), the per-image errors A_n A_nᵀ and the catalogue errors, block-diagonal over the
    image's rows (its targets are distinct); the per-pass star-tracker / GNSS errors (modes ``per_pass``
    / ``both``) as if they were per image when ``include_per_pass`` — the marginal covariance of one
    image, blind to their correlation across images (the campaign GLS carries that). On the targets the
    image's rows see: 2m_n × 2m_n, never 2T × 2T; the columns are ``error_columns`` of the rows.
    """
    m = rows_per_image_equal(obs, "image_covariance_rows")
    R, N = obs.runs, obs.n_images
    A, B, C = error_columns(obs, theta_rad, model, rows=(obs.image_index, obs.target_index))
    sig = row_pixel_sigma(obs, model)
    if sig is None:
        cov = np.broadcast_to(model.sigma_pixel_m**2 * np.eye(2 * m), (R, N, 2 * m, 2 * m)).copy()
    else:  # each row's own σ on its two diagonal entries (the image's rows are contiguous: canonical order)
        cov = np.zeros((R, N, 2 * m, 2 * m))
        d = np.arange(2 * m)
        cov[:, :, d, d] = (sig**2).reshape(N, 2 * m)
    for Z in (A, B if include_per_pass else None):
        if Z is not None:
            Zf = Z.reshape(R, N, 2 * m, Z.shape[-1])
            cov += Zf @ np.swapaxes(Zf, -1, -2)
    if C is not None:
        cov6 = cov.reshape(R, N, m, 2, m, 2)
        idx = np.arange(m)
        cov6[:, :, idx, :, idx, :] += np.moveaxis((C @ np.swapaxes(C, -1, -2)).reshape(R, N, m, 2, 2), 2, 0)
    return cov
