"""The statistical core of the diagnosis: a whitened linear-Gaussian model and its extensions.

Any model the diagnosis works on (a landmark campaign, the sea-sky scan, …) is reduced, at the
current estimate, to one **whitened** least-squares problem

    z = X b + C c + e,    e ~ N(0, I)

* ``z`` (n,): the residuals (measured − predicted) multiplied by the inverse Cholesky factor
  of their covariance under the noise model, plus one row per Gaussian prior (value 0);
* ``X`` (n, p): the base model — θ first, then the effects already named, then nuisance
  parameters with Gaussian priors (per-pass star-tracker/GNSS errors, catalogue errors) in
  units of their own σ, each with a prior row of 1 — so plain least squares on (z, X) *is* the
  GLS fit with the shared errors marginalised (the same solution as the Schur complement of
  ``boresight.estimate``'s GLS; the tests check it);
* ``C`` (n, k): the columns of one candidate effect (∂ predicted / ∂ parameter, whitened), in
  units of the effect's typical size so the arithmetic is well scaled.

Everything the diagnosis needs follows from projections. With P⊥ = I − X (XᵀX)⁻¹ Xᵀ (from a
QR of X) the base residual is r0 = P⊥ z and χ²₀ = |r0|². Adding C, with C⊥ = P⊥ C:

    ĉ = (C⊥ᵀC⊥)⁻¹ C⊥ᵀ r0,   cov ĉ = (C⊥ᵀC⊥)⁻¹,   Δχ² = r0ᵀ C⊥ ĉ = χ²₀ − χ²₁        (1)

Δχ² is the likelihood-ratio statistic (−2 Δ log L with a known noise model); under "the
candidate is absent" it is χ²(k), under "present with size c" it is non-central χ²(k, λ) with
λ = cᵀ (C⊥ᵀC⊥) c. The θ estimate moves by −B_θ ĉ with B = (XᵀX)⁻¹ XᵀC (the regression of C on
X); a candidate that is *not* fitted but present at size c biases θ by +B_θ c (the
"θ shift" of a non-separable effect).

Separability. The generalised eigenvalues f of C⊥ᵀC⊥ v = f CᵀC v are 1 − ρ², ρ the canonical
correlations between the candidate and the base model: f → 0 in a direction the base model
absorbs entirely. A direction with ρ > ``SEPARABILITY_RHO`` (0.995, i.e. the data keep < 1 %
of the candidate's signal there) is not separable on this data; a candidate with no
separable direction is ``not_separable``; one with some is tested on the separable subspace
(its LR statistic has that many degrees of freedom).

Example
-------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> X = rng.normal(size=(200, 2)); C = rng.normal(size=(200, 1))
>>> z = X @ [1.0, -2.0] + 0.5 * C[:, 0] + rng.normal(size=200)
>>> lin = Linearization(z, X, n_data=200, n_fitted=2)
>>> base = fit_base(lin)
>>> ext = extend(base, C)
>>> round(float(ext.c[0]), 2), ext.rank
(0.44, 1)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, stats

__all__ = [
    "SEPARABILITY_RHO",
    "Linearization",
    "BaseFit",
    "Extension",
    "fit_base",
    "extend",
    "max_canonical_correlation",
]

#: canonical correlation with the base model above which a direction is "not separable"
# DECISION: 0.995 — a direction is tested when the data keep at least 1 % (1 − ρ²) of the
# candidate's signal there once θ and the nuisances have taken theirs; whether what is kept is
# *enough* is judged by the achieved information (the minimum detectable size inside the
# physical range, ``workflow._identifiability``) and by the LR test itself. ρ is a relative
# measure: passes that carry no separating information (nadir passes for a time tag) raise CᵀC
# and push ρ towards 1 while C⊥ᵀC⊥ — which sets the test's power — never decreases, so a low
# cut rejects effects the data name easily (0.95 declared the time tag of the planned Kiev
# 680 km campaign not separable in 40 of 40 seeds although its separable part alone gives
# Δχ² ≈ 47 at 20 ms, ρ = 0.978; docs/discrepancy.md). The cut only guards against columns whose
# independence from θ is noise or second-order detail: the time-tag column of a single nadir
# pass (physically a constant rotation, ρ = 1) keeps 0.09–0.34 % from the noise of the derived
# attitude rate (ρ = 0.9983–0.9995, 1 and 3 nadir passes, 3 seeds each, with ``effect_model``'s degree-4 rate; the 0.98 that
# motivated an earlier 0.95 came from the noisier degree-6 rate). ``boresight.studies.planning.naming``
# models this rule when it plans a campaign.
SEPARABILITY_RHO = 0.995


@dataclass(frozen=True)
class Linearization:
    """The whitened problem at one estimate (see the module docstring).

    ``z`` (n,), ``X`` (n, p); the first ``n_fitted`` columns of X are the fitted parameters
    (θ then named effects) that cost degrees of freedom; the rest are nuisances with a prior row
    each. ``n_data`` rows are data (the rest prior rows).
    """

    z: np.ndarray
    X: np.ndarray
    n_data: int
    n_fitted: int


@dataclass(frozen=True)
class BaseFit:
    """Least squares of z on X. X is equilibrated (columns scaled to unit norm, ``col_scale``)
    and solved through the Cholesky factor ``L`` of the scaled Gram matrix, with one step of
    iterative refinement; every projection below is a product with X, never an n × n matrix."""

    lin: Linearization
    L: np.ndarray  # (p, p) Cholesky factor of (X S)ᵀ(X S)
    col_scale: np.ndarray  # (p,) S
    b: np.ndarray  # (p,) coefficients
    residual: np.ndarray  # (n,) r0 = z − X b
    chi2: float
    dof: int

    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def p_value(self) -> float:
        """P(χ²(dof) ≥ χ²): the base fit's goodness of fit against the noise model."""
        return float(stats.chi2.sf(self.chi2, self.dof)) if self.dof > 0 else float("nan")

    def _solve(self, y):
        return linalg.cho_solve((self.L, True), y)

    def covariance(self, k: int | None = None) -> np.ndarray:
        """Covariance of the first ``k`` coefficients (default the fitted ones), (XᵀX)⁻¹."""
        k = self.lin.n_fitted if k is None else k
        p = self.L.shape[0]
        E = np.zeros((p, k))
        E[np.arange(k), np.arange(k)] = 1.0
        cov = self._solve(E)[:k] * np.outer(self.col_scale[:k], self.col_scale[:k])
        return 0.5 * (cov + cov.T)

    @property
    def Xs(self) -> np.ndarray:
        if "_Xs" not in self.__dict__:
            object.__setattr__(self, "_Xs", self.lin.X * self.col_scale)
        return self.__dict__["_Xs"]

    def project(self, C: np.ndarray) -> np.ndarray:
        """P⊥ C, (n, k)."""
        Xs = self.Xs
        return C - Xs @ self._solve(Xs.T @ C)

    def regress(self, C: np.ndarray) -> np.ndarray:
        """B = (XᵀX)⁻¹ Xᵀ C, (p, k): how the base coefficients absorb the columns C."""
        return self._solve(self.Xs.T @ C) * self.col_scale[:, None]

    def leverage(self, rows: int) -> np.ndarray:
        """Diagonal of the hat matrix X (XᵀX)⁻¹ Xᵀ for the first ``rows`` rows."""
        Xs = self.lin.X[:rows] * self.col_scale
        W = linalg.solve_triangular(self.L, Xs.T, lower=True)
        return np.einsum("ij,ij->j", W, W)


