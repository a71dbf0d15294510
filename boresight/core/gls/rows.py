"""The one GLS on rows: the campaign's nuisances eliminated exactly, in information form.

``docs/architecture.md``, "The error structure and the one GLS on rows", is the design; this module
is its code. A campaign is K rows (observations), each in one image n(k) and of one target t(k);
each image is in one pass p(n). The residual of row k, whitened by its pixel noise (2-vector), is

    q_k = X_k x + A_k a_{n(k)} + B_k b_{p(n(k))} + C_k c_{t(k)} + ε_k,     ε_k ~ N(0, E₂)

with x = [θ, floated parameters] (n), a_n the per-image errors (na), b_p the per-pass errors (nb),
c_t the catalogue error of target t (3, or none) and every nuisance with the prior N(0, E) (the
columns are scaled by σ: ``boresight.core.gls.structure``). A robust weight w_k multiplies the
information of row k (w = 0 drops it). The GLS estimate of x is the x-part of the joint MAP
estimate (Woodbury), whose information is

    J = Σ_k w_k z_kᵀ z_k + blockdiag(0_x, E_ν),    z_k = [A_k  B_k  C_k  X_k] placed at its nuisances,

a bundle-adjustment matrix: 3 × 3 blocks per target, na × na per image, nb × nb per pass,
coupled only through rows. It is eliminated in the design's order, with Y = [X | q] carried
as ny = n + 1 right-hand columns (so the reduced [Y]-block holds the information of x, its
right-hand side and the weighted sum of squares at once):

1. **Rows.** A target seen by exactly one row has its c_t in that row only; eliminating it is
   whitening the row by (E₂ + w C Cᵀ)^(-1/2) (Woodbury: E₂ − w C (E₃ + w CᵀC)⁻¹ Cᵀ =
   (E₂ + w C Cᵀ)⁻¹). Exact, and free: a single-use ground-control point costs its row.
2. **Targets.** For every shared target, L_t L_tᵀ = H_tt = E₃ + Σ_{k∈t} w C_kᵀ C_k; the rows
   Ũ_t = L_t⁻¹ H_{t,·} of a sparse matrix Ũ (3 per target, non-zero on the images and passes that
   see t) give the Schur complement S = H_νν − Ũ_νᵀ Ũ_ν on ν = [a, b] by one sparse product
   (scipy.sparse, BSD-3-Clause), and S_νy = H_νy − Ũ_νᵀ Ũ_y, S_yy = H_yy − Ũ_yᵀ Ũ_y.
3. **Images and passes.** S (D = N·na + P·nb square) is factorised: a batched dense Cholesky
   (numpy) when D is at most ``DENSE_MAX`` (a pass or two), else scipy's SuperLU (``splu``,
   BSD-3-Clause, symmetric mode, a minimum-degree ordering on AᵀA + A,
   no pivoting off the diagonal: S is symmetric positive definite, every block carries the prior E).
4. **x.** The reduced [Y] block — its [x, x] part the information of x, its [x, q] part the
   right-hand side, its [q, q] part the weighted sum of squares q̃ᵀΣ⁻¹q̃ of ``NormalEquations``
   (χ² = that − yᵀx̂) — is S_yy − S_νyᵀ S⁻¹ S_νy, but it is *accumulated from the reduced rows*:
   with ν_Y = S⁻¹ S_νy (and c_Y target by target) the MAP nuisances of each column of Y and
   Ỹ_k = Y_k − A_k a_Y − B_k b_Y − C_k c_Y,

       min_ν Σ_k w_k |Y_k e − Z_k ν|² + |ν|²  =  eᵀ [Σ_k w_k Ỹ_kᵀ Ỹ_k + ν_Yᵀ ν_Y] e.

DECISION: information form for the nuisances (not the square-root form of the slot GLS this
replaced: it is what makes the targets' elimination a sparse product; every block carries the prior
E, so S is well conditioned, 1 + λ_max(ZᵀZ)), but the reduced x-block as that sum of squares: its
error is second order in the error of ν_Y (a minimiser), where the subtraction S_yy − S_νyᵀS⁻¹S_νy
lost eps·|H_yy|/|reduced| — 5e-4 relative on the planner's nearly unobservable θ (σ 3 517″,
``plan-kiev680``), 3e-9 on campaign-6pass's σ, ≤ 3e-11 on the test modes. With the sum of squares,
against the full-Σ route (``crlb.full_residual_covariance``) on every error mode of
``tests/core/test_campaign_gls.py``: θ and its covariance to ≤ 5e-13 relative, as the square-root
form was.

**Attitude samples** (a pushbroom line is an image whose star-tracker error interpolates its two tracker
samples: ``RowStructure.sample_index`` / ``sample_weight`` (N, 2), S samples). The per-image nuisances
become a_n = w_0 a_{s_0(n)} + w_1 a_{s_1(n)} = (W a)_n with the prior N(0, E) on each *sample*: every
per-row product stays per image (steps 1-2 unchanged), and only the reduced system is mapped,
H_νν ← Wᵀ H_aa W + E (image blocks coupling their two samples: banded in time), S_νy ← Wᵀ H_ay,
Ũ_ν ← Ũ_ν W; it is assembled sparse and factorised by either kernel. D = S·na + P·nb. A frame camera
is the one-sample case (samples [n, n], weights [1, 0]); without a sample table nothing changes.
The leverage takes a row's own columns on the sample system, [w_0 A, w_1 A, B] at its two samples and its pass.

**A correlated prior on the samples** (``RowStructure.sample_correlation`` (S, na): a star tracker's Gauss–Markov error,
``boresight.core.line_scan``). Column j of the per-sample nuisances may be, instead of white, a unit-variance AR(1)
over the samples in order: a_s = φ_s a_{s−1} + √(1 − φ_s²) e_s, e ~ N(0, E), φ_0 = 0 (and 0 where an independent
process starts), so Cov(a_s, a_m) = Π φ between them (= exp(−|t_s − t_m|/τ) for φ_s = exp(−Δt_s/τ)). The
innovations e = M a, M lower bidiagonal (M_ss = c_s = 1/√(1 − φ_s²), M_s,s−1 = −d_s = −φ_s c_s), are N(0, E), so the
prior's information is MᵀM: *tridiagonal* (c_s² + d_{s+1}² on the diagonal, −c_s d_s beside it; Rybicki & Press 1995,
ApJ 442, 1: the inverse of the exponential covariance on uneven times; the same factor a Kalman/RTS smoother of the
process runs through). It replaces E on those columns in H_νν (the band it adds lies inside the one the lines' two
samples already make), the prior's |ν|² of step 4 becomes |M a|² (innovations), and φ = 0 is E exactly. Everything
stays linear in samples; no S × S covariance is formed. λ_min(MᵀM) ≥ (1 − φ_max)/(1 + φ_max) (the covariance's row
sums are ≤ Σ_m φ_max^|m|), which ``condition_bound`` divides by.

Back-substitution (``row_nuisances``) gives the MAP nuisances at a correction dx of x, and
``row_residuals`` the pixel-level residuals q̃ − X dx − A a − B b − C c (N(0, E₂) per row up to
leverage), or with ``per_image_whitened`` the residual with the shared b, c removed and each
image whitened by the Cholesky factor of E + A_n A_nᵀ (its rows, 2m_n × 2m_n, images batched by
equal m_n).

``row_reduced_rows``: for the unweighted row z_i of residual component i, the reduced x-row
z̃_i = z_x − J_xν J_νν⁻¹ z_ν and the leverage h_i = z_iᵀ J⁻¹ z_i, by the same elimination:
c first (v = L_t⁻¹ C_iᵀ, h gets |v|²; for a folded row the 2 × 2 whitening), then with
z̄_ν = α_i − Ũ_νᵀ v (α_i the row's own [A_i, B_i] at its image and pass)

    h_i += z̄_νᵀ S⁻¹ z̄_ν = α_iᵀ (S⁻¹)_II α_i − 2 α_iᵀ (S⁻¹ Ũ_tᵀ)_I v + vᵀ Ũ_t S⁻¹ Ũ_tᵀ v,
    z̃_i = z̄_x − S_xν S⁻¹ z̄_ν,          h_i += z̃_iᵀ C_x z̃_i.

z̃ needs S⁻¹ S_νx only (n solves): exact on both paths. The leverage needs the blocks of S⁻¹ on
each row's image, pass and the images sharing its target — the selected inverse of S on its
sparsity pattern. Up to D = ``LEVERAGE_MAX`` S⁻¹ is formed whole (from either factorisation);
above, h_ν = z̄_νᵀ S⁻¹ z̄_ν from the selected inverse of S (``_selected_inverse``: Takahashi's
recursion on a banded Cholesky factor, the pass unknowns by the block inverse) or, when its band is
too wide, by solving S X = Z̄ with the SuperLU factor (``_leverage_by_solves``, its DECISION):
exact on every route, never an approximation.

Memory: O(K) for the rows (processed in chunks of ``CHUNK_ROWS`` for the per-row products),
O(nnz of Ũ) = K·3·(na + nb) for the fill's factor, O(nnz of S's factor) for SuperLU, and
R·D² on the dense path (and for the leverage up to ``LEVERAGE_MAX``; above, a batch of solves). Nothing has an images × targets axis pair.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
from scipy.linalg import solve_triangular
from scipy.sparse.linalg import splu

from boresight.core.gls.normal_equations import NormalEquations
from boresight.errors import InputValueError
from orbits.limits import check_memory

__all__ = [
    "RowStructure",
    "RowColumns",
    "RowFit",
    "RowNuisances",
    "row_gls",
    "row_nuisances",
    "row_residuals",
    "row_reduced_rows",
    "row_group_grams",
    "row_sandwich_middle",
    "condition_warning",
    "CONDITION_WARN",
    "DENSE_MAX",
    "LEVERAGE_MAX",
    "row_gls_bytes",
    "CHUNK_ROWS",
    "chol_inv_2x2",
]

#: largest reduced system (D = N·na + P·nb) factorised densely (batched Cholesky); above: SuperLU.
#: DECISION: measured (one process, single-threaded BLAS, loaded 2-core machine): campaign-6pass
#: (D = 756, one run) SuperLU 13 ms, dense 20 ms; kalman20 (D = 126, 10 runs, the 94 GLS of a robust
#: fit) dense 2.7 s, SuperLU 5.6 s (runs side by side in one block-diagonal system). Dense up to 256.
DENSE_MAX = 256
#: the bound of cond(S) above which ``condition_warning`` speaks (docs/architecture.md: 1e10)
CONDITION_WARN = 1e10
#: largest reduced system whose inverse S⁻¹ (D² doubles per run) is formed for the exact leverage
LEVERAGE_MAX = 4000
#: and at most this many bytes of it over the runs (R·D²·8, twice: the inverse and its product);
#: above either, the leverage is solved for (``_leverage_by_solves``)
LEVERAGE_INVERSE_MAX_BYTES = 2.0**30
#: bounds of the band selected inverse of the leverage above ``LEVERAGE_MAX`` (``_selected_inverse``):
#: its band storage (bytes, per run) and its recursion's work (D_a·w², w the band's half-width after
#: reverse Cuthill–McKee); above either, the leverage solves with the SuperLU factor
SELECTED_INVERSE_MAX_BYTES = 2.0**28
SELECTED_INVERSE_MAX_FLOPS = 2.0e10
#: largest Ũ_ν (R × 3T × D float64) the dense kernel forms; above, ``row_gls(path="auto")`` is sparse
DENSE_U_MAX_BYTES = 2.0**27
#: entries of the right-hand sides (and of the solutions) of one batch of the leverage's solves above
#: ``LEVERAGE_MAX`` (``_leverage_by_solves``): 2²² float64, 32 MiB each
LEVERAGE_SOLVE_ELEMENTS = 2**22
#: rows whose per-row products are formed at once (bounds the working memory of large campaigns)
CHUNK_ROWS = 16384
#: values per row (and run) from which ``_add_by`` sums groups by a sparse product instead of ``reduceat``
SPARSE_SUM_WIDTH = 16

Path = Literal["auto", "dense", "sparse"]


@dataclass(frozen=True)
class RowStructure:
    """Which image and target each row belongs to, and the pass of each image.

    ``image_index`` (K,) and ``target_index`` (K,) int64 in the canonical order (sorted by image,
    then target; each pair at most once); ``pass_index`` (N,) the pass of each image, any integer
    labels; ``n_targets`` T. Derived: ``pass_of_image`` (N,) compact 0..P-1, ``row_pass`` (K,).
    """

    image_index: np.ndarray
    target_index: np.ndarray
    pass_index: np.ndarray
    n_targets: int
    pass_of_image: np.ndarray = field(init=False, repr=False)
    n_passes: int = field(init=False)
    #: (N, 2) the attitude samples each image interpolates between, or None (one sample per image)
    sample_index: np.ndarray | None = None
    #: (N, 2) their weights (the interpolation's: (1 − f, f)); with ``sample_index``
    sample_weight: np.ndarray | None = None
    #: S, the attitude samples; with ``sample_index``
    n_samples: int | None = None
    #: (S, na) or None: φ of each per-sample nuisance column between sample s − 1 and s (0 ≤ φ < 1; φ[0] = 0): the
    #: column is an AR(1) of unit variance over the samples (module docstring); None (or φ = 0): the prior E
    sample_correlation: np.ndarray | None = None

    def __post_init__(self) -> None:
        img = np.asarray(self.image_index, np.int64)
        tgt = np.asarray(self.target_index, np.int64)
        if img.ndim != 1 or img.shape != tgt.shape:
            # internal: a RowStructure is built from a validated ObservationSet (RowStructure.of) or core.line_scan's stacked rows
            raise ValueError(f"RowStructure: image_index {img.shape} and target_index {tgt.shape} must be equal 1-d arrays")
        n_img = int(np.size(self.pass_index))
        if img.size and (img.min() < 0 or img.max() >= n_img or tgt.min() < 0 or tgt.max() >= self.n_targets):
            # internal: a RowStructure is built from a validated ObservationSet (RowStructure.of) or core.line_scan's stacked rows
            raise ValueError(f"RowStructure: an index is out of range (images 0..{n_img - 1}, targets 0..{self.n_targets - 1})")
        key = img * max(self.n_targets, 1) + tgt
        bad = np.flatnonzero(np.diff(key) <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            # internal: a RowStructure is built from a validated ObservationSet (RowStructure.of) or core.line_scan's stacked rows
            raise ValueError(
                f"RowStructure: rows are not in the canonical (image, target) order or repeat a pair: row {k} is"
                f" (image {int(img[k])}, target {int(tgt[k])}) after (image {int(img[k - 1])}, target {int(tgt[k - 1])})"
            )
        object.__setattr__(self, "image_index", img)
        object.__setattr__(self, "target_index", tgt)
        _, compact = np.unique(np.asarray(self.pass_index), return_inverse=True)
        object.__setattr__(self, "pass_of_image", compact.reshape(-1).astype(np.int64))
        object.__setattr__(self, "n_passes", int(compact.max()) + 1 if compact.size else 0)
        if (
            self.sample_index is not None
            or self.sample_weight is not None
            or self.n_samples is not None
            or self.has_sample_correlation
        ):
            self._check_samples(n_img)

    def _check_samples(self, n_img: int) -> None:
        """The attitude-sample table: ``sample_index`` (N, 2) in 0..S-1, ``sample_weight`` (N, 2) finite."""
        if self.sample_index is None or self.sample_weight is None or self.n_samples is None:
            # internal: as above (ObservationSet checks its attitude-sample table first)
            raise ValueError("RowStructure: sample_index, sample_weight and n_samples go together (all three or none)")
        si = np.asarray(self.sample_index, np.int64)
        sw = np.asarray(self.sample_weight, float)
        S = int(self.n_samples)
        if si.shape != (n_img, 2) or sw.shape != (n_img, 2):
            # internal: as above (ObservationSet checks its attitude-sample table first)
            raise ValueError(
                f"RowStructure: sample_index {si.shape} and sample_weight {sw.shape} must be ({n_img}, 2): two samples per image"
            )
        if si.size and (si.min() < 0 or si.max() >= S):
            n = int(np.argmax(((si < 0) | (si >= S)).any(axis=1)))
            # internal: as above (ObservationSet checks its attitude-sample table first)
            raise ValueError(f"RowStructure: image {n}'s sample_index {si[n].tolist()} is outside the samples 0..{S - 1}")
        if not np.all(np.isfinite(sw)):
            n = int(np.argmax(~np.isfinite(sw).all(axis=1)))
            # internal: as above (ObservationSet checks its attitude-sample table first)
            raise ValueError(f"RowStructure: image {n}'s sample_weight {sw[n].tolist()} is not finite")
        object.__setattr__(self, "sample_index", si)
        object.__setattr__(self, "sample_weight", sw)
        object.__setattr__(self, "n_samples", S)
        if self.sample_correlation is not None:
            phi = np.asarray(self.sample_correlation, float)
            if phi.ndim != 2 or phi.shape[0] != S:
                raise InputValueError(
                    f"RowStructure: sample_correlation {phi.shape} must be ({S}, na): one φ per sample and column"
                )
            if not np.all((phi >= 0) & (phi < 1)) or (S and np.any(phi[0] != 0)):
                s, j = np.argwhere(~((phi >= 0) & (phi < 1)) | (np.arange(S)[:, None] == 0) & (phi != 0))[0]
                raise InputValueError(
                    f"RowStructure: sample_correlation[{s}, {j}] = {float(phi[s, j])!r}: φ must be in [0, 1), and 0 at sample 0"
                )
            object.__setattr__(self, "sample_correlation", phi)

    @property
    def has_samples(self) -> bool:
        """True when the per-image nuisances live on an attitude-sample table (a pushbroom line's two samples)."""
        return self.sample_index is not None

    @property
    def has_sample_correlation(self) -> bool:
        """True when some per-sample nuisance column has a correlated (AR(1)) prior (``sample_correlation``)."""
        return self.sample_correlation is not None

    @property
    def n_image_blocks(self) -> int:
        """The blocks of the per-image nuisance a in the reduced system: S samples, or N images."""
        return self.n_images if self.n_samples is None else int(self.n_samples)

    @classmethod
    def of(cls, obs: Any) -> "RowStructure":
        """The rows of an ``ObservationSet`` (canonical order), with its attitude-sample table when it has one."""
        si = getattr(obs, "sample_index", None)
        samples: dict[str, Any] = {}
        if si is not None:
            samples = dict(sample_index=si, sample_weight=obs.sample_weight, n_samples=int(np.shape(obs.sample_t_s)[0]))
        return cls(
            np.asarray(obs.image_index), np.asarray(obs.target_index), np.asarray(obs.pass_index), int(obs.n_targets), **samples
        )

    @property
    def n_rows(self) -> int:
        return int(self.image_index.size)

    @property
    def n_images(self) -> int:
        return int(self.pass_of_image.size)

    @property
    def row_pass(self) -> np.ndarray:
        """(K,) the compact pass of each row."""
        out: np.ndarray = self.pass_of_image[self.image_index]
        return out

    @property
    def row_start(self) -> np.ndarray:
        """(N + 1,) CSR offsets: the rows of image n are ``row_start[n]:row_start[n + 1]``."""
        out: np.ndarray = np.concatenate([[0], np.cumsum(np.bincount(self.image_index, minlength=self.n_images))])
        return out


@dataclass(frozen=True)
class RowColumns:
    """Per-row columns, whitened by each row's pixel noise (units of the pixel σ).

    ``X`` (R, K, 2, n) Jacobian of the residuals w.r.t. x; ``q`` (R, K, 2) residuals; ``A`` (R, K,
    2, na) per-image, ``B`` (R, K, 2, nb) per-pass, ``C`` (R, K, 2, 3 or 0) catalogue nuisance
    columns, each scaled by its σ (prior N(0, E)); a width 0 where the noise model has none.
    """

    X: np.ndarray
    q: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    @property
    def Y(self) -> np.ndarray:
        """(R, K, 2, n + 1) = [X | q] (a new array: use ``Y_of`` for some rows)."""
        return np.concatenate([self.X, self.q[..., None]], axis=-1)

    def Y_of(self, rows: Any) -> np.ndarray:
        """[X | q] of the rows ``rows`` (a slice or an index array), (R, k, 2, n + 1)."""
        return np.concatenate([self.X[:, rows], self.q[:, rows, :, None]], axis=-1)


@dataclass
class RowFit:
    """The reduced normal equations of x and the factors for back-substitution.

    ``normal_equations`` is a ``NormalEquations`` over x (data part; dof = residual components −
    unknowns). ``image_gram`` (R, n+1, n+1): the Gram of [X | q] with only the pixel noise and the
    per-image errors eliminated. ``path``: ``"dense"`` or ``"sparse"`` (see the module docstring).
    """

    normal_equations: NormalEquations
    structure: RowStructure
    columns: RowColumns
    weights: np.ndarray | None
    path: str
    _f: dict[str, Any]

    @property
    def condition_bound(self) -> np.ndarray:
        """(R,) an upper bound of cond(S), the reduced image/pass system: S⁻¹ is a principal block of
        H_νν⁻¹ ≤ E (every nuisance carries the prior E), so λ_min(S) ≥ 1 (≥ (1 − φ_max)/(1 + φ_max) with a
        correlated sample prior, ``RowStructure.sample_correlation``: the bound is divided by it), and λ_max(S) ≤ λ_max
        of the image/pass block of H_νν ≤ its largest absolute row sum (Gershgorin). Above ~1e10 the MAP
        nuisances lose digits (the x-block only to second order: module docstring)."""
        out: np.ndarray = self._f["condition_bound"]
        return out

    @property
    def image_gram(self) -> np.ndarray:
        """(R, n+1, n+1), computed on first use (only ``diagnose`` reads it)."""
        if "image_gram" not in self._f:
            self._f["image_gram"] = _image_gram(self.structure, self.columns, self.weights)
        out: np.ndarray = self._f["image_gram"]
        return out


@dataclass(frozen=True)
class RowNuisances:
    """MAP nuisances at a correction of x: ``a`` (R, N, na), ``b`` (R, P, nb), ``c`` (R, T, 3 or 0); with
    attitude samples ``a`` is each image's interpolation of ``a_samples`` (R, S, na), else None."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    a_samples: np.ndarray | None = None


# ---------------------------------------------------------------------------------- sums over rows
def _add_by(out: np.ndarray, index: np.ndarray, values: np.ndarray) -> None:
    """out[:, g] += Σ_{k: index[k] = g} values[:, k] in place; values (R, k, ...), out (R, groups, ...).

    Sorted segments summed by ``np.add.reduceat`` (rows in canonical order are already sorted by
    image; other groupings are gathered into order first), added at the groups present only: a chunk of
    rows costs O(its rows), not O(groups) (a zero array of every group per chunk made the chunked sums
    quadratic in the campaign's size)."""
    R, k = values.shape[:2]
    if not k:
        return
    if np.all(index[1:] >= index[:-1]):
        srt, v = index, values
    else:
        order = np.argsort(index, kind="stable")
        srt, v = index[order], values[:, order]
    starts = np.flatnonzero(np.r_[True, srt[1:] != srt[:-1]])
    width = int(np.prod(values.shape[2:], dtype=np.int64))
    if width < SPARSE_SUM_WIDTH:
        out[:, srt[starts]] += np.add.reduceat(v, starts, axis=1)
        return
    # DECISION: wide rows (a row's p × q products) summed by a sparse indicator product (scipy's CSR
    # matvecs: each group's rows added in order, as reduceat does), not ``reduceat``, whose loop over
    # the inner axes is ~10× slower there: 13.8 against 1.5 ms for 16 384 rows of 6 × 16 in ~1 500
    # groups, and the largest term of an estimate of 131 000 single-use rows (/tmp timing script).
    ind = sp.csr_matrix((np.ones(k), np.arange(k), np.r_[starts, k]), shape=(starts.size, k))
    sums = ind @ np.moveaxis(v, 0, 1).reshape(k, R * width)  # (groups, R·width)
    out[:, srt[starts]] += np.moveaxis(sums.reshape((starts.size, R) + values.shape[2:]), 0, 1)


def _sum_by(index: np.ndarray, size: int, values: np.ndarray) -> np.ndarray:
    """out[:, g] = Σ_{k: index[k] = g} values[:, k]; values (R, K, ...) → (R, size, ...) (``_add_by``)."""
    out = np.zeros((values.shape[0], size) + values.shape[2:])
    _add_by(out, index, values)
    return out


def _row_gram(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(R, k, p, q): P_kᵀ Q_k for every row, P (R, k, 2, p), Q (R, k, 2, q).

    DECISION: ``matmul`` on the stacked 2-row blocks, not ``einsum("rkip,rkiq->rkpq")``: numpy runs that
    einsum as a generic sum-of-products loop, 8-10× slower (measured 400 against 40-60 ns a row at
    p = 6, q = 16, chunks of 2 048-16 384 rows; equal to round-off)."""
    out: np.ndarray = np.swapaxes(P, -1, -2) @ Q
    return out


def _gram_by(index: np.ndarray, size: int, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(R, size, p, q): Σ over the rows of each group of P_kᵀ Q_k, P (R, K, 2, p), Q (R, K, 2, q); chunked."""
    R, K = P.shape[:2]
    out = np.zeros((R, size, P.shape[-1], Q.shape[-1]))
    if not (P.shape[-1] and Q.shape[-1]):
        return out
    for i in range(0, K, CHUNK_ROWS):
        s = slice(i, i + CHUNK_ROWS)
        _add_by(out, index[s], _row_gram(P[:, s], Q[:, s]))
    return out


def _gram(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(R, p, q): Σ_k P_kᵀ Q_k over every row (one BLAS product per run: the rows' components stacked)."""
    R, p, q = P.shape[0], P.shape[-1], Q.shape[-1]
    if not (p and q):
        return np.zeros((R, p, q))
    out: np.ndarray = np.swapaxes(P.reshape(R, -1, p), -1, -2) @ Q.reshape(R, -1, q)
    return out


def _quadratic_rows(Z: np.ndarray, M: np.ndarray) -> np.ndarray:
    """(R, k, 2): z_iᵀ M z_i for every row component, Z (R, k, 2, n), M (R, n, n) (one BLAS product per run)."""
    R, n = Z.shape[0], Z.shape[-1]
    out: np.ndarray = np.sum((Z.reshape(R, -1, n) @ M).reshape(Z.shape) * Z, axis=-1)
    return out


def _wgram(w: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """(R, n, n): Σ_k w_k Y_kᵀ Y_k for row weights w (R, k) and rows Y (R, k, 2, n).

    DECISION: one BLAS product per run on the weighted rows, not ``einsum("rk,rkij,rkil->rjl")``, which
    numpy runs as a plain loop: 10× faster at n = 300 columns (diagnose's probes on a 60-pass campaign),
    equal to 1e-14 relative."""
    return _gram(Y * w[..., None, None], Y)


def _chunks(K: int) -> list[slice]:
    """The rows 0 … K − 1 in slices of ``CHUNK_ROWS``: the unit of every per-row product (working memory
    bounded, and the same cache-sized pieces whatever the campaign's size: its cost linear in rows)."""
    return [slice(i, min(i + CHUNK_ROWS, K)) for i in range(0, K, CHUNK_ROWS)]


def _to_samples(st: RowStructure, v: np.ndarray) -> np.ndarray:
    """Per-image values (R, N, ...) → per-sample sums (R, S, ...): out_s = Σ_{n, i: s_i(n) = s} w_i(n) v_n (Wᵀ v)."""
    si, sw = st.sample_index, st.sample_weight
    assert si is not None and sw is not None  # callers check has_samples
    wv = np.concatenate(
        [v * sw[:, 0].reshape((1, -1) + (1,) * (v.ndim - 2)), v * sw[:, 1].reshape((1, -1) + (1,) * (v.ndim - 2))], 1
    )
    return _sum_by(np.concatenate([si[:, 0], si[:, 1]]), st.n_image_blocks, wv)


def _to_images(st: RowStructure, a: np.ndarray) -> np.ndarray:
    """Per-sample values (R, S, ...) → per-image interpolations (R, N, ...): w_0(n) a_{s_0(n)} + w_1(n) a_{s_1(n)} (W a)."""
    si, sw = st.sample_index, st.sample_weight
    assert si is not None and sw is not None  # callers check has_samples
    shape = (1, -1) + (1,) * (a.ndim - 2)
    out: np.ndarray = a[:, si[:, 0]] * sw[:, 0].reshape(shape) + a[:, si[:, 1]] * sw[:, 1].reshape(shape)
    return out


def _image_sample_scale(st: RowStructure, na: int) -> np.ndarray:
    """(N, na) the standard deviation of each image's interpolated a_n = Σ_i w_i a_{s_i} in units of one sample's, per
    column: √(w_0² + w_1² + 2 w_0 w_1 ρ), ρ the prior correlation of its two samples (1 when they are one; 0 white;
    the product of the φ between them on a correlated column)."""
    si, sw = st.sample_index, st.sample_weight
    assert si is not None and sw is not None
    same = si[:, 0] == si[:, 1]
    if st.sample_correlation is None:
        white: np.ndarray = np.where(same, np.abs(sw.sum(axis=1)), np.sqrt(np.sum(sw**2, axis=1)))
        return np.repeat(white[:, None], na, axis=1)
    # Π_{s0 < s ≤ s1} φ_s by cumulative logs (φ = 0 counts as e^-690: nil)
    logs = np.cumsum(np.log(np.maximum(st.sample_correlation, 1e-300)), axis=0)
    rho = np.exp(logs[np.maximum(si[:, 0], si[:, 1])] - logs[np.minimum(si[:, 0], si[:, 1])])
    rho[same] = 1.0
    out: np.ndarray = np.sqrt(np.maximum(sw[:, :1] ** 2 + sw[:, 1:] ** 2 + 2.0 * sw[:, :1] * sw[:, 1:] * rho, 0.0))
    return out


def _ar1_coefficients(st: RowStructure) -> tuple[np.ndarray, np.ndarray] | None:
    """(c, d) (S, na) of the correlated samples' innovations e_s = c_s a_s − d_s a_{s−1} (c = 1/√(1 − φ²), d = φ c:
    module docstring), or None (the prior E)."""
    phi = st.sample_correlation
    if phi is None:
        return None
    c = 1.0 / np.sqrt(1.0 - phi**2)
    return c, phi * c


def _sample_innovations(st: RowStructure, a: np.ndarray) -> np.ndarray:
    """M a (R, S, na, ...) for per-sample values a: the innovations whose |·|² is the prior's aᵀ MᵀM a (a itself, E)."""
    cd = _ar1_coefficients(st)
    if cd is None:
        return a
    c, d = (v.reshape((1,) + v.shape + (1,) * (a.ndim - 3)) for v in cd)
    e: np.ndarray = a * c
    e[:, 1:] -= a[:, :-1] * d[:, 1:]
    return e


def _sample_prior(st: RowStructure, na: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, columns, values) of the per-sample nuisances' prior information on the S·na unknowns (sample s, column j
    at s·na + j): E, or with ``sample_correlation`` MᵀM (c_s² + d_{s+1}² on the diagonal, −c_s d_s at (s, s − 1) and
    (s − 1, s))."""
    S = st.n_image_blocks
    diag = np.arange(S * na)
    cd = _ar1_coefficients(st)
    if cd is None:
        return diag, diag, np.ones(S * na)
    c, d = cd
    d_next = np.concatenate([d[1:], np.zeros((1, na))])
    low = np.arange(na, S * na)  # (s, j) for s ≥ 1, beside (s − 1, j)
    off = (-c[1:] * d[1:]).ravel()
    return (
        np.concatenate([diag, low, low - na]),
        np.concatenate([diag, low - na, low]),
        np.concatenate([(c**2 + d_next**2).ravel(), off, off]),
    )


def _sample_prior_bound(st: RowStructure) -> float:
    """1 / (a lower bound of λ_min of the samples' prior information): (1 + φ_max)/(1 − φ_max), 1 for E."""
    phi = st.sample_correlation
    if phi is None or not phi.size:
        return 1.0
    m = float(phi.max())
    return (1.0 + m) / (1.0 - m)


def _chol_inv(H: np.ndarray) -> np.ndarray:
    """L⁻¹ for L Lᵀ = H (batched, small blocks)."""
    out: np.ndarray = np.linalg.inv(np.linalg.cholesky(H))
    return out


def chol_inv_2x2(H: np.ndarray) -> np.ndarray:
    """L⁻¹ for L Lᵀ = H, H (..., 2, 2) symmetric positive definite: the Cholesky recurrence (LAPACK's
    ``potrf``: l₀₀ = √h₀₀, l₁₀ = h₁₀ / l₀₀, l₁₁ = √(h₁₁ − l₁₀²)) and its triangular inverse in closed form.

    DECISION: closed form for the 2 × 2 blocks of every row (the pixel whitening of ``gls.campaign``, the
    single-use fold), not ``np.linalg`` (a LAPACK call per block: cholesky and inv were 0.16 s of a 2 s fit
    of 131 000 single-use rows); equal to round-off."""
    l00 = np.sqrt(H[..., 0, 0])
    l10 = H[..., 1, 0] / l00
    l11 = np.sqrt(H[..., 1, 1] - l10 * l10)
    if not np.all(l11 > 0):  # also NaN: not positive definite (np.linalg.cholesky's error)
        raise np.linalg.LinAlgError("chol_inv_2x2: a 2 × 2 block is not positive definite")
    out = np.zeros(H.shape)
    out[..., 0, 0] = 1.0 / l00
    out[..., 1, 1] = 1.0 / l11
    out[..., 1, 0] = -l10 / (l00 * l11)
    return out


# ---------------------------------------------------------------------------------- the fit
def _nu_index(st: RowStructure, na: int, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """Columns of ν = [a_0 … a_{N-1}, b_0 … b_{P-1}] of each row's image (K, na) and pass (K, nb)."""
    ia = st.image_index[:, None] * na + np.arange(na)
    ib = st.n_images * na + st.row_pass[:, None] * nb + np.arange(nb)
    return ia, ib


def _blocks_and_targets(
    st: RowStructure, cols: RowColumns, weights: np.ndarray | None
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Steps 1 and 2's per-row work, in one pass over chunks of rows (``_chunks``): each chunk's columns
    [A | B | Y] weighted by √w and its single-use rows folded (whitened by (E₂ + w C Cᵀ)^(-1/2)), then

    * the image and pass blocks ``blk``: H_aa (R, N, na, na), H_ab (R, N, na, nb), H_ay (R, N, na, ny),
      H_bb (R, P, nb, nb), H_by (R, P, nb, ny), H_yy (R, ny, ny), each nuisance block with its prior E
      (with attitude samples H_aa is each image's data part: the prior E is on the samples);
    * the shared targets' factors ``tf``: L_t⁻¹ (R, T, 3, 3) (from H_tt = E₃ + Σ_{k∈t} w C_kᵀ C_k, one
      earlier pass over the shared rows' C), Ũ_y = L_t⁻¹ H_ty (R, T, 3, ny), and the blocks of Ũ_ν: per
      shared row k, V_k A'_k (R, Ks, 3, na) with V_k = L_t⁻¹ C'_kᵀ, and per (target, pass) pair Σ V_k B'_k
      over the pair's rows (R, Ub, 3, nb).

    No weighted copy of the whole columns is formed; the per-row products are ``matmul``s of the chunk."""
    R, K = cols.q.shape[:2]
    N, P, T = st.n_images, st.n_passes, st.n_targets
    na, nb, nc, ny = cols.A.shape[-1], cols.B.shape[-1], cols.C.shape[-1], cols.X.shape[-1] + 1
    img, rp = st.image_index, st.row_pass
    sw = None if weights is None else np.sqrt(np.maximum(np.asarray(weights, float), 0.0))
    m = na + nb + ny
    Ha = np.zeros((R, N, na, m))  # [H_aa | H_ab | H_ay] per image
    Hb = np.zeros((R, P, nb, nb + ny))  # [H_bb | H_by] per pass
    yy = np.zeros((R, ny, ny))
    single = _single_rows(st, cols)
    ks = np.flatnonzero(~single) if nc else np.zeros(0, np.int64)
    tf: dict[str, Any] = dict(ks=ks)
    if ks.size:
        t = st.target_index[ks]
        Htt = np.zeros((R, T, 3, 3))
        for s in _chunks(ks.size):
            Cs = cols.C[:, ks[s]] if sw is None else cols.C[:, ks[s]] * sw[:, ks[s], None, None]
            _add_by(Htt, t[s], _row_gram(Cs, Cs))
        Linv = _chol_inv(Htt + np.eye(3))  # unshared targets: E₃, unused
        Pm = max(P, 1)
        pair, pair_of_row = np.unique(t * Pm + rp[ks], return_inverse=True)
        tf.update(
            t=t,
            Linv=Linv,
            Uy=np.zeros((R, T, 3, ny)),
            VA=np.empty((R, ks.size, 3, na)),
            VB=np.zeros((R, pair.size, 3, nb)),
            tb=pair // Pm,
            pb=pair % Pm,
        )
    for s in _chunks(K):
        Z = np.concatenate([cols.A[:, s], cols.B[:, s], cols.X[:, s], cols.q[:, s, :, None]], axis=-1)  # (R, k, 2, m)
        if sw is not None:
            Z *= sw[:, s, None, None]
        sg = single[s]
        if sg.all():
            Cw = cols.C[:, s] if sw is None else cols.C[:, s] * sw[:, s, None, None]
            Z = chol_inv_2x2(np.eye(2) + Cw @ np.swapaxes(Cw, -1, -2)) @ Z
        elif sg.any():
            j = np.flatnonzero(sg) + s.start
            Cw = cols.C[:, j] if sw is None else cols.C[:, j] * sw[:, j, None, None]
            Z[:, j - s.start] = chol_inv_2x2(np.eye(2) + Cw @ np.swapaxes(Cw, -1, -2)) @ Z[:, j - s.start]
        A, B, Y = Z[..., :na], Z[..., na : na + nb], Z[..., na + nb :]
        if na:
            _add_by(Ha, img[s], _row_gram(A, Z))
        if nb:
            _add_by(Hb, rp[s], _row_gram(B, Z[..., na:]))
        yy += _gram(Y, Y)
        if ks.size:
            lo, hi = np.searchsorted(ks, [s.start, s.stop])
            if hi > lo:
                loc = ks[lo:hi] - s.start
                Cw = cols.C[:, ks[lo:hi]] if sw is None else cols.C[:, ks[lo:hi]] * sw[:, ks[lo:hi], None, None]
                V = tf["Linv"][:, t[lo:hi]] @ np.swapaxes(Cw, -1, -2)  # (R, k, 3, 2)
                _add_by(tf["Uy"], t[lo:hi], V @ Y[:, loc])
                tf["VA"][:, lo:hi] = V @ A[:, loc]
                if nb:
                    _add_by(tf["VB"], pair_of_row[lo:hi], V @ B[:, loc])
    blk = dict(
        aa=Ha[..., :na] + (0.0 if st.has_samples else np.eye(na)),
        ab=np.ascontiguousarray(Ha[..., na : na + nb]),
        ay=np.ascontiguousarray(Ha[..., na + nb :]),
        bb=Hb[..., :nb] + np.eye(nb),
        by=np.ascontiguousarray(Hb[..., nb:]),
        yy=yy,
    )
    return blk, tf


def _U_nu(
    st: RowStructure, tf: dict[str, Any], r: int | None, na: int, nb: int, D: int, chunk: np.ndarray | None = None
) -> sp.csr_matrix:
    """Ũ_ν of run r: (3T, D) sparse, 3 rows per target, non-zero on its rows' images and passes;
    r None: every run, block-diagonally ((R·3T, R·D), run r's block at offsets r·3T, r·D). With
    ``chunk`` (targets) only their rows, numbered 0 … 3·chunk.size − 1."""
    t, img, tb, pb = tf["t"], st.image_index[tf["ks"]], tf["tb"], tf["pb"]
    VA, VB = tf["VA"], tf["VB"]  # (R, Ks, 3, na), (R, Ub, 3, nb)
    T = st.n_targets
    if chunk is not None:
        loc = np.full(st.n_targets, -1)
        loc[chunk] = np.arange(chunk.size)
        ka, kb = np.flatnonzero(loc[t] >= 0), np.flatnonzero(loc[tb] >= 0)
        t, img, VA, tb, pb, VB = loc[t[ka]], img[ka], VA[:, ka], loc[tb[kb]], pb[kb], VB[:, kb]
        T = chunk.size
    runs = np.arange(VA.shape[0]) if r is None else np.array([r])
    VA, VB = VA[runs], VB[runs]
    if st.has_samples:
        # a row's a-columns at its image's two samples, weighted: Ũ_ν(samples) = Ũ_ν(images) W (duplicates summed)
        si, sw = st.sample_index[img], st.sample_weight[img]  # type: ignore[index]
        VA = np.concatenate([VA * sw[None, :, 0, None, None], VA * sw[None, :, 1, None, None]], axis=1)
        t, img = np.concatenate([t, t]), np.concatenate([si[:, 0], si[:, 1]])
    shape = (runs.size * 3 * T, runs.size * D)
    idx = np.int32 if max(shape) < 2**31 else np.int64
    # COO triplets written in place, indices in 32 bits (no images × entries temporaries of 64-bit
    # broadcasts: at 10⁶ rows they were ~0.6 GB)
    nA, nB = VA.size, VB.size if nb else 0
    ri, ci, data = np.empty(nA + nB, idx), np.empty(nA + nB, idx), np.empty(nA + nB)
    off_r = (np.arange(runs.size, dtype=idx) * (3 * T))[:, None, None, None]
    off_c = (np.arange(runs.size, dtype=idx) * D)[:, None, None, None]
    three = np.arange(3, dtype=idx)
    ri[:nA].reshape(VA.shape)[...] = off_r + ((3 * t.astype(idx))[:, None] + three)[:, :, None]
    ci[:nA].reshape(VA.shape)[...] = off_c + (img.astype(idx)[:, None] * na + np.arange(na, dtype=idx))[:, None, :]
    data[:nA] = VA.ravel()
    if nB:
        ri[nA:].reshape(VB.shape)[...] = off_r + ((3 * tb.astype(idx))[:, None] + three)[:, :, None]
        ci[nA:].reshape(VB.shape)[...] = (
            off_c + (st.n_image_blocks * na + pb.astype(idx)[:, None] * nb + np.arange(nb, dtype=idx))[:, None, :]
        )
        data[nA:] = VB.ravel()
    return sp.coo_matrix((data, (ri, ci)), shape=shape).tocsr()


def _H_nu(st: RowStructure, blk: dict[str, np.ndarray], na: int, nb: int, D: int) -> sp.csr_matrix:
    """H_νν of every run, block-diagonally over runs ((R·D)², run r at offset r·D): image blocks,
    pass blocks and their coupling."""
    N, P = st.n_images, st.n_passes
    R = blk["aa"].shape[0]
    off = (np.arange(R) * D)[:, None]
    a0 = np.arange(N)[:, None] * na + np.arange(na)  # (N, na)
    b0 = N * na + st.pass_of_image[:, None] * nb + np.arange(nb)  # (N, nb)
    bp = N * na + np.arange(P)[:, None] * nb + np.arange(nb)  # (P, nb)
    ri = [np.repeat(a0, na, axis=1).ravel(), np.repeat(bp, nb, axis=1).ravel()]
    ci = [np.tile(a0, na).ravel(), np.tile(bp, nb).ravel()]
    data = [blk["aa"].reshape(R, -1), blk["bb"].reshape(R, -1)]
    if na and nb:
        ri += [np.repeat(a0, nb, axis=1).ravel(), np.repeat(b0, na, axis=1).ravel()]
        ci += [np.tile(b0, na).ravel(), np.tile(a0, nb).ravel()]
        data += [blk["ab"].reshape(R, -1), np.swapaxes(blk["ab"], -1, -2).reshape(R, -1)]
    rows = (off + np.concatenate(ri)[None]).ravel()
    cols = (off + np.concatenate(ci)[None]).ravel()
    return sp.csr_matrix((np.concatenate(data, axis=1).ravel(), (rows, cols)), shape=(R * D, R * D))


def _H_nu_samples(st: RowStructure, blk: dict[str, np.ndarray], na: int, nb: int, D: int) -> sp.csr_matrix:
    """H_νν on the attitude samples, every run block-diagonally ((R·D)², run r at offset r·D): with a_n = Σ_i w_i a_{s_i}
    for image n, the image blocks (data part) become Σ_n Σ_ij w_i w_j H_aa,n at (s_i, s_j), the couplings Σ_n w_i H_ab,n
    at (s_i, p(n)), plus the prior E on every sample (Wᵀ H_aa W + E; duplicates summed)."""
    S, P = st.n_image_blocks, st.n_passes
    R = blk["aa"].shape[0]
    si, sw = st.sample_index, st.sample_weight
    assert si is not None and sw is not None
    off = (np.arange(R) * D)[:, None]
    ja, jb = np.arange(na), np.arange(nb)
    ri, ci, data = [], [], []
    for i in range(2):
        for j in range(2):
            ww = sw[:, i] * sw[:, j]
            ri.append(np.broadcast_to((si[:, i, None] * na + ja)[:, :, None], (st.n_images, na, na)).ravel())
            ci.append(np.broadcast_to((si[:, j, None] * na + ja)[:, None, :], (st.n_images, na, na)).ravel())
            data.append((blk["aa"] * ww[None, :, None, None]).reshape(R, -1))
        if na and nb:
            b0 = S * na + st.pass_of_image[:, None] * nb + jb  # (N, nb)
            rr = np.broadcast_to((si[:, i, None] * na + ja)[:, :, None], (st.n_images, na, nb)).ravel()
            cc = np.broadcast_to(b0[:, None, :], (st.n_images, na, nb)).ravel()
            v = (blk["ab"] * sw[None, :, i, None, None]).reshape(R, -1)
            ri += [rr, cc]
            ci += [cc, rr]
            data += [v, v]
    pr, pc, pv = _sample_prior(st, na)  # E, or a correlated column's tridiagonal MᵀM
    bp = S * na + np.arange(P)[:, None] * nb + jb  # (P, nb)
    ri += [pr, np.repeat(bp, nb, axis=1).ravel()]
    ci += [pc, np.tile(bp, nb).ravel()]
    data += [np.broadcast_to(pv, (R, pv.size)), blk["bb"].reshape(R, -1)]
    rows = (off + np.concatenate(ri)[None]).ravel()
    cols = (off + np.concatenate(ci)[None]).ravel()
    return sp.coo_matrix((np.concatenate(data, axis=1).ravel(), (rows, cols)), shape=(R * D, R * D)).tocsr()


def _gershgorin(st: RowStructure, blk: dict[str, np.ndarray]) -> np.ndarray:
    """(R,) the largest absolute row sum of H_νν's image/pass block (≥ 1: the prior)."""
    R = blk["yy"].shape[0]
    bound = np.ones(R)
    ab = np.abs(blk["ab"])
    if blk["aa"].shape[-1]:
        bound = np.maximum(bound, (np.abs(blk["aa"]).sum(-1) + ab.sum(-1)).max(axis=(1, 2)))
    if blk["bb"].shape[-1]:
        coupling = _sum_by(st.pass_of_image, st.n_passes, ab.sum(-2))  # (R, P, nb)
        bound = np.maximum(bound, (np.abs(blk["bb"]).sum(-1) + coupling).max(axis=(1, 2)))
    return bound


def _tri_solve(L: np.ndarray, b: np.ndarray, transpose: bool = False) -> np.ndarray:
    """L⁻¹ b (or L⁻ᵀ b) for lower-triangular L (R, D, D), b (R, D, k): LAPACK's trsm run by run
    (numpy has no batched triangular solve; its general solve costs an LU per call)."""
    out = np.empty(np.broadcast_shapes(b.shape, L.shape[:1] + b.shape[1:]))
    for r in range(L.shape[0]):
        out[r] = solve_triangular(
            L[r], b[r] if b.shape[0] > 1 else b[0], lower=True, trans=1 if transpose else 0, check_finite=False
        )
    return out


def _U_nu_dense(st: RowStructure, tf: dict[str, Any], na: int, nb: int, D: int) -> np.ndarray:
    """Ũ_ν of every run as a dense (R, 3T, D) array (the dense kernel: D ≤ ``DENSE_MAX``)."""
    t, img, tb, pb = tf["t"], st.image_index[tf["ks"]], tf["tb"], tf["pb"]
    R = tf["VA"].shape[0]
    Ud = np.zeros((R, st.n_targets, 3, D))
    # each (target, image) pair and each (target, pass) pair occurs once: plain assignment
    # (advanced indices apart: their (pairs, columns) axes come first, then runs and the 3 rows)
    Ud[:, t[:, None], :, img[:, None] * na + np.arange(na)] = np.transpose(tf["VA"], (1, 3, 0, 2))
    if nb:
        Ud[:, tb[:, None], :, st.n_images * na + pb[:, None] * nb + np.arange(nb)] = np.transpose(tf["VB"], (1, 3, 0, 2))
    return Ud.reshape(R, 3 * st.n_targets, D)


def _H_nu_dense(st: RowStructure, blk: dict[str, np.ndarray], na: int, nb: int, D: int) -> np.ndarray:
    """H_νν of every run as a dense (R, D, D) array."""
    N, P = st.n_images, st.n_passes
    R = blk["aa"].shape[0]
    H = np.zeros((R, D, D))
    a0 = np.arange(N)[:, None] * na + np.arange(na)
    bp = N * na + np.arange(P)[:, None] * nb + np.arange(nb)
    H[:, a0[:, :, None], a0[:, None, :]] = blk["aa"]
    H[:, bp[:, :, None], bp[:, None, :]] = blk["bb"]
    if na and nb:
        b0 = N * na + st.pass_of_image[:, None] * nb + np.arange(nb)
        H[:, a0[:, :, None], b0[:, None, :]] = blk["ab"]
        H[:, b0[:, :, None], a0[:, None, :]] = np.swapaxes(blk["ab"], -1, -2)
    return H


def _image_gram(st: RowStructure, cols: RowColumns, weights: np.ndarray | None) -> np.ndarray:
    """min over the per-image errors only of Σ w |Y e − A a|² + |a|², as the sum of squares of the
    reduced rows Ỹ = Y − A α_n plus α_nᵀ α_n, α_n = (A_nᵀ W A_n + E)⁻¹ A_nᵀ W Y_n (the catalogue not
    eliminated; the same second-order-accurate form as ``row_gls``'s x-block)."""
    w = np.ones(cols.q.shape[:2]) if weights is None else np.maximum(np.asarray(weights, float), 0.0)
    sw = np.sqrt(w)[..., None, None]
    A, Y = cols.A, cols.Y
    if not A.shape[-1]:
        return _gram(Y * sw, Y * sw)
    if st.has_samples:
        return _sample_gram(st, cols, w)
    alpha = _image_alpha(st, A * sw, Y * sw)
    gram = _gram(alpha, alpha)
    for i in range(0, st.n_rows, CHUNK_ROWS):
        s = slice(i, i + CHUNK_ROWS)
        Yt = Y[:, s] - A[:, s] @ alpha[:, st.image_index[s]]
        gram += _wgram(w[:, s], Yt)
    return gram


def _image_alpha(st: RowStructure, A: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """α_n = (A_nᵀ A_n + E)⁻¹ A_nᵀ Y_n (R, N, na, ny) for the weighted rows A, Y: the per-image errors' MAP values."""
    out: np.ndarray = np.linalg.solve(
        _gram_by(st.image_index, st.n_images, A, A) + np.eye(A.shape[-1]), _gram_by(st.image_index, st.n_images, A, Y)
    )
    return out


def row_group_grams(fit: RowFit, image_group: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """The fit's reduced [Y]-block and its ``image_gram``, each summed over one group of images at a time:
    (R, G, ny, ny) twice, ``image_group`` (N,) the group of each image in 0..G-1.

    When no nuisance spans two groups — every pass and every target in one group (a campaign's passes
    grouped by the targets they share; no attitude-sample table) — the joint information is
    block-diagonal over the groups, each group's nuisances are eliminated by its own rows alone, and the
    group's sum Σ_{k∈g} w_k Ỹ_kᵀ Ỹ_k + Σ_{ν∈g} ν_Yᵀ ν_Y (module docstring, step 4) is the reduced block of
    the GLS of that group's rows: exact, however the columns of Y differ between the groups. So a column
    non-zero on one group's rows only costs one column of Y, shared by every group (``diagnose``'s
    per-pass probes: ``boresight.studies.discrepancy.campaign``). The groups' sum is the fit's own block
    (``normal_equations``) and ``image_gram``. Raises ValueError when a pass or a target spans two groups."""
    st, cols, f = fit.structure, fit.columns, fit._f
    g_img = np.asarray(image_group, np.int64)
    if g_img.shape != (st.n_images,) or (g_img.size and (g_img.min() < 0 or g_img.max() >= n_groups)):
        # internal: row_group_grams is called by studies.discrepancy.campaign alone, with groups from its own _pass_groups
        raise ValueError(f"row_group_grams: image_group must be ({st.n_images},) in 0..{n_groups - 1}")
    if st.has_samples:
        # internal: row_group_grams is called by studies.discrepancy.campaign alone, with groups from its own _pass_groups
        raise ValueError("row_group_grams: an attitude-sample table couples images; no grouping")
    g_row = g_img[st.image_index]
    g_pass = np.full(st.n_passes, -1)
    g_pass[st.pass_of_image] = g_img
    g_tgt = np.full(st.n_targets, -1)
    g_tgt[st.target_index] = g_row
    if np.any(g_pass[st.pass_of_image] != g_img) or (cols.C.shape[-1] and np.any(g_tgt[st.target_index] != g_row)):
        # internal: row_group_grams is called by studies.discrepancy.campaign alone, with groups from its own _pass_groups
        raise ValueError("row_group_grams: a pass or a target spans two groups of images")
    R, ny = cols.q.shape[0], cols.X.shape[-1] + 1
    w = np.ones(cols.q.shape[:2]) if fit.weights is None else np.maximum(np.asarray(fit.weights, float), 0.0)
    a, b, c = f["nuY"]
    na = cols.A.shape[-1]
    alpha = _image_alpha(st, cols.A * np.sqrt(w)[..., None, None], cols.Y * np.sqrt(w)[..., None, None]) if na else None
    reduced, image = np.zeros((R, n_groups, ny, ny)), np.zeros((R, n_groups, ny, ny))

    def members(g_of: np.ndarray) -> list[Any]:
        """The members of each group, in order: a slice where they are contiguous (rows in canonical order
        usually are, a pass's images together), else an index array."""
        order = np.argsort(g_of, kind="stable")
        bounds = np.searchsorted(g_of[order], np.arange(n_groups + 1))
        ident = np.array_equal(order, np.arange(order.size))
        return [slice(bounds[g], bounds[g + 1]) if ident else order[bounds[g] : bounds[g + 1]] for g in range(n_groups)]

    rows_of, imgs_of, passes_of = members(g_row), members(g_img), members(g_pass)
    tgts = np.flatnonzero(g_tgt >= 0)  # the targets with rows (a target without one has c = 0)
    tgt_of = [tgts[m] for m in members(g_tgt[tgts])]
    for g in range(n_groups):
        rows_, imgs, passes, tg = rows_of[g], imgs_of[g], passes_of[g], tgt_of[g]
        wg = w[:, rows_]
        reduced[:, g] = _wgram(wg, _reduced_Y(st, cols, f["nuY"], rows_)) + _gram(a[:, imgs], a[:, imgs])
        reduced[:, g] += _gram(b[:, passes], b[:, passes]) + _gram(c[:, tg], c[:, tg])
        if alpha is None:
            image[:, g] = _wgram(wg, cols.Y_of(rows_))
        else:
            Yt = cols.Y_of(rows_) - cols.A[:, rows_] @ alpha[:, st.image_index[rows_]]
            image[:, g] = _wgram(wg, Yt) + _gram(alpha[:, imgs], alpha[:, imgs])
    return 0.5 * (reduced + np.swapaxes(reduced, -1, -2)), image


def _sample_gram(st: RowStructure, cols: RowColumns, w: np.ndarray) -> np.ndarray:
    """``_image_gram`` with the per-image errors on attitude samples: α_s = (Wᵀ H_aa W + E)⁻¹ Wᵀ H_ay (a sparse
    banded system per run), each image's α_n its interpolation, Σ w Ỹᵀ Ỹ + α_sᵀ α_s."""
    sw = np.sqrt(w)[..., None, None]
    A, Y = cols.A * sw, cols.Y * sw
    R, na = A.shape[0], A.shape[-1]
    NA = st.n_image_blocks
    blk = dict(aa=_gram_by(st.image_index, st.n_images, A, A), ab=np.zeros((R, st.n_images, na, 0)), bb=np.zeros((R, 0, 0, 0)))
    D = NA * na
    H = _H_nu_samples(st, blk, na, 0, D)
    rhs = _to_samples(st, _gram_by(st.image_index, st.n_images, A, Y)).reshape(R * D, -1)
    lu = splu(H.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    alpha_s = lu.solve(rhs).reshape(R, NA, na, -1)
    alpha = _to_images(st, alpha_s)
    e_s = _sample_innovations(st, alpha_s)
    gram = _gram(e_s, e_s)
    for i in range(0, st.n_rows, CHUNK_ROWS):
        s = slice(i, i + CHUNK_ROWS)
        Yt = cols.Y[:, s] - cols.A[:, s] @ alpha[:, st.image_index[s]]
        gram += _wgram(w[:, s], Yt)
    return gram


def row_gls_bytes(st: RowStructure, R: int, n: int, na: int, nb: int, C_width: int = 3, path: str = "sparse") -> float:
    """Estimated working set (bytes) of ``row_gls`` on ``st`` with R runs and widths n, na, nb: the
    weighted row columns and [X | q] (R × K × 2 × (na + nb + 3 + n + 1), twice), the shared targets'
    factors (VA: 3 × na per shared row; L⁻¹, Ũ_y: per target), the MAP nuisances of the right-hand
    columns, and the reduced system — dense: three D × D per run and Ũ_ν (3T × D); sparse: its
    non-zeros (an na × na block per pair of images that share a target — counted exactly, by the
    sparse product of the image × target incidence —, the image/pass couplings and the pass
    blocks; at most D²), three times (S, its CSC copy and SuperLU's factor, taken as large as S).
    float64 values, 32-bit indices; generous by design (``orbits.limits``)."""
    K, N, T, P = st.n_rows, st.n_image_blocks, st.n_targets, st.n_passes
    D = N * na + P * nb
    ny = n + 1
    rows = 2 * 8.0 * R * K * 2 * (na + nb + C_width + ny)
    targets = 8.0 * R * (K * 3 * (na + nb) + T * (9 + 3 * ny)) if C_width else 0.0
    nuis = 8.0 * R * (D + 3 * T) * ny
    if path == "dense":
        system = 8.0 * R * (3 * float(D) ** 2 + 3 * T * D)
    else:
        pairs = float(st.n_images)
        if C_width and K:
            shared = np.bincount(st.target_index, minlength=T)[st.target_index] > 1
            if shared.any():
                # the image pairs that share a target: the non-zeros of B Bᵀ, B the (images × targets)
                # incidence of the shared rows — a sparse product whose size is 1/na² of the fill it counts
                inc = sp.csr_matrix(
                    (np.ones(int(shared.sum()), np.float32), (st.image_index[shared], st.target_index[shared])),
                    shape=(st.n_images, T),
                )
                pairs = float((inc @ inc.T).nnz)
        per_image = 4.0 if st.has_samples else 1.0  # an image's errors on two samples
        nnz = min(pairs * per_image * na**2 + N * 2 * na * nb + P * nb**2, float(D) ** 2)
        system = 3 * 12.0 * R * nnz  # 8 B value + 4 B index per non-zero: S, its copy, its factor
    # DECISION: × 1.5 over the counted arrays (temporaries of the per-chunk products, SuperLU's
    # workspace): campaign-6pass (1 320 rows, sparse) 6.3 MiB estimated, 4.4 MiB traced + 1.0 MiB of
    # SuperLU factor (not traced); tests/core/test_row_gls.py's strip (10 000 rows, 2 runs) 45 MiB,
    # 24.8 + 3.7 MiB.
    return 1.5 * (rows + targets + nuis + system)


def row_gls(structure: RowStructure, columns: RowColumns, weights: np.ndarray | None = None, *, path: Path = "auto") -> RowFit:
    """The GLS of x on rows: the nuisances eliminated in the order of the module docstring.

    ``weights`` (R, K) robust weights on each row's information (1 = as modelled, 0 = dropped) or
    None. ``path``: ``"dense"`` (batched Cholesky of the reduced image/pass system), ``"sparse"``
    (SuperLU) or ``"auto"`` (dense when D = N·na + P·nb ≤ ``DENSE_MAX``).
    """
    st, cols = structure, columns
    R, K = cols.q.shape[:2]
    if K != st.n_rows:
        # internal: row_gls's callers (fit_rows, core.line_scan) build the columns from the same rows as the structure
        raise ValueError(f"row_gls: the columns have {K} rows, the structure {st.n_rows}")
    n, na, nb = cols.X.shape[-1], cols.A.shape[-1], cols.B.shape[-1]
    ny = n + 1
    D = st.n_image_blocks * na + st.n_passes * nb
    T = st.n_targets
    if st.sample_correlation is not None and st.sample_correlation.shape[1] != na:
        raise InputValueError(
            f"row_gls: sample_correlation has {st.sample_correlation.shape[1]} columns, the per-sample columns A {na}"
        )
    if path == "auto":
        # DECISION: the dense kernel also forms Ũ_ν (R, 3T, D): dense only while that stays small too
        # (few images can see very many targets); the sparse kernel gives the same numbers (tested, 1e-10)
        path = "dense" if D <= DENSE_MAX and 8.0 * R * 3 * T * D <= DENSE_U_MAX_BYTES else "sparse"
    check_memory(
        f"the GLS on rows of {R} run(s) × {K} rows ({st.n_images} images, {T} targets, D = {D} image/pass unknowns,"
        f" the {path} kernel)",
        row_gls_bytes(st, R, n, na, nb, C_width=cols.C.shape[-1], path=path),
        hint="fewer runs per chunk, or the campaign split by pass",
    )
    blk, tf = _blocks_and_targets(st, cols, weights)
    Syy = blk["yy"].copy()
    if tf["ks"].size:
        Syy -= _gram(tf["Uy"], tf["Uy"])
    ay = _to_samples(st, blk["ay"]) if st.has_samples else blk["ay"]
    Hny = np.concatenate([ay.reshape(R, -1, ny), blk["by"].reshape(R, -1, ny)], axis=1)  # (R, D, ny)
    Sny = Hny.copy()
    f: dict[str, Any] = dict(tf=tf, na=na, nb=nb, D=D)
    if st.has_samples and D:
        # attitude samples: the reduced system assembled sparse (its a-blocks couple the two samples of each
        # image), then factorised by the kernel ``path`` chooses
        H = _H_nu_samples(st, blk, na, nb, D)
        f["condition_bound"] = _sparse_gershgorin(H, R, D) * _sample_prior_bound(st)
        S = _reduced_sparse(st, blk, tf, na, nb, D, Sny, H)
        if path == "dense":
            Sdense = np.stack([S[r * D : (r + 1) * D, r * D : (r + 1) * D].toarray() for r in range(R)])
    else:
        f["condition_bound"] = _gershgorin(st, blk)
    if D == 0:
        f["L"] = np.zeros((R, 0, 0))
        red, SinvSny = Syy, np.zeros((R, 0, ny))
    elif path == "dense":
        # S⁻¹ S_νy by two triangular solves (never an explicit S⁻¹, whose error eps·cond S would
        # enter ν_Y directly)
        if not st.has_samples:
            Sdense = _H_nu_dense(st, blk, na, nb, D)
            if tf["ks"].size:
                Ud = _U_nu_dense(st, tf, na, nb, D)  # (R, 3T, D)
                Sdense -= np.swapaxes(Ud, -1, -2) @ Ud
                Sny -= np.swapaxes(Ud, -1, -2) @ tf["Uy"].reshape(R, -1, ny)
        L = np.linalg.cholesky(Sdense)
        f["L"] = L
        W = _tri_solve(L, Sny)
        red = Syy - np.swapaxes(W, -1, -2) @ W
        SinvSny = _tri_solve(L, W, transpose=True)
    else:
        # every run at once: the runs' systems side by side, block-diagonally (one sparse product,
        # one factorisation)
        if not st.has_samples:
            S = _reduced_sparse(st, blk, tf, na, nb, D, Sny, _H_nu(st, blk, na, nb, D))
        lu = splu(S.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        f["lu"], f["S"] = lu, S
        SinvSny = lu.solve(Sny.reshape(R * D, ny)).reshape(R, D, ny)
        red = Syy - np.swapaxes(Sny, -1, -2) @ SinvSny
    f["Sny"], f["SinvSny"] = Sny, SinvSny
    # DECISION: the reduced [Y] block is accumulated from the reduced rows, not as S_yy − S_νyᵀ S⁻¹ S_νy:
    # with ν_Y the MAP nuisances of each column of Y, min_ν Σ w |Y e − Z ν|² + |ν|² is
    # Σ_k w_k Ỹ_kᵀ Ỹ_k + ν_Yᵀ ν_Y (Ỹ = Y − Z ν_Y) — a sum of squares whose error is second order in
    # the error of ν_Y (ν_Y is a minimiser), where the subtraction lost eps·|H_yy|/|reduced|:
    # 5e-4 relative on the planner's nearly unobservable θ alone (σ 3 517″, plan-kiev680), 3e-9 on
    # campaign-6pass's σ.
    f["nuY"], data_gram, counted = _nuisances_and_gram(f, st, cols, weights, SinvSny)
    # the prior |ν|² is on the samples (|M a|²: their innovations, when correlated)
    prior_parts = (_sample_innovations(st, f["a_samples"]),) + f["nuY"][1:] if st.has_samples else f["nuY"]
    red_rows = sum(_gram(Z, Z) for Z in prior_parts if Z.size) + data_gram
    red = 0.5 * (red_rows + np.swapaxes(red_rows, -1, -2))
    ne = NormalEquations(n, R)
    ne.data_information = red[:, :n, :n].copy()
    ne.vector = red[:, :n, n].copy()
    ne.weighted_sum_squares = red[:, n, n].copy()
    ne.n_residuals = counted
    return RowFit(ne, st, cols, weights, path, f)


def _reduced_sparse(
    st: RowStructure, blk: dict[str, np.ndarray], tf: dict[str, Any], na: int, nb: int, D: int, Sny: np.ndarray, H: sp.csr_matrix
) -> sp.csr_matrix:
    """S = H_νν − Ũ_νᵀ Ũ_ν of every run (block-diagonally) and S_νy −= Ũ_νᵀ Ũ_y in place (step 2, sparse)."""
    R, ny = Sny.shape[0], Sny.shape[-1]
    S = H
    if tf["ks"].size:
        # the fill Ũᵀ Ũ summed over chunks of targets: Ũ of one chunk at a time (at 10⁶ rows the
        # whole Ũ as COO and CSR took 0.66 GB)
        targets = np.unique(tf["t"])
        step = max(1, targets.size * CHUNK_ROWS // max(tf["ks"].size, 1))
        for j in range(0, targets.size, step):
            chunk = targets[j : j + step]
            U = _U_nu(st, tf, None, na, nb, D, chunk=chunk)
            Sny -= (U.T @ tf["Uy"][:, chunk].reshape(-1, ny)).reshape(R, D, ny)
            S = (S - U.T @ U).tocsr()
            del U
    return S


def _sparse_gershgorin(H: sp.csr_matrix, R: int, D: int) -> np.ndarray:
    """(R,) the largest absolute row sum of each run's block of a block-diagonal sparse H_νν (≥ 1: the prior)."""
    sums = np.asarray(abs(H).sum(axis=1)).reshape(R, D)
    out: np.ndarray = np.maximum(sums.max(axis=1), 1.0)
    return out


def _reduced_Y(
    st: RowStructure, cols: RowColumns, nuY: tuple[np.ndarray, np.ndarray, np.ndarray], s: slice | np.ndarray
) -> np.ndarray:
    """Ỹ = Y − A a_Y − B b_Y − C c_Y (R, k, 2, ny) for the rows ``s``: each column of Y with its MAP
    nuisances ``nuY`` (``_nuisances_and_gram``) removed (unweighted; pixel-σ units), for ``row_group_grams``."""
    a, b, c = nuY
    img, rp, tgt = st.image_index[s], st.row_pass[s], st.target_index[s]
    out: np.ndarray = cols.Y_of(s) - cols.A[:, s] @ a[:, img] - cols.B[:, s] @ b[:, rp]
    if cols.C.shape[-1]:
        out -= cols.C[:, s] @ c[:, tgt]
    return out


def _solve_S(fit: RowFit, rhs: np.ndarray) -> np.ndarray:
    """S⁻¹ rhs, rhs (R, D, ...)."""
    f = fit._f
    if not f["D"]:
        return np.zeros(rhs.shape)
    if "L" in f:
        L = f["L"]
        flat = rhs.reshape(rhs.shape[:2] + (-1,))
        out: np.ndarray = _tri_solve(L, _tri_solve(L, flat), transpose=True).reshape(rhs.shape)
        return out
    sol: np.ndarray = f["lu"].solve(np.ascontiguousarray(rhs.reshape(rhs.shape[0] * f["D"], -1))).reshape(rhs.shape)
    return sol


def _S_inverse(fit: RowFit) -> np.ndarray:
    """S⁻¹ (R, D, D), from the Cholesky factor or the LU factors (D solves), kept once formed."""
    f = fit._f
    if "Sinv" not in f:
        if "L" in f:
            L = f["L"]
            Linv = _tri_solve(L, np.broadcast_to(np.eye(f["D"]), L.shape))
            Sinv = np.swapaxes(Linv, -1, -2) @ Linv
        else:
            # S is block-diagonal over runs: the stacked identities give every run's inverse at once
            R = f["Sny"].shape[0]
            Sinv = f["lu"].solve(np.tile(np.eye(f["D"]), (R, 1))).reshape(R, f["D"], f["D"])
        f["Sinv"] = 0.5 * (Sinv + np.swapaxes(Sinv, -1, -2))
    out: np.ndarray = f["Sinv"]
    return out


def _nuisances_and_gram(
    fit_parts: dict[str, Any], st: RowStructure, cols: RowColumns, weights: np.ndarray | None, nu: np.ndarray
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray, np.ndarray]:
    """The MAP nuisances for each of the ny right-hand columns of Y = [X | q], the weighted sum of squares of
    the reduced rows and the residual components counted, in one pass over chunks of rows:

    * a (R, N, na, ny), b (R, P, nb, ny) from ν = S⁻¹ S_νy (R, D, ny), then c (R, T, 3, ny) target by target:
      shared c_t = L_t⁻ᵀ (Ũ_ty − Ũ_tν ν); single-use c = (E₃ + w CᵀC)⁻¹ w Cᵀ r = w Cᵀ (E₂ + w C Cᵀ)⁻¹ r
      (Woodbury; r = Y − A a − B b, the row's residual before its own target);
    * Σ_k w_k Ỹ_kᵀ Ỹ_k (R, ny, ny), Ỹ = Y − A a − B b − C c (unweighted, pixel-σ units);
    * (R,) the residual components counted (non-zero Jacobian row or residual; weight > 0)."""
    tf, na, nb = fit_parts["tf"], fit_parts["na"], fit_parts["nb"]
    R, D, ny = nu.shape
    K = st.n_rows
    NA = st.n_image_blocks
    a = nu[:, : NA * na].reshape(R, NA, na, ny)
    b = nu[:, NA * na :].reshape(R, st.n_passes, nb, ny)
    if st.has_samples:
        # the samples' MAP nuisances, and each image's interpolation of them (what its rows see)
        fit_parts["a_samples"] = a
        a = _to_images(st, a)
    nc = cols.C.shape[-1]
    c = np.zeros((R, st.n_targets, nc, ny))
    img, rp, tgt = st.image_index, st.row_pass, st.target_index
    ks = tf["ks"]
    if nc and ks.size:
        # Ũ_tν ν = Σ_{k∈t} (V A')_k a_n(k) + Σ_{pairs (t, p)} (V B')_tp b_p
        Unu = np.zeros(tf["Uy"].shape)
        for s in _chunks(ks.size):
            _add_by(Unu, tf["t"][s], tf["VA"][:, s] @ a[:, img[ks[s]]])
        if nb:
            for s in _chunks(tf["tb"].size):
                _add_by(Unu, tf["tb"][s], tf["VB"][:, s] @ b[:, tf["pb"][s]])
        c = np.swapaxes(tf["Linv"], -1, -2) @ (tf["Uy"] - Unu)  # L⁻ᵀ g
        c[:, np.setdiff1d(np.arange(st.n_targets), tf["t"])] = 0.0
    single = _single_rows(st, cols)
    w = None if weights is None else np.asarray(weights, float)
    gram = np.zeros((R, ny, ny))
    counted = np.zeros(R, np.int64)
    for s in _chunks(K):
        X, q = cols.X[:, s], cols.q[:, s]
        valid = np.any(X != 0, axis=-1) | (q != 0)
        if w is not None:
            valid &= w[:, s, None] > 0
        counted += valid.reshape(R, -1).sum(axis=1)
        r = np.concatenate([X, q[..., None]], axis=-1) - cols.A[:, s] @ a[:, img[s]] - cols.B[:, s] @ b[:, rp[s]]
        if nc:
            sg = single[s]
            if sg.any():
                j = np.flatnonzero(sg)
                Cs = cols.C[:, s][:, j]  # (R, k1, 2, 3)
                w2 = 1.0 if w is None else np.maximum(w[:, s][:, j], 0.0)[..., None, None]
                Li = chol_inv_2x2(np.eye(2) + w2 * (Cs @ np.swapaxes(Cs, -1, -2)))
                c[:, tgt[s][j]] = (w2 * np.swapaxes(Cs, -1, -2)) @ (np.swapaxes(Li, -1, -2) @ (Li @ r[:, j]))
            r -= cols.C[:, s] @ c[:, tgt[s]]
        gram += _gram(r, r) if w is None else _wgram(w[:, s], r)
    return (a, b, c), gram, counted


def row_nuisances(fit: RowFit, dx: np.ndarray) -> RowNuisances:
    """The MAP per-image, per-pass and catalogue nuisances given x = dx (R, n): the nuisances of the
    columns of Y (kept by ``row_gls``) contracted with [−dx, 1] (they are linear in it)."""
    f = fit._f
    dx = np.asarray(dx, float)
    ext = np.concatenate([-dx, np.ones((dx.shape[0], 1))], axis=-1)  # Y · ext = q − X dx
    a, b, c = (np.einsum("r...i,ri->r...", Z, ext) for Z in f["nuY"])
    a_s = np.einsum("r...i,ri->r...", f["a_samples"], ext) if "a_samples" in f else None
    return RowNuisances(a, b, c, a_s)


def _single_rows(st: RowStructure, cols: RowColumns) -> np.ndarray:
    """(K,) rows whose target is seen by that row only (folded in step 1)."""
    if not cols.C.shape[-1]:
        return np.zeros(st.n_rows, bool)
    out: np.ndarray = np.bincount(st.target_index, minlength=st.n_targets)[st.target_index] == 1
    return out


def row_residuals(fit: RowFit, dx: np.ndarray, per_image_whitened: bool = False) -> np.ndarray:
    """Pixel-level normalised residuals (R, K, 2) at the correction ``dx`` (R, n).

    The MAP nuisances of the (weighted) fit given x = dx are removed from the whitened residual
    q̃ − X dx; the rest is in units of the pixel σ, without the robust weights (a down-weighted
    row shows its full residual). With ``per_image_whitened`` the per-image errors are not
    removed but whitened: the residual with the shared errors (b, c) at their MAP value, times
    the inverse Cholesky factor of each image's covariance E + A_n A_nᵀ over its rows in order —
    N(0, E) up to the leverage of x and the shared errors, as a whiteness test needs them.
    With attitude samples an image's a_n = Σ_i w_i a_{s_i} has the marginal prior (Σ_i w_i)² E when its two
    samples are one, else (w_0² + w_1²) E, which the whitening uses (images sharing a sample stay correlated).
    """
    st, cols = fit.structure, fit.columns
    nu = row_nuisances(fit, dx)
    dx = np.asarray(dx, float)
    R = cols.q.shape[0]
    img, rp, tgt = st.image_index, st.row_pass, st.target_index
    na, nc = cols.A.shape[-1], cols.C.shape[-1]
    e = np.empty(cols.q.shape)
    for s in _chunks(st.n_rows):
        es = cols.q[:, s] - (cols.X[:, s] @ dx[:, None, :, None])[..., 0] - (cols.B[:, s] @ nu.b[:, rp[s], :, None])[..., 0]
        if nc:
            es -= (cols.C[:, s] @ nu.c[:, tgt[s], :, None])[..., 0]
        if na and not per_image_whitened:
            es -= (cols.A[:, s] @ nu.a[:, img[s], :, None])[..., 0]
        e[:, s] = es
    if not (per_image_whitened and na):
        return e
    counts = np.bincount(img, minlength=st.n_images)
    start = st.row_start
    out = np.empty_like(e)
    for m in np.unique(counts[counts > 0]):
        ims = np.flatnonzero(counts == m)
        rows = (start[ims][:, None] + np.arange(m)).ravel()  # (u·m,) the rows of these images
        An = cols.A[:, rows].reshape(R, ims.size, 2 * m, na)
        if st.has_samples:
            An = An * _image_sample_scale(st, na)[ims][None, :, None, :]
        L = np.linalg.cholesky(np.eye(2 * m) + An @ np.swapaxes(An, -1, -2))
        white = np.linalg.solve(L, e[:, rows].reshape(R, ims.size, 2 * m)[..., None])[..., 0]
        out[:, rows] = white.reshape(R, -1, 2)
    return out


def row_reduced_rows(fit: RowFit, covariance_x: np.ndarray | None, leverage: bool = True) -> tuple[np.ndarray | None, np.ndarray]:
    """Each residual component's leverage h (R, K, 2) and reduced x-row z̃ (R, K, 2, n).

    h_i = z_iᵀ J⁻¹ z_i for the unweighted whitened row z_i and the fit's (weighted) joint
    information J; z̃_i = z_x − J_xν J_νν⁻¹ z_ν (module docstring). ``covariance_x`` (R, n, n) the
    inverse reduced information (``NormalEquations.solve().covariance``, with any prior the caller
    added); with ``leverage=False`` h is not computed (None) and ``covariance_x`` is not needed.
    Up to D = ``LEVERAGE_MAX`` (or on the dense kernel) h comes from S⁻¹ formed whole; above, from the
    selected inverse of S or solves with its SuperLU factor (``_leverage_by_solves``): exact on every
    route (equal to 1e-9 relative, ``tests/core/test_row_gls.py``); z̃ is exact on both paths.
    """
    st, cols, f = fit.structure, fit.columns, fit._f
    tf, na, nb = f["tf"], f["na"], f["nb"]
    R, K = cols.q.shape[:2]
    n = cols.X.shape[-1]
    img = st.image_index
    # step 1: a folded row is whitened by (E₂ + w C Cᵀ)⁻¹ (its α and x part), its c part of h is C Hc⁻¹ Cᵀ
    alpha = np.concatenate([cols.A, cols.B], axis=-1)  # (R, K, 2, m), own image then own pass
    zx = cols.X.copy()
    h = np.zeros((R, K, 2))
    single = np.flatnonzero(_single_rows(fit.structure, fit.columns))
    if single.size:
        sw2 = 1.0 if fit.weights is None else np.maximum(np.asarray(fit.weights, float)[:, single], 0.0)[..., None, None]
        Cs = cols.C[:, single]
        P2 = np.linalg.inv(np.eye(2) + sw2 * (Cs @ np.swapaxes(Cs, -1, -2)))
        alpha[:, single] = P2 @ alpha[:, single]
        zx[:, single] = P2 @ zx[:, single]
        Hc = np.eye(3) + sw2 * (np.swapaxes(Cs, -1, -2) @ Cs)
        h[:, single] = np.einsum("rkic,rkcd,rkid->rki", Cs, np.linalg.inv(Hc), Cs)
    ks = tf["ks"]
    v = None
    if ks.size:
        t = tf["t"]
        v = np.swapaxes(tf["Linv"][:, t] @ np.swapaxes(cols.C[:, ks], -1, -2), -1, -2)  # (R, Ks, 2, 3): v_i = L⁻¹ C_iᵀ
        h[:, ks] += np.sum(v**2, axis=-1)
        zx[:, ks] -= v @ tf["Uy"][:, t, :, :n]
    # step 3: the image/pass system. M = S⁻¹ S_νx; z̃ = z̄_x − Mᵀ z̄_ν, z̄_ν = α − Ũ_νᵀ v
    M = f["SinvSny"][..., :n]  # (R, D, n)
    if st.has_samples:  # in the image layout: each image's interpolation of its samples' rows of S⁻¹ S_νx
        NA = st.n_image_blocks
        Ma = _to_images(st, M[:, : NA * na].reshape(R, NA, na, n)).reshape(R, -1, n)
        M = np.concatenate([Ma, M[:, NA * na :]], axis=1)
    ia, ib = _nu_index(st, na, nb)
    own = np.concatenate([ia, ib], axis=1)  # (K, m)
    for i in range(0, K, CHUNK_ROWS):
        s_ = slice(i, i + CHUNK_ROWS)
        zx[:, s_] -= alpha[:, s_] @ M[:, own[s_]]  # (R, k, 2, m) @ (R, k, m, n)
    if ks.size:
        assert v is not None
        # Ũ_ν M per target, row by row (no Ũ formed): Σ_{k∈t} (V A')_k M_a(n(k)) + Σ_pairs (V B')_tp M_b(p)
        t = tf["t"]
        UM = np.zeros((R, st.n_targets, 3, n))
        for i in range(0, ks.size, CHUNK_ROWS):
            s_ = slice(i, i + CHUNK_ROWS)
            UM += _sum_by(t[s_], st.n_targets, tf["VA"][:, s_] @ M[:, ia[ks[s_]]])
        if nb:
            Mb = M[:, st.n_images * na :].reshape(R, st.n_passes, nb, n)
            UM += _sum_by(tf["tb"], st.n_targets, tf["VB"] @ Mb[:, tf["pb"]])
        zx[:, ks] += v @ UM[:, t]
    if not leverage:
        return None, zx
    cx = np.asarray(covariance_x, float)
    Pimg_idx = np.concatenate(
        [np.arange(st.n_images)[:, None] * na + np.arange(na), st.n_images * na + st.pass_of_image[:, None] * nb + np.arange(nb)],
        axis=1,
    )
    if st.has_samples:  # the leverage on the sample system: a row's own columns are its two samples' (weighted) and its pass
        alpha, own, Pimg_idx = _sample_layout(st, alpha, na, nb)
    # the sparse kernel's S in independent blocks (passes that share no target): each block inverted whole
    blocks = _BlockInverse.of(fit) if "L" not in f else None
    if blocks is None and "L" not in f and (f["D"] > LEVERAGE_MAX or 16.0 * R * f["D"] ** 2 > LEVERAGE_INVERSE_MAX_BYTES):
        h += _leverage_by_solves(fit, alpha, v, own)
        h += _quadratic_rows(zx, cx)
        return h, zx
    # h_ν = αᵀ (S⁻¹)_II α − 2 αᵀ (S⁻¹ Ũ_tᵀ)_I v + vᵀ Ũ_t S⁻¹ Ũ_tᵀ v
    if blocks is None:
        Sinv = _S_inverse(fit)
        Pimg = Sinv[:, Pimg_idx[:, :, None], Pimg_idx[:, None, :]]  # (R, N, m, m)
    else:
        Pimg = blocks.gather(Pimg_idx)
    h += np.einsum("rkim,rkmp,rkip->rki", alpha, Pimg[:, img], alpha)
    if ks.size:
        assert v is not None
        h += _shared_leverage(fit, alpha, v, own, None if blocks is None else blocks.runs())
    h += _quadratic_rows(zx, cx)
    return h, zx


@dataclass(frozen=True)
class _BlockInverse:
    """S⁻¹ of a reduced system that falls apart into small independent blocks (its connected components:
    the passes of a campaign whose passes share no target, each with its images), every block inverted
    whole. ``flat`` holds the blocks' inverses one after the other (row-major), ``comp`` (R·D,) the block
    of each unknown (runs at offsets r·D), ``loc`` its place in the block, ``start`` / ``size`` each
    block's offset in ``flat`` and its order.

    DECISION: above ``LEVERAGE_MAX`` unknowns a campaign of single-use targets (the per-pass nuisances
    couple a pass's images, nothing couples two passes) took the band selected inverse, whose pass
    block X Z_bb is dense over every image (its sparse products with the rows' columns: 17 s of the
    leverage's 21 s in a 66 s diagnose at 60 passes, 13 100 rows, D = 7 560; cProfile). Its exact inverse is block-diagonal:
    Σ_c D_c³ work and Σ_c D_c² memory (60 blocks of 126: 0.2 s, 7.6 MB). Below ``LEVERAGE_MAX`` too, where
    S⁻¹ whole (D² per run) grew as the square of the passes. Taken on the sparse kernel when S of a run
    falls apart, every block has at most ``LEVERAGE_MAX`` unknowns and the blocks fit
    ``LEVERAGE_INVERSE_MAX_BYTES``; otherwise S⁻¹ whole, the selected inverse or the solves, as before.
    Exact: S⁻¹ is zero between blocks."""

    flat: np.ndarray
    comp: np.ndarray
    loc: np.ndarray
    start: np.ndarray
    size: np.ndarray
    D: int
    R: int

    @classmethod
    def of(cls, fit: RowFit) -> "_BlockInverse | None":
        """The blocks of the sparse kernel's S (every run), or None when S of a run is one block or a block is too large."""
        from scipy.sparse.csgraph import connected_components

        f = fit._f
        if "S" not in f:
            return None
        S = f["S"].tocoo()
        D = int(f["D"])
        n_all = S.shape[0]
        n_comp, comp = connected_components(S, directed=False)
        size = np.bincount(comp, minlength=n_comp)
        if (
            size.max() >= D
            or size.max() > LEVERAGE_MAX
            or 8.0 * float(np.sum(size.astype(float) ** 2)) > LEVERAGE_INVERSE_MAX_BYTES
        ):
            return None
        # blocks of equal order side by side (one batched inverse each); an unknown's place in its block
        order = np.lexsort((np.arange(n_all), comp))
        first = np.zeros(n_comp, np.int64)
        first[1:] = np.cumsum(size)[:-1]
        loc = np.empty(n_all, np.int64)
        loc[order] = np.arange(n_all) - first[comp[order]]
        by_size = np.argsort(size, kind="stable")
        start = np.zeros(n_comp, np.int64)
        start[by_size] = np.concatenate([[0], np.cumsum(size[by_size].astype(np.int64) ** 2)[:-1]])
        flat = np.zeros(int(np.sum(size.astype(np.int64) ** 2)))
        c = comp[S.row]
        flat[start[c] + loc[S.row] * size[c] + loc[S.col]] += S.data  # S's blocks (duplicates summed, as COO means)
        for d in np.unique(size):
            ids = by_size[size[by_size] == d]
            lo, hi = start[ids[0]], start[ids[-1]] + d * d
            blk = flat[lo:hi].reshape(ids.size, d, d)
            inv = np.linalg.inv(blk)
            flat[lo:hi] = (0.5 * (inv + np.swapaxes(inv, -1, -2))).ravel()
        return cls(flat, comp, loc, start, size.astype(np.int64), D, n_all // max(D, 1))

    def gather(self, idx: np.ndarray) -> np.ndarray:
        """(R, N, m, m): the entries (S⁻¹)_{idx_n i, idx_n j} of every run for index rows ``idx`` (N, m) (0 across blocks)."""
        ii = (np.arange(self.R) * self.D)[:, None, None, None] + idx[None, :, :, None]  # (R, N, m, 1)
        jj = (np.arange(self.R) * self.D)[:, None, None, None] + idx[None, :, None, :]  # (R, N, 1, m)
        ci, cj = self.comp[ii], self.comp[jj]
        same = ci == cj
        pos = self.start[ci] + self.loc[ii] * self.size[ci] + np.where(same, self.loc[jj], 0)
        out: np.ndarray = np.where(same, self.flat[pos], 0.0)
        return out

    def runs(self) -> list[sp.csr_matrix]:
        """Each run's S⁻¹ as a sparse (D, D) matrix (the blocks' entries)."""
        n_all = self.comp.size
        cs = self.size[self.comp]
        rows_ = np.repeat(np.arange(n_all), cs)
        members = np.argsort(self.comp, kind="stable")  # unknowns grouped by block, in loc order
        first = np.zeros(self.size.size, np.int64)
        first[1:] = np.cumsum(self.size)[:-1]
        cols_ = members[first[self.comp[rows_]] + (np.arange(rows_.size) - np.repeat(np.cumsum(cs) - cs, cs))]
        vals = self.flat[self.start[self.comp[rows_]] + self.loc[rows_] * self.size[self.comp[rows_]] + self.loc[cols_]]
        full = sp.csr_matrix((vals, (rows_, cols_)), shape=(n_all, n_all))
        return [full[r * self.D : (r + 1) * self.D][:, r * self.D : (r + 1) * self.D].tocsr() for r in range(self.R)]


def _sample_layout(st: RowStructure, alpha: np.ndarray, na: int, nb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A row's own nuisance columns on the sample system: α = [w_0 A, w_1 A, B] (R, K, 2, 2na + nb) at its image's two
    samples and its pass, ``own`` (K, 2na + nb) their indices in ν, and the same indices per image (N, 2na + nb)."""
    si, sw = st.sample_index, st.sample_weight
    assert si is not None and sw is not None
    NA = st.n_image_blocks
    ja, jb = np.arange(na), np.arange(nb)
    per_image = np.concatenate(
        [si[:, :1] * na + ja, si[:, 1:] * na + ja, NA * na + st.pass_of_image[:, None] * nb + jb], axis=1
    )  # (N, 2na + nb)
    img = st.image_index
    w = sw[img]  # (K, 2)
    a = alpha[..., :na]
    alpha_s = np.concatenate([a * w[None, :, None, :1], a * w[None, :, None, 1:], alpha[..., na:]], axis=-1)
    return alpha_s, per_image[img], per_image


def _shared_leverage(fit: RowFit, alpha: np.ndarray, v: np.ndarray, own: np.ndarray, Sinv: Any = None) -> np.ndarray:
    """The shared-target terms of h_ν, −2 αᵀ (S⁻¹ Ũ_tᵀ)_I v + vᵀ Ũ_t S⁻¹ Ũ_tᵀ v, (R, K, 2), with S⁻¹ formed
    whole (default) or ``Sinv`` each run's (D, D), dense or sparse (``_BlockInverse.runs``).

    Targets in chunks: S⁻¹ Ũᵀ of a chunk is (D, 3·chunk) dense, bounded by ``CHUNK_ROWS`` columns."""
    st, f = fit.structure, fit._f
    tf, na, nb, D = f["tf"], f["na"], f["nb"], f["D"]
    if Sinv is None:
        Sinv = _S_inverse(fit)
    R, K = alpha.shape[:2]
    ks, t = tf["ks"], tf["t"]
    out = np.zeros((R, K, 2))
    targets = np.unique(t)
    step = max(1, min(targets.size, (4 * CHUNK_ROWS * 64) // max(3 * D, 1)))
    for j in range(0, targets.size, step):
        chunk = targets[j : j + step]
        loc = np.full(st.n_targets, -1)
        loc[chunk] = np.arange(chunk.size)
        sel = np.flatnonzero(loc[t] >= 0)  # the shared rows of this chunk (positions in ks)
        tl = loc[t[sel]]
        for r in range(R):
            U = _U_nu(st, tf, r, na, nb, D, chunk=chunk)  # (3c, D)
            USinv = U @ Sinv[r]
            Q = np.asarray(USinv.toarray() if sp.issparse(USinv) else USinv).T  # (D, 3c) = S⁻¹ Ũᵀ
            G = np.asarray(U @ Q).reshape(chunk.size, 3, chunk.size, 3)
            Gt = G[tl, :, tl, :]  # (k, 3, 3)
            Qk = Q.reshape(D, chunk.size, 3)[own[ks[sel]][:, :, None], tl[:, None, None], np.arange(3)]  # (k, m, 3)
            a_, v_ = alpha[r, ks[sel]], v[r, sel]
            out[r, ks[sel]] = -2 * np.einsum("kim,kmc,kic->ki", a_, Qk, v_) + np.einsum("kic,kcd,kid->ki", v_, Gt, v_)
    return out


def _leverage_by_solves(fit: RowFit, alpha: np.ndarray, v: np.ndarray | None, own: np.ndarray) -> np.ndarray:
    """h_ν = z̄_νᵀ S⁻¹ z̄_ν (R, K, 2) for every residual component, z̄_ν = α_i − Ũ_νᵀ v_i, above
    ``LEVERAGE_MAX``: from the selected inverse of S (``_selected_inverse``: the band of S⁻¹ after a
    reverse Cuthill–McKee ordering of the image unknowns, the pass unknowns by the block inverse) or,
    when that band is too wide, by solving S X = Z̄ with the fit's SuperLU factor,
    ``LEVERAGE_SOLVE_ELEMENTS`` of X at a time. Z̄ is built in batches of rows either way.

    The runs' systems are block-diagonal, so a column of Z̄ carries the same residual component of
    every run (run r's part at offset r·D). The rows go in two groups: those without a shared target
    (z̄_ν is their own α_i: the image and pass columns), then the shared targets' rows, targets in
    chunks (a target's rows share the Ũ_t of its z̄_ν).

    DECISION: a selected inverse by Takahashi's recursion on a *banded* Cholesky factor (LAPACK's
    ``pbtrf`` through scipy, the band from reverse Cuthill–McKee; the few pass unknowns, each coupled
    to all its pass's images, by the exact block inverse) rather than on a general sparse LDLᵀ
    (scipy's ``splu`` exposes no LDLᵀ, and a Python loop over the columns of a general factor would need
    its supernodes): every entry a leverage reads is a non-zero of S, hence in the band, and the
    recursion costs D_a·w² for half-width w. The SuperLU solves stay as the exact fallback (one
    triangular pair per residual component): at D = 6 024 the band takes ~2 s CPU where the solves took
    134 s (``docs/benchmarks.md``, "The exact leverage above 4 000 image/pass unknowns", with its command).
    Equal to S⁻¹ formed whole to 1e-9 relative (D = 4 224, both routes) and to the dense kernel to 1e-10
    on every error mode."""
    st, f = fit.structure, fit._f
    tf, na, nb, D, lu = f["tf"], f["na"], f["nb"], f["D"], f["lu"]
    R, K = alpha.shape[:2]
    m = own.shape[1]
    out = np.zeros((R, K, 2))
    per_batch = max(1, LEVERAGE_SOLVE_ELEMENTS // (2 * R * D))  # residual rows (2 components each) per solve
    run_d = (np.arange(R) * D)[:, None, None, None]

    Zsel = _selected_inverse(fit)

    def solve(rows_: np.ndarray, Zsh: sp.spmatrix | None) -> None:
        k = rows_.size
        col = (2 * np.arange(k)[:, None] + np.arange(2))[None, :, :, None]  # (1, k, 2, 1)
        ri = np.broadcast_to(run_d + own[rows_][None, :, None, :], (R, k, 2, m))
        ci = np.broadcast_to(col, (R, k, 2, m))
        Zc = sp.coo_matrix((alpha[:, rows_].ravel(), (ri.ravel(), ci.ravel())), shape=(R * D, 2 * k)).tocsr()
        if Zsh is not None:
            Zc = Zc - Zsh
        if Zsel is not None:  # z̄ᵀ S⁻¹ z̄ from the selected inverse: only entries on z̄'s support pairs are read
            ZZ = Zc.multiply(Zsel @ Zc).tocsr()  # (R·D, 2k): each run's products in its own block of rows
            out[:, rows_] = np.stack([np.asarray(ZZ[r * D : (r + 1) * D].sum(axis=0)).ravel() for r in range(R)]).reshape(R, k, 2)
            return
        Z = Zc.toarray()
        X = lu.solve(Z)
        out[:, rows_] = np.einsum("rdj,rdj->rj", Z.reshape(R, D, 2 * k), X.reshape(R, D, 2 * k)).reshape(R, k, 2)

    ks = tf["ks"]
    plain = np.ones(K, bool)
    plain[ks] = False
    plain_rows = np.flatnonzero(plain)
    for i in range(0, plain_rows.size, per_batch):
        solve(plain_rows[i : i + per_batch], None)
    if not ks.size:
        return out
    assert v is not None
    t = tf["t"]
    order = np.argsort(t, kind="stable")  # positions in ks, by target
    targets, first = np.unique(t[order], return_index=True)
    ends = np.r_[first[1:], order.size]
    j = 0
    while j < targets.size:
        # targets j … j2−1: at least one, at most ``per_batch`` rows where more than one target
        j2 = max(j + 1, int(np.searchsorted(ends, first[j] + per_batch, side="right")))
        chunk = targets[j:j2]
        pos = np.sort(order[first[j] : ends[j2 - 1]])  # positions in ks of the chunk's rows, in row order
        rows_ = ks[pos]
        loc = np.full(st.n_targets, -1)
        loc[chunk] = np.arange(chunk.size)
        U = _U_nu(st, tf, None, na, nb, D, chunk=chunk)  # (R·3c, R·D), block-diagonal over runs
        c3 = 3 * chunk.size
        vi = (np.arange(R) * c3)[:, None, None, None] + (3 * loc[t[pos]])[None, :, None, None] + np.arange(3)
        vj = (2 * np.arange(pos.size)[:, None] + np.arange(2))[None, :, :, None]
        V = sp.coo_matrix(
            (
                v[:, pos].ravel(),
                (np.broadcast_to(vi, (R, pos.size, 2, 3)).ravel(), np.broadcast_to(vj, (R, pos.size, 2, 3)).ravel()),
            ),
            shape=(R * c3, 2 * pos.size),
        )
        solve(rows_, (U.T @ V.tocsr()))
        j = j2
    return out


def _band_takahashi(Lb: np.ndarray) -> np.ndarray:
    """The band of S⁻¹ from the banded Cholesky factor of S (``scipy.linalg.cholesky_banded``, lower:
    ``Lb[d, j]`` = L[j + d, j]): Takahashi's recursion, column by column from the last,

        Z[i, j] = −Σ_{k>j} Z[i, k] L[k, j] / L[j, j]  (j < i ≤ j + b),
        Z[j, j] = (1/L[j, j] − Σ_{k>j} Z[j, k] L[k, j]) / L[j, j],

    from Z L = L⁻ᵀ (upper triangular, diagonal 1/L[j, j]); L has no fill outside the band, so every
    Z[i, k] it reads lies in the band. Returns ``Zb`` (b + 1, n), ``Zb[d, j]`` = Z[j + d, j]."""
    b, n = Lb.shape[0] - 1, Lb.shape[1]
    Zb = np.zeros_like(Lb)
    p = np.arange(b)
    dg, mn = np.abs(p[:, None] - p[None, :]), np.minimum(p[:, None], p[None, :])
    c = Lb[0]
    for j in range(n - 1, -1, -1):
        w = min(b, n - 1 - j)
        if not w:
            Zb[0, j] = 1.0 / c[j] ** 2
            continue
        W = Zb[dg[:w, :w], j + 1 + mn[:w, :w]]  # Z[j+1 : j+1+w, j+1 : j+1+w] from the band
        lcol = Lb[1 : w + 1, j]
        z = -(W @ lcol) / c[j]
        Zb[1 : w + 1, j] = z
        Zb[0, j] = (1.0 / c[j] - lcol @ z) / c[j]
    return Zb


def _selected_inverse(fit: RowFit) -> sp.csr_matrix | None:
    """S⁻¹ of every run on (at least) the sparsity pattern of S, block-diagonal over runs ((R·D)²,
    run r at offset r·D), or None when its band is too wide (then ``_leverage_by_solves`` solves).

    S = [[S_aa, S_ab], [S_ba, S_bb]] with a the image unknowns and b the pass unknowns (few, but each
    coupled to every image of its pass: an arrow). S_aa is reordered by reverse Cuthill–McKee
    (``scipy.sparse.csgraph``) into a band of half-width w_b, factorised banded (LAPACK ``pbtrf``) and its
    inverse's band computed by ``_band_takahashi``; the pass block by the block inverse:
    X = S_aa⁻¹ S_ab, Z_bb = (S_bb − S_ba X)⁻¹, Z_ab = −X Z_bb, Z_aa = S_aa⁻¹ + X Z_bb Xᵀ (on the band).
    Every pair of unknowns a row's z̄ touches (its image, its pass, the images and passes sharing its
    target) is a non-zero of S, so inside that band: exact entries, no approximation."""
    from scipy.linalg import cho_solve_banded, cholesky_banded
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    f, st = fit._f, fit.structure
    if "S" not in f or st.has_samples:
        return None
    S, na, D = f["S"], f["na"], f["D"]
    Da = st.n_image_blocks * na
    R = S.shape[0] // D
    blocks = []
    for r in range(R):
        Sr = S[r * D : (r + 1) * D][:, r * D : (r + 1) * D].tocsr()
        if not Da:  # only pass unknowns: a small dense block
            blocks.append(sp.coo_matrix(np.linalg.inv(Sr.toarray())))
            continue
        Saa = Sr[:Da][:, :Da].tocsr()
        perm = reverse_cuthill_mckee(Saa, symmetric_mode=True).astype(np.int64)
        P = Saa[perm][:, perm].tocoo()
        w = int(np.abs(P.row - P.col).max()) if P.row.size else 0
        if 8.0 * Da * (w + 1) * 4 > SELECTED_INVERSE_MAX_BYTES or float(Da) * w * w > SELECTED_INVERSE_MAX_FLOPS:
            return None
        low = P.row >= P.col
        ab = np.zeros((w + 1, Da))
        ab[(P.row - P.col)[low], P.col[low]] = P.data[low]
        Lb = cholesky_banded(ab, lower=True)
        Zb = _band_takahashi(Lb)
        mb = D - Da
        rows_, cols_, vals = [], [], []
        if mb:
            Sab = Sr[:Da][:, Da:].toarray()[perm]  # (Da, mb), permuted rows
            X = cho_solve_banded((Lb, True), Sab)
            Zbb = np.linalg.inv(Sr[Da:][:, Da:].toarray() - Sab.T @ X)
            Zbb = 0.5 * (Zbb + Zbb.T)
            XZ = X @ Zbb
            for d in range(w + 1):
                Zb[d, : Da - d] += np.einsum("ij,ij->i", X[d:], XZ[: Da - d])
            pa = np.repeat(perm, mb)
            pb = np.tile(Da + np.arange(mb), Da)
            rows_ += [pa, pb, np.repeat(Da + np.arange(mb), mb)]
            cols_ += [pb, pa, np.tile(Da + np.arange(mb), mb)]
            vals += [-XZ.ravel(), -XZ.ravel(), Zbb.ravel()]
        for d in range(w + 1):
            j = np.arange(Da - d)
            rows_ += [perm[j + d]] + ([perm[j]] if d else [])
            cols_ += [perm[j]] + ([perm[j + d]] if d else [])
            vals += [Zb[d, : Da - d]] + ([Zb[d, : Da - d]] if d else [])
        blocks.append(sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows_), np.concatenate(cols_))), shape=(D, D)))
    out: sp.csr_matrix = sp.block_diag(blocks, format="csr")
    return out


def condition_warning(fit: RowFit) -> str | None:
    """A warning when ``fit.condition_bound`` exceeds ``CONDITION_WARN`` in some run, else None.

    >>> condition_warning.__name__
    'condition_warning'
    """
    bound = np.asarray(fit.condition_bound, float)
    bad = np.flatnonzero(bound > CONDITION_WARN)
    if not bad.size:
        return None
    r = int(bad[np.argmax(bound[bad])])
    where = "" if bound.size == 1 else f" (run {r}; {bad.size} of {bound.size} runs)"
    return (
        f"the noise model's image/pass nuisance system is ill-conditioned: cond ≤ {bound[r]:.2g} > {CONDITION_WARN:.0e}{where};"
        " the MAP per-image/per-pass errors and the pixel-level residuals may have lost digits (θ and σ only to second order)"
        " — check the noise model's σ (a star-tracker or GNSS σ far above what the pixels resolve)"
    )


def row_sandwich_middle(
    structure: RowStructure,
    WG: np.ndarray,
    pixel_covariance: np.ndarray,
    A: np.ndarray | None,
    B: np.ndarray | None,
    C: np.ndarray | None,
) -> np.ndarray:
    """(WG)ᵀ Σ (WG) (R, n, n) for weighted Jacobian rows WG (R, K, 2, n), error source by error source.

    ``pixel_covariance`` (2, 2) or (R, K, 2, 2) the pixel noise of each row; ``A``, ``B``, ``C`` (R, K,
    2, ·) the scaled (not whitened) nuisance columns or None. A shared error with columns Z adds TᵀT,
    T = Σ over the rows it touches of Zᵀ WG (per image, per pass, per target).
    """
    st = structure
    pix = np.asarray(pixel_covariance, float)
    mid = np.einsum("rkai,ab,rkbj->rij", WG, pix, WG) if pix.ndim == 2 else np.einsum("rkai,rkab,rkbj->rij", WG, pix, WG)
    for Z, index, size in ((A, st.image_index, st.n_images), (B, st.row_pass, st.n_passes), (C, st.target_index, st.n_targets)):
        if Z is not None and Z.shape[-1]:
            T = _gram_by(index, size, Z, WG)  # (R, groups, z, n)
            if Z is A and st.has_samples:  # a per-sample error touches its images with their weights: Wᵀ T
                T = _to_samples(st, T)
                if st.has_sample_correlation:  # its prior covariance (MᵀM)⁻¹: Tᵀ (MᵀM)⁻¹ T, a banded solve
                    pr, pc, pv = _sample_prior(st, Z.shape[-1])
                    n_p = st.n_image_blocks * Z.shape[-1]
                    P = sp.csc_matrix((pv, (pr, pc)), shape=(n_p, n_p))
                    R_, G_, z_, n_ = T.shape
                    KT = splu(P).solve(np.moveaxis(T, 0, 2).reshape(G_ * z_, R_ * n_))
                    mid = mid + np.einsum("rgzi,rgzj->rij", T, np.moveaxis(KT.reshape(G_, z_, R_, n_), 2, 0))
                    continue
            mid = mid + np.einsum("rgzi,rgzj->rij", T, T)
    sym: np.ndarray = 0.5 * (mid + np.swapaxes(mid, -1, -2))
    return sym
