"""The information-form accumulator shared by every least-squares algorithm (Kiev 2012 eqs 18, 22).

Every linearised algorithm gives, per observation block, residuals q (measured − predicted)
and a Jacobian G with ``q ≈ G (θ − θ0)``. The normal equations are accumulated recursively

    B_n = B_{n−1} + G_nᵀ W_n G_n,   y_n = y_{n−1} + G_nᵀ W_n q_n,   B_0 = 0, y_0 = 0   (eq 18)

and solved for ``B θ = y`` (the slide writes Σ G_kᵀ y_k; it means Σ G_kᵀ q_k). W is the
weight (inverse covariance) of the block: unit, diagonal or full. Algorithms 2, 3 and the
unit-vector algorithm differ only in how they build (G, q).

Nuisance parameters local to a block (a per-image pointing error, say) are eliminated on the
fly by a Schur complement: with nuisance columns H and prior information P_ν of the nuisance,

    B += Gᵀ W G − Gᵀ W H (Hᵀ W H + P_ν)⁻¹ Hᵀ W G,    y += Gᵀ W q − Gᵀ W H (Hᵀ W H + P_ν)⁻¹ Hᵀ W q,

which by the Woodbury identity equals GLS with the block covariance W⁻¹ + H P_ν⁻¹ Hᵀ.
Nuisances shared by several blocks (a per-pass bias) are carried as extra parameters and
eliminated at the end with :meth:`NormalEquations.eliminate`.

Shapes: the state has a leading run axis R: ``information`` (R, n, n), ``vector`` (R, n).
``update`` takes G (R, ..., k, n) and q (R, ..., k); axes between the run axis and k are
independent blocks and are summed.

Example
-------
>>> import numpy as np
>>> G = np.array([[[1.0, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]])   # (R=1, k=4, n=3)
>>> ne = NormalEquations()
>>> ne.update(G, G @ np.array([1.0, 2.0, 3.0]))
>>> sol = ne.solve()
>>> np.round(sol.theta, 12).tolist(), sol.dof.tolist()
([[1.0, 2.0, 3.0]], [1])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.errors import InputValueError, ObservabilityError, axis_name

__all__ = ["NormalEquations", "Solution", "ObservabilityError", "DEFAULT_MAX_CONDITION"]

# DECISION: a condition number of 1e8 means the weakest axis is known 1e4 times worse than
# the best one (e.g. 1″ on θx and 3° on θz): past that a θ is garbage, so we refuse. Good
# geometries of the Kiev cases sit at 1e2-1e5 (docs/estimators.md, "Observability").
DEFAULT_MAX_CONDITION = 1e8


@dataclass(frozen=True)
class Solution:
    """A solved set of normal equations (leading run axis R).

    ``theta`` (R, n) solves B θ = y; ``covariance`` (R, n, n) = B⁻¹ (the estimate's covariance
    when the weights are the true inverse covariance); ``condition_number`` (R,) of B (with the
    prior, if any); ``data_condition_number`` (R,) of the data part alone; ``weak_axis`` (R, n)
    eigenvector of B's smallest eigenvalue; ``chi2`` (R,) the minimised weighted sum of squares
    qᵀWq − yᵀθ (prior included); ``dof`` (R,) residual components + prior components −
    parameters (estimated or eliminated).
    """

    theta: np.ndarray
    covariance: np.ndarray
    condition_number: np.ndarray
    data_condition_number: np.ndarray
    weak_axis: np.ndarray
    chi2: np.ndarray
    dof: np.ndarray
    information: np.ndarray


def _axis(v: Any, labels: Any = None) -> str:
    """Name a weak direction: θ axes by ``axis_name``; with more unknowns, the largest components."""
    v = np.asarray(v, float)
    if v.size == 3 and labels is None:
        return axis_name(v)
    labels = list(labels) if labels is not None else ["θx", "θy", "θz"] + [f"p{k}" for k in range(v.size - 3)]
    v = v / (np.linalg.norm(v) or 1.0)
    order = np.argsort(-np.abs(v))[:3]
    return "direction " + " ".join(f"{v[k]:+.2f}·{labels[k]}" for k in order if abs(v[k]) >= 0.05)


def _sym(a: Any) -> np.ndarray:
    sym: np.ndarray = 0.5 * (a + np.swapaxes(a, -1, -2))
    return sym


def _condition(B: Any) -> tuple[np.ndarray, np.ndarray]:
    """Condition number (inf if singular), eigenvector of the smallest eigenvalue; batched."""
    lam, vec = np.linalg.eigh(_sym(B))
    lo, hi = lam[..., 0], lam[..., -1]
    # DECISION: eigenvalues below 1e-14·λmax are round-off of an exact zero: call them singular.
    singular = ~(lo > 1e-14 * np.abs(hi)) | ~(hi > 0)
    cond = np.divide(hi, lo, out=np.full(lo.shape, np.inf), where=~singular)
    return cond, vec[..., :, 0]


#: the accumulated sums of a ``NormalEquations`` (run axis first): what a sum of two accumulators
#: adds and what a one-run state repeats over the runs
_SUMS = (
    "data_information",
    "prior_information",
    "vector",
    "weighted_sum_squares",
    "n_residuals",
    "n_prior",
    "n_flat_nuisance",
)


class NormalEquations:
    """Recursive information-form least squares B θ = y (Kiev 2012 eqs 18, 22), batched over runs.

    Parameters
    ----------
    n_params : int
        Number of unknowns (3 for θ; more when shared nuisances are carried, see ``eliminate``).
    runs : int or None
        Size R of the run axis; ``None`` takes it from the first ``update`` or ``add_prior``.

    The unknown is whatever the Jacobians are taken with respect to — for an iterated
    estimator, the correction θ − θ0 about the linearisation point θ0.
    """

    def __init__(self, n_params: int = 3, runs: int | None = None) -> None:
        if int(n_params) != n_params or n_params < 1:
            raise InputValueError(f"NormalEquations.n_params must be a positive integer, got {n_params!r}")
        if runs is not None and (int(runs) != runs or runs < 1):
            raise InputValueError(f"NormalEquations.runs must be a positive integer or None, got {runs!r}")
        self.n_params = int(n_params)
        self.runs: int | None = None
        self._n_eliminated = 0  # parameters eliminated (count against the degrees of freedom)
        if runs is not None:
            self._init(int(runs))

    def _init(self, runs: int) -> None:
        n = self.n_params
        self.runs = runs
        self.data_information = np.zeros((runs, n, n))
        self.prior_information = np.zeros((runs, n, n))
        self.vector = np.zeros((runs, n))
        self.weighted_sum_squares = np.zeros(runs)  # qᵀ W q (+ prior term)
        self.n_residuals = np.zeros(runs, dtype=int)
        self.n_prior = np.zeros(runs, dtype=int)
        self.n_flat_nuisance = np.zeros(runs, dtype=int)

    def _check_runs(self, r: int, name: str) -> None:
        if self.runs is None:
            self._init(r)
        elif self.runs == 1 and r > 1:
            # a state with one run (e.g. a prior added before any data) is shared by every run
            for name in _SUMS:
                setattr(self, name, np.repeat(getattr(self, name), r, axis=0))
            self.runs = r
        elif r not in (1, self.runs):
            raise InputValueError(
                f"NormalEquations.update: {name} has {r} runs on its leading axis, the accumulator has {self.runs}"
            )

    @property
    def information(self) -> np.ndarray:
        """B (R, n, n): data information plus prior information."""
        return self.data_information + self.prior_information

    # ------------------------------------------------------------------ accumulation
    def add_prior(self, sigma: Any = None, *, information: Any = None, mean: Any = None) -> None:
        """Add a Gaussian prior on the unknown as initial information (B_0 ≠ 0).

        ``sigma`` (n,) or scalar: independent standard deviations (same units as θ, rad);
        or ``information`` (n, n) or (R, n, n): an inverse covariance. ``mean`` (n,) or (R, n):
        the prior mean of the unknown (for an iterated estimator: θ_prior − θ0); default 0.

        >>> ne = NormalEquations(runs=1)
        >>> ne.add_prior(2.0)
        >>> ne.solve().covariance[0].diagonal().tolist()
        [4.0, 4.0, 4.0]
        """
        n = self.n_params
        if (sigma is None) == (information is None):
            raise InputValueError("NormalEquations.add_prior: give exactly one of sigma or information")
        if sigma is not None:
            s = np.broadcast_to(np.asarray(sigma, float), (n,))
            if not np.all(np.isfinite(s) & (s > 0)):
                raise InputValueError(f"NormalEquations.add_prior: sigma must be finite and > 0, got {sigma!r}")
            P = np.diag(1.0 / s**2)
        else:
            P = np.asarray(information, float)
            if P.shape[-2:] != (n, n) or P.ndim not in (2, 3):
                raise InputValueError(
                    f"NormalEquations.add_prior: information must have shape ({n}, {n}) or (R, {n}, {n}), got {P.shape}"
                )
        P = P if P.ndim == 3 else P[None]
        self._check_runs(P.shape[0], "information")
        m = np.zeros((1, n)) if mean is None else np.asarray(mean, float)
        m = m if m.ndim == 2 else m[None]
        if m.shape[-1] != n:
            raise InputValueError(f"NormalEquations.add_prior: mean must have shape ({n},) or (R, {n}), got {m.shape}")
        self.prior_information = self.prior_information + P
        self.vector = self.vector + np.einsum("rij,rj->ri", P, m)
        self.weighted_sum_squares = self.weighted_sum_squares + np.einsum("ri,rij,rj->r", m, P, m)
        self.n_prior = self.n_prior + np.linalg.matrix_rank(P)

    def update(
        self,
        G: Any,
        q: Any,
        weights: Any = None,
        *,
        covariance: Any = None,
        nuisance: Any = None,
        nuisance_information: Any = None,
        valid: Any = None,
    ) -> None:
        """Add a batch of residuals: B += Gᵀ W G, y += Gᵀ W q (Kiev 2012 eq 18).

        Parameters
        ----------
        G : (R, ..., k, n) Jacobian of the residuals with respect to the unknown.
        q : (R, ..., k) residuals, measured − predicted.
        weights : None (unit), (R, ..., k) diagonal weights, or (R, ..., k, k) a full
            weight matrix (inverse covariance). Leading axes broadcast.
        covariance : alternatively the residual covariance, (R, ..., k) diagonal or
            (R, ..., k, k) full; the block is whitened with its Cholesky factor.
        nuisance : (R, ..., k, p) columns of nuisance parameters local to each block, eliminated
            by a Schur complement before accumulation.
        nuisance_information : (p, p) or broadcastable (R, ..., p, p) prior information of the
            nuisance; ``None`` is a flat prior (the nuisance is fitted freely and costs p degrees
            of freedom per block).
        valid : (R, ..., k) bool, which residual components count as observations (for the
            degrees of freedom); default: components with a non-zero Jacobian row or residual.
        """
        G = np.asarray(G, float)
        q = np.asarray(q, float)
        n = self.n_params
        if G.ndim < 3 or G.shape[-1] != n:
            raise InputValueError(f"NormalEquations.update: G must have shape (R, ..., k, {n}), got {G.shape}")
        if q.shape != G.shape[:-1]:
            raise InputValueError(f"NormalEquations.update: q must have shape {G.shape[:-1]} to match G {G.shape}, got {q.shape}")
        if weights is not None and covariance is not None:
            raise InputValueError("NormalEquations.update: give weights or covariance, not both")
        self._check_runs(G.shape[0], "G")
        k = G.shape[-1 - 1]
        H = None
        if nuisance is not None:
            H = np.asarray(nuisance, float)
            if H.shape[:-1] != G.shape[:-1]:
                raise InputValueError(f"NormalEquations.update: nuisance must have shape {G.shape[:-1]} + (p,), got {H.shape}")
        cols = G if H is None else np.concatenate([G, H], axis=-1)

        if valid is None:
            valid = np.any(G != 0, axis=-1) | (q != 0)
        valid = np.broadcast_to(np.asarray(valid, bool), q.shape)

        if covariance is not None:
            cols, q = _whitened(covariance, cols, q, k)
            weights = None
        Wcols, Wq, valid = _weighted(weights, cols, q, k, valid)

        N = np.einsum("...ki,...kj->...ij", cols, Wcols)  # (R, ..., n+p, n+p)
        b = np.einsum("...ki,...k->...i", cols, Wq)  # (R, ..., n+p)
        c = np.einsum("...k,...k->...", q, Wq)  # (R, ...)
        if H is not None:
            p = H.shape[-1]
            Nhh = N[..., n:, n:]
            if nuisance_information is not None:
                Nhh = Nhh + np.asarray(nuisance_information, float)
            # DECISION: pseudo-inverse, so that a nuisance direction the block cannot see (e.g.
            # a GNSS error along the line of sight) simply drops out instead of failing.
            Ninv = np.linalg.pinv(_sym(Nhh), hermitian=True)
            Ngh = N[..., :n, n:]
            bh = b[..., n:]
            N = N[..., :n, :n] - Ngh @ Ninv @ np.swapaxes(Ngh, -1, -2)
            b = b[..., :n] - np.einsum("...ij,...jk,...k->...i", Ngh, Ninv, bh)
            c = c - np.einsum("...i,...ij,...j->...", bh, Ninv, bh)
            if nuisance_information is None:
                blocks_used = np.any(valid, axis=-1).reshape(valid.shape[0], -1).sum(axis=1)
                self.n_flat_nuisance = self.n_flat_nuisance + p * blocks_used
        R = G.shape[0]
        self.data_information = self.data_information + _sym(N.reshape(R, -1, n, n).sum(axis=1))
        self.vector = self.vector + b.reshape(R, -1, n).sum(axis=1)
        self.weighted_sum_squares = self.weighted_sum_squares + c.reshape(R, -1).sum(axis=1)
        self.n_residuals = self.n_residuals + valid.reshape(valid.shape[0], -1).sum(axis=1)

    def __add__(self, other: "NormalEquations") -> "NormalEquations":
        """The sum of two accumulators over the same unknown (independent data)."""
        if not isinstance(other, NormalEquations) or other.n_params != self.n_params:
            raise InputValueError("NormalEquations: can only add accumulators with the same n_params")
        out = NormalEquations(self.n_params)
        if self.runs is None or other.runs is None:
            src = other if self.runs is None else self
            out.__dict__.update({k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in src.__dict__.items()})
            return out
        out._init(max(self.runs, other.runs))
        for name in _SUMS:
            setattr(out, name, getattr(self, name) + getattr(other, name))
        out._n_eliminated = self._n_eliminated + other._n_eliminated
        return out

    def eliminate(self, n_keep: int) -> "NormalEquations":
        """Schur-complement out the last ``n_params − n_keep`` unknowns (shared nuisances).

        Returns a new accumulator over the first ``n_keep`` unknowns whose solution equals the
        first ``n_keep`` components of the full solution, with the marginal covariance. Prior
        information on the eliminated unknowns must have been added (``add_prior``) for a
        Bayesian (GLS) treatment; without it they are fitted freely.

        >>> ne = NormalEquations(n_params=2, runs=1)
        >>> ne.update(np.array([[[1.0, 1.0], [1.0, -1.0], [0.0, 1.0]]]), np.array([[3.0, 1.0, 1.0]]))
        >>> round(float(ne.eliminate(1).solve().theta[0, 0]), 12)
        2.0
        """
        n = self.n_params
        if not (1 <= n_keep <= n) or int(n_keep) != n_keep:
            raise InputValueError(f"NormalEquations.eliminate: n_keep must be an integer in [1, {n}], got {n_keep!r}")
        if self.runs is None:
            raise InputValueError("NormalEquations.eliminate: nothing accumulated yet")
        B = self.information
        Bkk, Bkn, Bnn = B[:, :n_keep, :n_keep], B[:, :n_keep, n_keep:], B[:, n_keep:, n_keep:]
        Binv = np.linalg.pinv(_sym(Bnn), hermitian=True)
        y1, y2 = self.vector[:, :n_keep], self.vector[:, n_keep:]
        out = NormalEquations(n_keep, self.runs)
        P = self.prior_information
        # the prior on the kept block is kept apart (for the data condition number); cross
        # terms between kept and eliminated priors are folded into the data part.
        out.prior_information = P[:, :n_keep, :n_keep].copy()
        out.data_information = _sym(Bkk - Bkn @ Binv @ np.swapaxes(Bkn, -1, -2)) - out.prior_information
        out.vector = y1 - np.einsum("rij,rjk,rk->ri", Bkn, Binv, y2)
        out.weighted_sum_squares = self.weighted_sum_squares - np.einsum("ri,rij,rj->r", y2, Binv, y2)
        out.n_residuals = self.n_residuals.copy()
        out.n_prior = self.n_prior.copy()
        out.n_flat_nuisance = self.n_flat_nuisance.copy()
        out._n_eliminated = self._n_eliminated + (n - n_keep)
        return out

    # ------------------------------------------------------------------ solution
    def dof(self) -> np.ndarray:
        """Degrees of freedom (R,): residual components + prior components − unknowns (incl. eliminated)."""
        return self.n_residuals + self.n_prior - self.n_params - self._n_eliminated - self.n_flat_nuisance

    def solve(self, check: bool = True, max_condition: float = DEFAULT_MAX_CONDITION, labels: Any = None) -> Solution:
        """Solve B θ = y for every run; raise ``ObservabilityError`` if θ is not determined.

        With ``check`` (default) a run with fewer residual components (plus prior components)
        than unknowns, or with cond(B) > ``max_condition``, raises an ``ObservabilityError``
        naming the run, the weak axis and the condition number. With ``check=False`` such runs
        get the minimum-norm (pseudo-inverse) solution and covariance. ``labels`` names the
        unknowns in the message (default θx, θy, θz, p0, …).
        """
        if self.runs is None:
            raise ObservabilityError("NormalEquations.solve: no observations were accumulated (0 residuals for 3 parameters)")
        B = _sym(self.information)
        cond, weak = _condition(B)
        data_cond, _ = _condition(self.data_information)
        n = self.n_params
        if check:
            have = self.n_residuals + self.n_prior
            few = np.flatnonzero(have < n)
            if few.size:
                r = int(few[0])
                raise ObservabilityError(
                    f"θ is not observable: too few observations — run {r} has {int(self.n_residuals[r])} residual components"
                    f" (+{int(self.n_prior[r])} prior) for {n} unknowns ({few.size} of {self.runs} runs);"
                    f" weak axis {_axis(weak[r], labels)}, condition number {cond[r]:.3g}",
                    weak_axis=weak[r],
                    condition_number=float(cond[r]),
                    run=r,
                )
            bad = np.flatnonzero(~(cond <= max_condition))
            if bad.size:
                r = int(bad[0])
                raise ObservabilityError(
                    f"θ is not observable: weak axis {_axis(weak[r], labels)}, condition number {cond[r]:.3g} > {max_condition:.3g}"
                    f" (run {r}; {bad.size} of {self.runs} runs)",
                    weak_axis=weak[r],
                    condition_number=float(cond[r]),
                    run=r,
                )
        if np.all(np.isfinite(cond)):
            # DECISION: batched Cholesky (numpy) — scipy's cho_factor is not batched.
            L = np.linalg.cholesky(B)
            Linv = np.linalg.inv(L)
            cov = np.swapaxes(Linv, -1, -2) @ Linv
        else:
            cov = np.linalg.pinv(B, hermitian=True)
        cov = _sym(cov)
        theta = np.einsum("rij,rj->ri", cov, self.vector)
        chi2 = self.weighted_sum_squares - np.einsum("ri,ri->r", self.vector, theta)
        return Solution(
            theta=theta,
            covariance=cov,
            condition_number=cond,
            data_condition_number=data_cond,
            weak_axis=weak,
            chi2=chi2,
            dof=self.dof(),
            information=B,
        )


def _whitened(covariance: Any, cols: np.ndarray, q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(cols, q) whitened by the residual covariance: (…, k) diagonal or (…, k, k) full."""
    S = np.asarray(covariance, float)
    if S.shape[-1:] != (k,) or S.ndim < 1:
        raise InputValueError(f"NormalEquations.update: covariance must have shape (..., {k}) or (..., {k}, {k}), got {S.shape}")
    if S.shape[-2:] == (k, k) and S.shape != q.shape:
        # DECISION: whiten with the Cholesky factor L (Σ = L Lᵀ) rather than invert Σ:
        # L⁻¹G, L⁻¹q are better conditioned than Gᵀ Σ⁻¹ G formed from an explicit inverse.
        try:
            L = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            raise InputValueError("NormalEquations.update: covariance is not positive definite") from None
        L = np.broadcast_to(L, q.shape[:-1] + (k, k))
        return np.linalg.solve(L, cols), np.linalg.solve(L, q[..., None])[..., 0]
    if not np.all(S > 0):
        raise InputValueError("NormalEquations.update: diagonal covariance must be > 0")
    w = np.sqrt(1.0 / S)
    return cols * w[..., None], q * w


def _weighted(
    weights: Any, cols: np.ndarray, q: np.ndarray, k: int, valid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(W cols, W q, valid) for unit (None), diagonal (…, k) or full (…, k, k) weights; a zero
    diagonal weight removes the component from the observations counted."""
    if weights is None:
        return cols, q, valid
    W = np.asarray(weights, float)
    if W.shape[-2:] == (k, k) and W.shape != q.shape:
        return W @ cols, (W @ q[..., None])[..., 0], valid
    if W.shape[-1:] == (k,) or W.ndim == 0:
        if np.any(W < 0):
            raise InputValueError("NormalEquations.update: diagonal weights must be ≥ 0")
        return cols * W[..., None], q * W, valid & np.broadcast_to(W > 0, q.shape)
    raise InputValueError(f"NormalEquations.update: weights must have shape (..., {k}) or (..., {k}, {k}), got {W.shape}")