def fit_base(lin: Linearization) -> BaseFit:
    """Least squares of z on X (see :class:`BaseFit`). Raises ``ObservabilityError`` when a
    column of X is (numerically) a combination of the others."""
    if lin.X.ndim != 2 or lin.z.shape != (lin.X.shape[0],):
        raise ValueError(f"Linearization: expected z (n,) and X (n, p), got {lin.z.shape}, {lin.X.shape}")
    norms = np.sqrt(np.einsum("ij,ij->j", lin.X, lin.X))
    if np.any(~(norms > 0)):
        from boresight.errors import ObservabilityError

        raise ObservabilityError(f"the base model is not determined by the data (column {int(np.argmin(norms))} is zero)")
    S = 1.0 / norms
    Xs = lin.X * S
    N = Xs.T @ Xs
    try:
        L = np.linalg.cholesky(N)
    except np.linalg.LinAlgError:
        L = None
    # DECISION: the pivots of the Cholesky factor of the equilibrated Gram matrix bound its
    # conditioning from below (cheap; an eigen-decomposition costs ~10× the factorisation).
    piv = np.diag(L) ** 2 if L is not None else np.zeros(1)
    if L is None or not piv.min() > 1e-13 * piv.max():
        from boresight.errors import ObservabilityError

        raise ObservabilityError("the base model is not determined by the data (a parameter is a combination of the others;"
                                 f" smallest Cholesky pivot {piv.min():.3g})")
    bs = linalg.cho_solve((L, True), Xs.T @ lin.z)
    r = lin.z - Xs @ bs
    bs = bs + linalg.cho_solve((L, True), Xs.T @ r)  # iterative refinement
    r = lin.z - Xs @ bs
    chi2 = float(r @ r)
    dof = int(lin.n_data - lin.n_fitted)
    return BaseFit(lin, L, S, bs * S, r, chi2, dof)


