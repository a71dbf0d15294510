"""Block-sparse GLS for a whole campaign: per-image blocks, shared errors eliminated block by block.

The residuals of one run (``boresight.core.crlb``) are q = X x + e with x = [θ, p] (θ and any floated
effect parameters p) and the error

    e = ε_pix + Σ_n A_n a_n + Σ_p B_p b_p + Σ_m C_m c_m

— pixel noise ε_pix (independent per observation, covariance σK² L Lᵀ per 2-vector, L the
algorithm's ``residual_map``), per-image star-tracker/GNSS errors a_n (6 per image, modes
``per_image``/``both``), per-pass ones b_p (6 per pass, modes ``per_pass``/``both``) and
catalogue errors c_m (3 per landmark, shared by every image that sees landmark m). Each
nuisance has a Gaussian prior N(0, σ²); its columns are scaled by σ so the prior is N(0, E).

GLS with Σ = cov(e) equals the x-part of the joint MAP estimate of [x, a, b, c] (Woodbury:
whitening with Σ⁻¹ is the same as carrying the nuisances with their prior information and
Schur-complementing them out). The joint information matrix is sparse:

* a_n touches only the rows of image n (2M_n of them): eliminated image by image with a 6×6
  Cholesky of S_n = A_nᵀA_n + E (rows whitened by the pixel noise). For every other column set
  Y, Z of the image the reduced products are

      ⟨Y, Z⟩_n = Y_nᵀ Z_n − (A_nᵀ Y_n)ᵀ S_n⁻¹ (A_nᵀ Z_n),

  which is Y_nᵀ D_n⁻¹ Z_n with the per-image covariance D_n = σK² LLᵀ + A_n A_nᵀ (Woodbury) —
  O(M_n) per image instead of a 2M_n × 2M_n Cholesky;
* b_p touches the images of pass p: its 6×6 block ⟨B, B⟩ summed over the pass, plus E, is
  eliminated pass by pass;
* c_m touches the images that see landmark m. After a_n and b_p are gone the landmarks of one
  image (and of one pass) are coupled, so the catalogue block is block-diagonal over the
  connected groups of landmarks (landmarks linked by a shared image or pass — the points of
  bundle adjustment); each group is eliminated with one dense Cholesky of size 3 × (its
  landmarks).

What is left is the information of x, its right-hand side and χ² = qᵀΣ⁻¹q − yᵀx̂. No array has
an images × columns axis pair: the largest per-image array is (M_n × M_n) 3×3 blocks, the largest
shared one (passes × landmarks) 6×3 blocks, and the cost is linear in images and observations
(plus the cube of each landmark group's size). ``tests/core/test_campaign_gls.py`` checks it equal to
the dense route (per-image Cholesky whitening, shared columns eliminated at the end) to 1e-9.

``solve_nuisances`` back-substitutes for the MAP nuisances at a given x and returns the
*pixel-level* normalised residuals (what is left after the per-image, per-pass and catalogue
errors are removed, divided by the pixel σ): the robust losses of ``boresight.estimate`` weight
observations by these.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.normal_equations import NormalEquations
from boresight.core.gls.rows import RowColumns, RowStructure
from boresight.core.gls.structure import error_columns, gather_slots, observed_slots, pixel_covariance

__all__ = [
    "CampaignGLS",
    "campaign_gls",
    "solve_nuisances",
    "pixel_residuals",
    "sandwich_middle",
    "reduced_rows",
    "single_threaded_blas",
    "dense_rows",
]


# DECISION: the QR factorisations here are small (tens to a few hundred columns); a threaded BLAS
# on a busy machine makes them erratic (2 ms → 2 s for a 520 × 130 QR measured on 2 shared cores),
# so they run single-threaded (threadpoolctl, BSD-3-Clause; without it the BLAS default stands).
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
    import functools

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if _POOL is None:
            return func(*args, **kwargs)
        with _POOL.limit(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper


#: rows stacked before a QR is taken (bounds the memory of a long pass or a large landmark group)
CHUNK_ROWS = 20000


def _qr_stack(row_blocks: Any, ncols: Any, R: Any) -> np.ndarray:
    """R factor (R, ≤ncols, ncols) of the stacked rows (each block (R, k, ncols)), chunked."""
    acc: np.ndarray = np.zeros((R, 0, ncols))
    buf, nbuf = [], 0
    for blk in row_blocks:
        if blk.shape[1] == 0:
            continue
        buf.append(blk)
        nbuf += blk.shape[1]
        if nbuf >= CHUNK_ROWS:
            acc = np.linalg.qr(np.concatenate([acc] + buf, axis=1), mode="r")  # type: ignore[assignment]  # R, not QRResult
            buf, nbuf = [], 0
    if buf or acc.shape[1] == 0:
        acc = np.linalg.qr(np.concatenate([acc] + buf, axis=1), mode="r")  # type: ignore[assignment]  # R, not QRResult
    return acc


def _place(Cpart: Any, loc: Any, K: Any) -> np.ndarray:
    """Slot columns (R, u, k, S, 3) → local landmark columns (R, u, k, 3K); loc (u, S), −1 = none."""
    R, u, k, S, _ = Cpart.shape
    locf = np.where(loc < 0, K, loc)
    out = np.zeros((R, u, k, K + 1, 3))
    uu = np.broadcast_to(np.arange(u)[:, None], loc.shape)
    out[:, uu, :, locf, :] = np.moveaxis(Cpart, (1, 3), (0, 1))
    return out[..., :K, :].reshape(R, u, k, 3 * K)


@dataclass
class CampaignGLS:
    """The reduced normal equations of a campaign and the square-root factors for back-substitution.

    ``normal_equations`` is a ``NormalEquations`` over x = [θ, extras] (data part only, dof =
    residual components − unknowns).
    """

    normal_equations: NormalEquations
    n_params: int
    _store: dict[str, Any]

    @property
    def slots(self) -> tuple[np.ndarray, np.ndarray]:
        """The per-image slot layout of the fit: (landmark index (N, Mx), observed (N, Mx))."""
        return self._store["idx"], self._store["valid"]

    @property
    def image_gram(self) -> np.ndarray:
        """(R, n+1, n+1): the Gram of [X | q] with only the pixel noise and the per-image errors
        eliminated (the information against which ``diagnose`` measures canonical correlations)."""
        gram: np.ndarray = self._store["image_gram"]
        return gram

    @property
    def whitened_columns(self) -> np.ndarray:
        """(R, N, Mx, 2, n+1): [X | q] whitened by the pixel noise, unweighted, in the slot layout."""
        y: np.ndarray = self._store["Y"]
        return y


def _whitened_columns(
    obs: Any, theta_rad: Any, G: Any, q: Any, model: Any, residual_map: Any, obs_weights: Any, slotted: Any
) -> tuple[tuple[Any, Any, Any, Any], np.ndarray, dict[str, Any]]:
    """The slot layout, the whitened columns [A | B | C | Y] (robust weights applied), the valid
    rows and the store of the unweighted ones (``_store`` of ``CampaignGLS``)."""
    n = G.shape[-1]
    idx, valid = observed_slots(obs.mask)
    v4 = valid[None, :, :, None]
    Lmap = None if residual_map is None else gather_slots(np.asarray(residual_map, float), idx)
    Xs = G if slotted else gather_slots(G, idx)
    qs = np.asarray(q, float) if slotted else gather_slots(np.asarray(q, float), idx)
    rowvalid = v4 & (np.any(Xs != 0, axis=-1) | (qs != 0))  # (R, N, Mx, 2), as the dense route counts
    w = None
    if obs_weights is not None:
        w = gather_slots(np.asarray(obs_weights, float)[..., None], idx)[..., 0]  # (R, N, Mx)
        rowvalid = rowvalid & (w[..., None] > 0)
    empty = np.zeros(Xs.shape[:-1] + (0,))
    A, B, C = (empty if Z is None else Z for Z in error_columns(obs, theta_rad, model, Lmap, slots=(idx, valid)))
    Y = np.concatenate([Xs, qs[..., None]], axis=-1)  # (R, N, Mx, 2, n+1)

    # whitening by the pixel noise σK² L Lᵀ per observation (identity L in the image plane)
    sk = model.sigma_pixel_m
    if Lmap is None:
        # E/σK per observation: a scaling (the same numbers as the 2 × 2 products, without them)
        f = (v4 / sk)[..., None]
        Y, A, B, C = (Z * f for Z in (Y, A, B, C))
    else:
        S_o = sk**2 * (Lmap @ np.swapaxes(Lmap, -1, -2))
        S_o = np.where(v4[..., None], S_o, np.eye(2))
        Wh = np.linalg.inv(np.linalg.cholesky(S_o)) * v4[..., None]
        Y, A, B, C = (Wh @ Z for Z in (Y, A, B, C))
    # the unweighted whitened columns give the residuals; the weighted ones the fit
    store = dict(idx=idx, valid=valid, Y=Y, A=A, B=B, C=C, n=n)
    if w is not None:
        sw = np.sqrt(np.maximum(w, 0.0))[..., None, None]
        Y, A, B, C = (Z * sw for Z in (Y, A, B, C))
    store.update(na=A.shape[-1], nb=B.shape[-1], nc=3 if C.shape[-1] else 0)
    return (A, B, C, Y), rowvalid, store


def _eliminate_images(A: Any, B: Any, C: Any, Y: Any, store: Any, R: Any, N: Any) -> Any:
    """Stage 1, per image: rows [A | B | C slots | Y] + prior rows [E 0 …]; eliminate a_n.
    The reduced rows (R, N, k1, ·); sets ``store['top1']`` and ``store['image_gram']``."""
    na, nc, ny = store["na"], store["nc"], store["n"] + 1
    Mx = store["idx"].shape[1]
    Cslot = np.zeros((R, N, Mx, 2, Mx, nc))
    if nc:
        Cslot[:, :, np.arange(Mx), :, np.arange(Mx), :] = np.moveaxis(C, 2, 0)
    K1 = np.concatenate([A, B, Cslot.reshape(R, N, Mx, 2, Mx * nc), Y], axis=-1).reshape(R, N, 2 * Mx, -1)
    if na:
        # Householder QR of the na nuisance columns [A; E] only, then the orthogonal projection
        # of the other columns [Rest; 0] onto the complement: rows (2M_n + na) per image carrying
        # the same reduced information as the full factorisation, at a fraction of its cost.
        Aaug = np.concatenate([K1[..., :na], np.broadcast_to(np.eye(na), (R, N, na, na))], axis=2)
        Q, Raa = np.linalg.qr(Aaug, mode="reduced")  # Q (R, N, 2Mx + na, na)
        rest = K1[..., na:]
        QtR = np.swapaxes(Q[:, :, : 2 * Mx], -1, -2) @ rest  # (R, N, na, ·) = Qᵀ [Rest; 0]
        rest1 = np.concatenate([rest, np.zeros((R, N, na, rest.shape[-1]))], axis=2) - Q @ QtR
        store["top1"] = np.concatenate([Raa, QtR], axis=-1)
    else:
        rest1 = K1
    del K1
    # the information of x with only the per-image errors eliminated (pixel noise and a_n: xᵀD_n⁻¹x
    # summed over images), against which the diagnosis measures canonical correlations
    Yr = rest1[..., -ny:]
    store["image_gram"] = np.einsum("rnki,rnkj->rij", Yr, Yr)
    return rest1


def _eliminate_passes(obs: Any, rest1: Any, store: Any, R: Any, M: Any) -> list[tuple[Any, Any]]:
    """Stage 2, per pass: rows [B | C of the pass's landmarks | Y] + prior rows; eliminate b_p.
    The units left for stage 3: (rows (R, u, k, 3S + ny), landmarks (u, S) with −1 = none)."""
    idx, valid, nb, nc = store["idx"], store["valid"], store["nb"], store["nc"]
    N, Mx = idx.shape
    k1 = rest1.shape[2]
    if not nb:
        return [(rest1, np.where(valid, idx, -1) if nc else np.zeros((N, 0), int))]
    passes, pidx = np.unique(obs.pass_index, return_inverse=True)
    units = []
    tops2 = {}
    for p in range(passes.size):
        imgs = np.flatnonzero(pidx == p)
        lms = np.unique(idx[imgs][valid[imgs]])
        loc = np.full(M, -1)
        loc[lms] = np.arange(lms.size)
        rp = rest1[:, imgs]
        Cp = rp[..., nb : nb + Mx * nc].reshape(R, imgs.size, k1, Mx, nc)
        Cloc = _place(Cp, np.where(valid[imgs], loc[idx[imgs]], -1), lms.size) if nc else Cp.reshape(R, imgs.size, k1, 0)
        rows = np.concatenate([rp[..., :nb], Cloc, rp[..., nb + Mx * nc :]], axis=-1).reshape(R, imgs.size * k1, -1)
        ncol = rows.shape[-1]
        prior = np.zeros((R, nb, ncol))
        prior[:, np.arange(nb), np.arange(nb)] = 1.0
        R2 = _qr_stack([rows[:, i : i + CHUNK_ROWS] for i in range(0, rows.shape[1], CHUNK_ROWS)] + [prior], ncol, R)
        tops2[p] = (R2[:, :nb], lms)
        units.append((R2[:, None, nb:, nb:], lms[None, :]))
    store["tops2"] = tops2
    store["pidx"] = pidx
    return units


def _landmark_groups(units: Any, M: Any) -> tuple[Any, dict[Any, Any]]:
    """The connected groups of landmarks (those sharing rows): (component of each landmark,
    {group: [(rows, landmarks, selected units)]})."""
    rows_, cols_ = [], []
    uid = 0
    for _, lm in units:
        uu, ss = np.nonzero(lm >= 0)
        rows_.append(lm[uu, ss])
        cols_.append(M + uid + uu)
        uid += lm.shape[0]
    r_, c_ = np.concatenate(rows_), np.concatenate(cols_)
    graph = coo_matrix((np.ones(r_.size), (r_, c_)), shape=(M + uid,) * 2)
    _, comp = connected_components(graph, directed=False)
    lm_comp = comp[:M]
    blocks_by_group: dict[Any, list[Any]] = {}
    for rows, lm in units:
        first = np.where((lm >= 0).any(axis=1), lm.max(axis=1), -1)
        for g in np.unique(lm_comp[first[first >= 0]]):
            blocks_by_group.setdefault(int(g), []).append(
                (rows, lm, np.flatnonzero((first >= 0) & (lm_comp[np.maximum(first, 0)] == g)))
            )
    return lm_comp, blocks_by_group


def _group_rows(blocks: Any, loc: Any, n_members: Any, ny: Any, R: Any) -> Iterator[Any]:
    """The rows of one landmark group, chunk by chunk, with its prior rows last."""
    kk = 3 * n_members
    for rows, lm, sel in blocks:
        for i in range(0, sel.size, max(1, CHUNK_ROWS // max(rows.shape[2], 1))):
            s = sel[i : i + max(1, CHUNK_ROWS // max(rows.shape[2], 1))]
            sub = rows[:, s]
            S = lm.shape[1]
            Cl = _place(
                sub[..., : 3 * S].reshape(R, s.size, sub.shape[2], S, 3),
                np.where(lm[s] >= 0, loc[np.maximum(lm[s], 0)], -1),
                n_members,
            )
            yield np.concatenate([Cl, sub[..., 3 * S :]], axis=-1).reshape(R, -1, kk + ny)
    prior = np.zeros((R, kk, kk + ny))
    prior[:, np.arange(kk), np.arange(kk)] = 1.0
    yield prior


def _eliminate_landmarks(units: Any, store: Any, R: Any, M: Any) -> list[Any]:
    """Stage 3, per landmark group: rows [C of the group's landmarks | Y] + prior; eliminate c.
    The final rows of [x | q] of every group (or of every unit when there is no catalogue error)."""
    ny = store["n"] + 1
    if not store["nc"]:
        return [rows.reshape(R, -1, rows.shape[-1])[..., -ny:] for rows, _ in units]
    final = []
    lm_comp, blocks_by_group = _landmark_groups(units, M)
    tops3 = {}
    for g, blocks in blocks_by_group.items():
        members = np.flatnonzero(lm_comp == g)
        members = members[np.isin(members, np.concatenate([np.unique(lm[sel][lm[sel] >= 0]) for _, lm, sel in blocks]))]
        loc = np.full(M, -1)
        loc[members] = np.arange(members.size)
        kk = 3 * members.size
        R3 = _qr_stack(_group_rows(blocks, loc, members.size, ny, R), kk + ny, R)
        tops3[g] = (R3[:, :kk], members)
        final.append(R3[:, kk:, kk:])
    store["tops3"] = tops3
    return final


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
    """Accumulate the campaign's GLS normal equations block by block (square-root form).

    ``G`` (R, N, M, 2, n) Jacobian of q w.r.t. x (θ first), ``q`` (R, N, M, 2) residuals,
    ``residual_map`` (R, N, M, 2, 2) or None (image plane), ``obs_weights`` (R, N, M) robust
    weights on the pixel noise of each observation (1 = as modelled, 0 = dropped) or None.
    ``slotted``: G (R, N, Mx, 2, n) and q (R, N, Mx, 2) are already in the per-image slot layout
    of ``observed_slots(obs.mask)`` (each image's observed landmarks first; a caller with many columns
    saves the images × every-landmark array).

    Each elimination is a QR factorisation of the stacked, whitened rows of the block with the
    nuisance's prior rows E appended (a square-root information filter): numerically as good as
    whitening each image with the Cholesky factor of its covariance, without forming it.
    Stages: ``_whitened_columns``, then ``_eliminate_images`` (a_n), ``_eliminate_passes`` (b_p)
    and ``_eliminate_landmarks`` (c).
    """
    R, N, M = obs.runs, obs.n_images, obs.n_landmarks
    G = np.asarray(G, float)
    n = G.shape[-1]
    if not model.sigma_pixel_m > 0:
        raise ValueError(f"campaign_gls: GLS needs model.sigma_pixel_m > 0, got {model.sigma_pixel_m!r}")
    (A, B, C, Y), rowvalid, store = _whitened_columns(obs, theta_rad, G, q, model, residual_map, obs_weights, slotted)
    rest1 = _eliminate_images(A, B, C, Y, store, R, N)
    units = _eliminate_passes(obs, rest1, store, R, M)
    final = _eliminate_landmarks(units, store, R, M)
    YYt = sum(np.einsum("rki,rkj->rij", f, f) for f in final)
    YYt = 0.5 * (YYt + np.swapaxes(YYt, -1, -2))
    ne = NormalEquations(n, R)
    ne.data_information = YYt[:, :n, :n].copy()
    ne.vector = YYt[:, :n, n].copy()
    ne.weighted_sum_squares = YYt[:, n, n].copy()
    ne.n_residuals = rowvalid.reshape(R, -1).sum(axis=1)
    return CampaignGLS(normal_equations=ne, n_params=n, _store=store)


def _tri_solve(T: Any, b: Any) -> np.ndarray:
    return np.linalg.solve(T, b[..., None])[..., 0]


@_single_threaded
def solve_nuisances(fit: CampaignGLS, dx: Any, per_image_whitened: bool = False) -> np.ndarray:
    """Pixel-level normalised residuals at the correction ``dx`` (R, n), (R, N, Mx, 2) in slots.

    With ``per_image_whitened`` the per-image errors are not removed but whitened: the residual
    with the shared errors at their MAP value, multiplied by the inverse Cholesky factor of each
    image's covariance D_n (pixel noise and per-image errors) — N(0, E) rows in slot order, up
    to the leverage of x and the shared errors, as a whiteness test needs them (the MAP removal
    of the per-image errors correlates an image's residuals).

    The MAP nuisances given x (catalogue c, then per-pass b, then per-image a) are removed from
    the whitened residual q − X dx by back-substitution in the stored square-root factors (of the
    robustly weighted fit, if weights were given); what remains is in units of the pixel σ,
    without the robust weights (a down-weighted observation shows its full residual). The slot layout is
    ``fit._store['idx']``, ``['valid']``.
    """
    s = fit._store
    na, nb, nc = s["na"], s["nb"], s["nc"]
    dx = np.asarray(dx, float)
    R = dx.shape[0]
    ext = np.concatenate([-dx, np.ones((R, 1))], axis=-1)  # Y · ext = q − X dx
    idx, valid = s["idx"], s["valid"]
    N, Mx = idx.shape
    M = int(idx.max()) + 1
    c_l = np.zeros((R, max(M, 1), 3))
    if nc:
        for top, members in s["tops3"].values():
            kk = 3 * members.size
            c = _tri_solve(top[:, :, :kk], np.einsum("rij,rj->ri", top[:, :, kk:], ext))
            c_l[:, members] = c.reshape(R, members.size, 3)
    c_slots = c_l[:, idx] * valid[None, :, :, None]  # (R, N, Mx, 3)
    b_img = np.zeros((R, N, nb))
    if nb:
        for p, (top, lms) in s["tops2"].items():
            rhs = np.einsum("rij,rj->ri", top[:, :, nb + 3 * lms.size * (nc > 0) :], ext)
            if nc:
                rhs = rhs - np.einsum("rij,rj->ri", top[:, :, nb : nb + 3 * lms.size], c_l[:, lms].reshape(R, -1))
            b = _tri_solve(top[:, :, :nb], rhs)
            b_img[:, s["pidx"] == p] = b[:, None]
    A, B, C, Y = s["A"], s["B"], s["C"], s["Y"]
    e: np.ndarray = np.einsum("rnmki,ri->rnmk", Y, ext) - np.einsum("rnmkb,rnb->rnmk", B, b_img)
    if nc:
        e = e - np.einsum("rnmkj,rnmj->rnmk", C, c_slots)
    if per_image_whitened:
        if not na:
            return e
        # whiten each image by the Cholesky factor of its covariance in pixel units, E + A_n A_nᵀ
        An = A.reshape(R, N, 2 * Mx, na)
        L = np.linalg.cholesky(np.eye(2 * Mx) + An @ np.swapaxes(An, -1, -2))
        white: np.ndarray = np.linalg.solve(L, e.reshape(R, N, 2 * Mx)[..., None])[..., 0].reshape(R, N, Mx, 2)
        return white
    if na:
        top = s["top1"]  # (R, N, na, na + nb + Mx nc + ny)
        rhs = np.einsum("rnij,rj->rni", top[..., na + nb + Mx * nc :], ext)
        rhs = rhs - np.einsum("rnij,rnj->rni", top[..., na : na + nb], b_img)
        if nc:
            rhs = rhs - np.einsum("rnij,rnj->rni", top[..., na + nb : na + nb + Mx * nc], c_slots.reshape(R, N, -1))
        a = np.linalg.solve(top[..., :na], rhs[..., None])[..., 0]
        e = e - np.einsum("rnmka,rna->rnmk", A, a)
    return e


def sandwich_middle(obs: Any, theta_rad: Any, model: DisturbanceModel, WG: Any, residual_map: Any = None) -> np.ndarray:
    """(WG)ᵀ Σ (WG) for weighted Jacobian columns WG (R, N, M, 2, n), block by block, (R, n, n).

    Pixel noise: Σ_o (WG)_oᵀ σK² LLᵀ (WG)_o; a shared error with scaled columns Z (one per
    image, pass or landmark) adds TᵀT with T = Σ over the rows it touches of Zᵀ WG.
    """
    WG = np.where(obs.mask[None, :, :, None, None], WG, 0.0)
    A, B, C = error_columns(obs, theta_rad, model, residual_map)
    pix = pixel_covariance(model, residual_map)
    mid = np.einsum("rnmki,kl,rnmlj->rij", WG, pix, WG) if np.ndim(pix) == 2 else np.einsum("rnmki,rnmkl,rnmlj->rij", WG, pix, WG)
    if A is not None:
        T = np.einsum("rnmka,rnmki->rnai", A, WG)
        mid = mid + np.einsum("rnai,rnaj->rij", T, T)
    if B is not None:
        passes, pidx = np.unique(obs.pass_index, return_inverse=True)
        Tn = np.einsum("rnmka,rnmki->rnai", B, WG)
        T = np.zeros((Tn.shape[0], passes.size) + Tn.shape[2:])
        np.add.at(T, (slice(None), pidx), Tn)  # type: ignore[arg-type]  # numpy's stubs take no slice in the index tuple
        mid = mid + np.einsum("rpai,rpaj->rij", T, T)
    if C is not None:
        T = np.einsum("rnmka,rnmki->rmai", C, WG)
        mid = mid + np.einsum("rmai,rmaj->rij", T, T)
    sym: np.ndarray = 0.5 * (mid + np.swapaxes(mid, -1, -2))
    return sym


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
    fit = campaign_gls(obs, theta_rad, G, q, model, residual_map, obs_weights=obs_weights)
    R = obs.runs
    e = solve_nuisances(fit, np.zeros((R, G.shape[-1])))
    idx, valid = fit._store["idx"], fit._store["valid"]
    out = np.zeros(obs.xy_m.shape)
    nn, ss = np.nonzero(valid)
    out[:, nn, idx[nn, ss]] = e[:, nn, ss]
    # χ² minimised over a (linearised) correction of x: the noise-model consistency statistic
    # whatever weighting produced θ
    sol = fit.normal_equations.solve(check=False)
    return out, sol.chi2


@_single_threaded
def reduced_rows(fit: CampaignGLS, covariance_x: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each residual row's reduced x-row and leverage, from the fit's square-root factors.

    The fit's joint information over [a (per image), b (per pass), c (catalogue), x] is RᵀR with R
    block upper-triangular (the factors kept for ``solve_nuisances``). For the whitened
    (unweighted) row z_i = [z_ν, z_x] of residual component i, forward substitution Rᵀv = z_i gives

        v_ν = R_νν⁻ᵀ z_ν                      (image block, then its pass, then its landmark group)
        z̃_i = z_x − R_νxᵀ v_ν = z_x − J_xν J_νν⁻¹ z_ν     (the row with the nuisances eliminated)
        h_i = |v_ν|² + z̃_iᵀ C_x z̃_i            (C_x = ``covariance_x``, the inverse reduced information)

    With fit weights w (``obs_weights``) J is the weighted information, h_i = z_iᵀ J⁻¹ z_i and the
    pixel-level residual of an unweighted fit has variance 1 − h_i; the reduced rows satisfy
    Σ_i w_i z̃_i q̃_i = the reduced right-hand side (``tests/core/test_campaign_gls.py``), which is what
    the M-estimator sandwich of ``boresight.estimate`` needs. Returns (h (R, N, Mx, 2),
    z̃ (R, N, Mx, 2, n)) in the slot layout. Memory: one landmark group's rows × its 3·landmarks
    columns at a time.
    """
    s = fit._store
    na, nb, nc, n = s["na"], s["nb"], s["nc"], s["n"]
    A, B, C, Y = s["A"], s["B"], s["C"], s["Y"]
    idx, valid = s["idx"], s["valid"]
    R, N, Mx = Y.shape[:3]
    zx = Y[..., :n].copy()  # (R, N, Mx, 2, n)
    vsq = np.zeros((R, N, Mx, 2))
    va: Any = None  # set where there are per-image nuisances (na), used only then
    if na:
        top = s["top1"]
        Raa = top[..., :na]
        va = np.linalg.solve(np.swapaxes(Raa, -1, -2), A.reshape(R, N, 2 * Mx, na).swapaxes(-1, -2))  # (R, N, na, 2Mx)
        va = va.swapaxes(-1, -2).reshape(R, N, Mx, 2, na)
        vsq += np.sum(va**2, axis=-1)
        off = na + nb + Mx * nc
        zx -= np.einsum("rnax,rnska->rnskx", top[..., off : off + n], va)
    zb: Any = B.copy() if nb else None
    if nb and na:
        zb -= np.einsum("rnab,rnska->rnskb", s["top1"][..., na : na + nb], va)
    vb: Any = None  # set where there are per-pass nuisances (nb), used only then
    if nb:
        vb = np.zeros_like(zb)
        for p, (top, lms) in s["tops2"].items():
            imgs = np.flatnonzero(s["pidx"] == p)
            rhs = zb[:, imgs].reshape(R, -1, nb).swapaxes(-1, -2)
            vb[:, imgs] = (
                np.linalg.solve(np.swapaxes(top[:, :, :nb], -1, -2), rhs).swapaxes(-1, -2).reshape(R, imgs.size, Mx, 2, nb)
            )
            off = nb + 3 * lms.size * (nc > 0)
            zx[:, imgs] -= np.einsum("rbx,rnskb->rnskx", top[:, :, off : off + n], vb[:, imgs])
        vsq += np.sum(vb**2, axis=-1)
    if nc:
        passes_of: Any = s.get("pidx")
        for top, members in s["tops3"].values():
            kk = 3 * members.size
            loc = np.full(int(idx.max()) + 1, -1)
            loc[members] = np.arange(members.size)
            imgs = np.flatnonzero(np.any(valid & (loc[idx] >= 0), axis=1))
            RccT = np.swapaxes(top[:, :, :kk], -1, -2)
            Rcx = top[:, :, kk : kk + n]
            for i0 in range(0, imgs.size, max(1, CHUNK_ROWS // max(2 * Mx, 1))):
                im = imgs[i0 : i0 + max(1, CHUNK_ROWS // max(2 * Mx, 1))]
                u = im.size
                lslot = np.where(valid[im], loc[idx[im]], members.size)  # (u, Mx); members.size = none
                P = np.zeros((u, Mx, members.size + 1))
                P[np.arange(u)[:, None], np.arange(Mx)[None, :], lslot] = 1.0  # slot → group landmark, one-hot
                rhs = np.einsum("rudkj,udm->rudkmj", C[:, im], P)
                if na:
                    # − R_acᵀ v_a: the image's slot-landmark columns of its a-rows
                    Rac = s["top1"][:, im][..., na + nb : na + nb + Mx * nc].reshape(R, u, na, Mx, 3)
                    rhs -= np.einsum("ruacj,rudka,ucm->rudkmj", Rac, va[:, im], P, optimize=True)
                if nb:
                    for p in np.unique(passes_of[im]):
                        top2, lms = s["tops2"][p]
                        sel = np.flatnonzero(passes_of[im] == p)
                        Rbc = top2[:, :, nb : nb + 3 * lms.size].reshape(R, nb, lms.size, 3)
                        Q = np.zeros((lms.size, members.size + 1))
                        Q[np.arange(lms.size), np.where(loc[lms] >= 0, loc[lms], members.size)] = 1.0
                        rhs[:, sel] -= np.einsum("rblj,rudkb,lm->rudkmj", Rbc, vb[:, im[sel]], Q, optimize=True)
                rhs = rhs[..., : members.size, :].reshape(R, u * Mx * 2, kk)
                vc = np.linalg.solve(RccT, rhs.swapaxes(-1, -2)).swapaxes(-1, -2)  # (R, rows, kk)
                vsq[:, im] += np.sum(vc**2, axis=-1).reshape(R, u, Mx, 2)
                zx[:, im] -= np.einsum("rcx,rqc->rqx", Rcx, vc).reshape(R, u, Mx, 2, n)
    zx = zx * valid[None, :, :, None, None]
    h = vsq + np.einsum("rnski,rij,rnskj->rnsk", zx, np.asarray(covariance_x, float), zx)
    return h * valid[None, :, :, None], zx


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
    adapter of callers not yet on rows (issue 27). Rows are ``np.nonzero(obs.mask)``, the canonical
    (image, landmark) order; G (R, N, M, 2, n), q (R, N, M, 2), ``residual_map`` (R, N, M, 2, 2) or
    None, or with ``slotted`` G and q in the slot layout of ``observed_slots(obs.mask)``. Each row is
    whitened by its pixel noise σK² L Lᵀ (a division by σK in the image plane)."""
    idx, valid = observed_slots(obs.mask)
    nn, ss = np.nonzero(valid)
    st = RowStructure(nn, idx[nn, ss], np.asarray(obs.pass_index), int(obs.n_landmarks))
    G = np.asarray(G, float)
    q = np.asarray(q, float)
    X = (G[:, nn, ss] if slotted else G[:, nn, idx[nn, ss]]).copy()
    qr = (q[:, nn, ss] if slotted else q[:, nn, idx[nn, ss]]).copy()
    L = None if residual_map is None else gather_slots(np.asarray(residual_map, float), idx)
    cols = error_columns(obs, theta_rad, model, L, slots=(idx, valid))
    R, K = X.shape[0], nn.size
    A, B, C = (np.zeros((R, K, 2, 0)) if Z is None else Z[:, nn, ss] for Z in cols)
    sk = model.sigma_pixel_m
    if L is None:
        X, qr, A, B, C = (Z / sk for Z in (X, qr, A, B, C))
    else:
        Wh = np.linalg.inv(np.linalg.cholesky(sk**2 * (L[:, nn, ss] @ np.swapaxes(L[:, nn, ss], -1, -2))))
        X, A, B, C = (Wh @ Z for Z in (X, A, B, C))
        qr = (Wh @ qr[..., None])[..., 0]
    return st, RowColumns(X=X, q=qr, A=A, B=B, C=C)