@dataclass(frozen=True)
class Extension:
    """The base model extended by candidate columns C (scaled units), from eq (1).

    ``rho`` (k,) canonical correlations of C with the base model (descending);
    ``rank`` the number of separable directions; ``c`` (k,) and ``cov`` (k, k) the estimate
    and its covariance (pseudo-inverse on the separable subspace: directions that are not
    separable are set to 0 and carry no variance — ``rank < k`` says so); ``delta_chi2`` the
    LR statistic with ``rank`` degrees of freedom; ``theta_change`` (n_fitted,) how the fitted
    base coefficients move when C is added; ``signature`` (n,) the fitted whitened signature
    C⊥ ĉ; ``information`` (k, k) C⊥ᵀC⊥.
    """

    rho: np.ndarray
    rank: int
    c: np.ndarray
    cov: np.ndarray
    delta_chi2: float
    base_change: np.ndarray
    base_cov_after: np.ndarray
    signature: np.ndarray
    information: np.ndarray
    basis: np.ndarray  # (k, rank) separable directions in parameter space
    Cperp: np.ndarray

    @property
    def p_value(self) -> float:
        return float(stats.chi2.sf(self.delta_chi2, self.rank)) if self.rank else 1.0


def _separable_basis(C: np.ndarray, Cp: np.ndarray, rho_max: float):
    """Generalised eigen-decomposition C⊥ᵀC⊥ v = f CᵀC v → (ρ descending, basis of separable v)."""
    G0 = C.T @ C
    G1 = Cp.T @ Cp
    k = C.shape[1]
    scale = np.sqrt(np.clip(np.diag(G0), 0, None))
    live = scale > 1e-300
    if not np.any(live):
        return np.ones(k), np.zeros((k, 0))
    S = np.where(live, 1.0 / np.where(live, scale, 1.0), 0.0)
    G0s = G0 * S[:, None] * S[None, :]
    # drop directions with no signal at all (CᵀC singular, e.g. a column that is zero on this data)
    w0, V0 = np.linalg.eigh(G0s[np.ix_(live, live)])
    keep0 = w0 > 1e-10 * w0.max()
    T = np.zeros((k, int(keep0.sum())))
    T[np.ix_(live, np.ones(keep0.sum(), bool))] = V0[:, keep0] / np.sqrt(w0[keep0])
    T = T * S[:, None]  # parameter-space directions with unit signal norm
    f, W = np.linalg.eigh(T.T @ G1 @ T)  # f = 1 − ρ², ascending
    f = np.clip(f, 0.0, 1.0)
    rho = np.sqrt(1.0 - f)
    sep = rho <= rho_max
    basis = T @ W[:, sep]
    rho_all = np.concatenate([rho, np.ones(k - rho.size)])  # directions without signal: ρ ≡ 1
    return np.sort(rho_all)[::-1], basis


def extend(base: BaseFit, C: np.ndarray, rho_max: float = SEPARABILITY_RHO) -> Extension:
    """Fit the base model extended by columns ``C`` (n, k); see :class:`Extension`."""
    C = np.asarray(C, float)
    if C.ndim == 1:
        C = C[:, None]
    if C.shape[0] != base.residual.shape[0]:
        raise ValueError(f"extend: C has {C.shape[0]} rows, the model {base.residual.shape[0]}")
    Cp = base.project(C)
    rho, V = _separable_basis(C, Cp, rho_max)
    k = C.shape[1]
    nf = base.lin.n_fitted
    if V.shape[1] == 0:
        zero = np.zeros(k)
        return Extension(rho, 0, zero, np.zeros((k, k)), 0.0, np.zeros(nf), base.covariance(), np.zeros_like(base.residual),
                         Cp.T @ Cp, V, Cp)
    A = Cp @ V  # (n, r)
    Na = A.T @ A
    cov_a = np.linalg.inv(Na)
    cov_a = 0.5 * (cov_a + cov_a.T)
    g = A.T @ base.residual
    a = cov_a @ g
    c = V @ a
    cov = V @ cov_a @ V.T
    dchi2 = float(g @ a)
    B = base.regress(C @ V)[:nf]  # (nf, r)
    change = -B @ a
    cov_after = base.covariance() + B @ cov_a @ B.T
    return Extension(rho, V.shape[1], c, cov, dchi2, change, cov_after, A @ a, Cp.T @ Cp, V, Cp)


def max_canonical_correlation(A: np.ndarray, B: np.ndarray) -> float:
    """Largest canonical correlation between the column spaces of A (n, a) and B (n, b)."""
    if A.shape[1] == 0 or B.shape[1] == 0:
        return 0.0

    def orth(M):
        U, s, _ = np.linalg.svd(M, full_matrices=False)
        return U[:, s > 1e-10 * (s.max() if s.size else 1.0)]

    Qa, Qb = orth(A), orth(B)
    if Qa.shape[1] == 0 or Qb.shape[1] == 0:
        return 0.0
    return float(min(1.0, np.linalg.svd(Qa.T @ Qb, compute_uv=False).max()))

