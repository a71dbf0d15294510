"""The statistical core of the diagnosis: a whitened linear-Gaussian model and its extensions.

Any model the diagnosis works on (a landmark campaign, the sea-sky scan, …) is reduced, at the
current estimate, to one **whitened** least-squares problem

    z = X b + C c + e,    e ~ N(0, I)

* ``z`` (n,): the residuals (measured − predicted), whitened under the noise model;
* ``X`` (n, p): the base model — θ first, then the effects already named; the errors shared by
  several observations (per-pass star-tracker/GNSS errors, catalogue errors) are eliminated
  with their Gaussian priors, so least squares on (z, X) *is* the GLS fit with them
  marginalised (the same solution as ``boresight.estimate``'s GLS; the tests check it);
* ``C`` (n, k): the columns of one candidate effect (∂ predicted / ∂ parameter, whitened), in
  units of the effect's typical size so the arithmetic is well scaled.

The problem is held in **reduced normal-equation form** (:class:`GramProblem`): the Gram matrix
of every column the diagnosis may use (base, candidates, structure probes) and of z, which for a
campaign is exactly what the one block-sparse campaign GLS (``boresight.core.gls.campaign``)
accumulates; columns are :class:`Columns`, coefficient vectors over that basis, so every fit,
extension and withdrawal below is algebra on small Gram blocks. Small problems and the tests may
give the rows instead (:class:`Linearization`, converted by :func:`gram_problem`).

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
from typing import Any, Callable

import numpy as np
import scipy.sparse as sps
from scipy import linalg

from boresight.errors import InputTypeError, InputValueError
from boresight.stats import chi2_sf

__all__ = [
    "SEPARABILITY_RHO",
    "Linearization",
    "GramProblem",
    "Columns",
    "gram_problem",
    "BaseFit",
    "Extension",
    "fit_base",
    "extend",
    "max_canonical_correlation",
    "separable_basis",
    "canonical_correlation",
    "lr_test",
    "STRUCTURED_MIN_COLUMNS",
]

#: canonical correlation with the base model above which a direction is "not separable"
# DECISION: 0.995 — a direction is tested when the data keep at least 1 % (1 − ρ²) of the
# candidate's signal there once θ and the nuisances have taken theirs; whether what is kept is
# *enough* is judged by the achieved information (the minimum detectable size inside the
# physical range, ``naming.identifiability``) and by the LR test itself. ρ is a relative
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


#: a column joins an independent subset while more than this fraction of its signal is left
# DECISION: 1e-6. Exact dependencies (the probe ``attitude law`` is a sum of ``pass`` columns)
# come out at ≤ 1e-12 in the Gram form; the pass columns, built at θ = 0, sum to the base's θ
# columns at the current θ up to ~1e-8 of their signal — a direction that carries no information
# and would only make the combined fit ill-conditioned. 1e-6 drops both and keeps every
# direction the data can see at the percent level (the separability cut keeps ≥ 1 %).
INDEPENDENCE_TOL = 1e-6


@dataclass(frozen=True)
class Linearization:
    """The whitened problem given as rows (see the module docstring): the form small problems
    and the tests build. ``z`` (n,), ``X`` (n, p); the first ``n_fitted`` columns of X are the
    fitted parameters (θ then named effects) that cost degrees of freedom; the rest are nuisances
    with a prior row each. ``n_data`` rows are data (the rest prior rows). :func:`gram_problem`
    turns it into the reduced form every fit works on."""

    z: np.ndarray
    X: np.ndarray
    n_data: int
    n_fitted: int


@dataclass(frozen=True)
class Columns:
    """Columns of a :class:`GramProblem` as coefficients over its column basis: the whitened
    columns are X_all T, T (p, k). ``C @ V`` combines them, ``C[:, j]`` selects."""

    T: np.ndarray

    @property
    def k(self) -> int:
        return self.T.shape[1]

    def __matmul__(self, V):
        return Columns(_dense_if_small(self.T @ np.asarray(V, float)))

    def __getitem__(self, key):
        return Columns(self.T[key])

    @staticmethod
    def concat(cols) -> "Columns":
        cols = list(cols)
        if any(sps.issparse(c.T) for c in cols):
            return Columns(sps.hstack([sps.csc_matrix(c.T) for c in cols], format="csc"))
        return Columns(np.concatenate([c.T for c in cols], axis=1))


@dataclass(frozen=True)
class GramProblem:
    """The whitened problem in reduced normal-equation form: everything the diagnosis computes.

    ``gram`` (p+1, p+1) is [X z]ᵀ Σ⁻¹ [X z] over p columns (θ, named effects, candidates,
    probes) and the residual z, with every nuisance (per-pass star-tracker/GNSS errors, catalogue
    errors) eliminated — for a campaign, the reduced normal equations of
    ``boresight.core.gls.campaign`` (the one GLS); ``raw`` (p, p) the same Gram with only the
    per-row errors whitened (pixel noise and the per-image errors), against which canonical
    correlations with the base model are measured (CᵀC of the module docstring). Either is an array or
    a :class:`BlockGram` (the same matrix held by its blocks, never formed: a campaign's per-pass
    columns). The first ``n_fitted`` columns are the base model. ``rows(x, cov, use)`` gives, for the
    residual tests, the ``n_data`` per-row residuals in units of their noise (nuisances at their MAP
    value given the coefficients x (p,)), their leverages (cov (u, u) the covariance of x[use], ``use``
    (u,) the columns with a coefficient or a variance) and the residuals in a form that is white under
    the model (``BaseFit.innovations``).
    """

    gram: Any
    raw: Any
    n_data: int
    n_fitted: int
    rows: Callable | None = None

    @property
    def p(self) -> int:
        return int(self.gram.shape[0]) - 1

    def columns(self, start: int, stop: int) -> Columns:
        """The columns start..stop−1 as :class:`Columns`: sparse coefficients (k entries, not a dense (p, k)).

        DECISION: sparse whatever their size — every state of a diagnosis keeps its candidates' and probes' columns,
        and a dense (p, k) each (p ≈ 4 300 at 600 passes) was ~100 MB of live memory at 39 300 observations, growing
        as the passes squared (``docs/benchmarks.md``, "### ``diagnose``"); a selection's products are exact either
        way (one unit entry a column)."""
        k = stop - start
        return Columns(sps.csc_matrix((np.ones(k), (np.arange(start, stop), np.arange(k))), shape=(self.p, k)))

    def quad(self, A, B=None):
        """Aᵀ G B over the p columns (B = A by default), A (p, a), B (p, b) coefficients (arrays or sparse)."""
        if isinstance(self.gram, BlockGram):
            return self.gram.quad(A, A if B is None else B)
        return _quad(self.gram[: self.p, : self.p], A, A if B is None else B)

    def score(self, A) -> np.ndarray:
        """Aᵀ Xᵀz (a,): the columns A against the residual."""
        if isinstance(self.gram, BlockGram):
            e = np.zeros((self.p + 1, 1))
            e[-1] = 1.0
            return np.asarray(self.gram.quad(A, e)).reshape(-1)
        return _quad(self.gram[: self.p, self.p], A)

    @property
    def zz(self) -> float:
        """zᵀz (the residual's own term)."""
        if isinstance(self.gram, BlockGram):
            e = np.zeros((self.p + 1, 1))
            e[-1] = 1.0
            return float(self.gram.quad(e, e)[0, 0])
        return float(self.gram[self.p, self.p])

    def raw_gram(self, C: Columns):
        """CᵀC in the per-row whitened metric, (k, k)."""
        if isinstance(self.raw, BlockGram):
            return self.raw.quad(C.T, C.T)
        return _quad(self.raw, C.T, C.T)


#: above this many entries a product of coefficient matrices is kept sparse (a (k, k) block of the per-pass probes)
_DENSE_MAX = 1_000_000


def _dense_if_small(A):
    """A sparse matrix as an array when it has at most ``_DENSE_MAX`` entries (else as it is)."""
    if sps.issparse(A) and A.shape[0] * A.shape[1] <= _DENSE_MAX:
        return A.toarray()
    return A


def _array(A) -> np.ndarray:
    """A sparse matrix (or a matrix) as a plain array."""
    return A.toarray() if sps.issparse(A) else np.asarray(A)


def _support(A) -> np.ndarray:
    """The rows of a coefficient matrix (array or sparse) with a non-zero entry."""
    if sps.issparse(A):
        A = sps.csr_matrix(A)
        return np.flatnonzero(np.diff(A.indptr) > 0)
    return np.flatnonzero(np.any(A != 0, axis=1))


class BlockGram:
    """A Gram matrix over n columns held by its blocks, never formed: ``shared`` (s, s), ``coupling`` (s, G·l)
    and ``local`` (G, l, l), with the maps ``Ms`` (s, n) and ``Ml`` (G·l, n) (sparse) from the n columns to
    s shared atoms and l local atoms in each of G groups (the first ``size`` of them, default all), so that

        G = Msᵀ shared Ms + Msᵀ coupling Ml + Mlᵀ couplingᵀ Ms + Mlᵀ blockdiag(local) Ml.

    It is the reduced Gram of a campaign whose passes fall into G groups that share no target
    (``campaign.CampaignProblem._gram``): a column non-zero on one group's rows only (a per-pass probe) is a
    local atom there, the other columns (θ, the effects, the probes over every pass) are shared; the
    per-pass columns of two groups are orthogonal. Storage s² + G·l·(s + l), not n²; a product Aᵀ G B costs
    the non-zeros of the coefficients times the atoms they reach.

    DECISION: the whole (p + 1)² Gram was 145 MB at 600 passes (p = 4 258: 7 per-pass columns a pass) per
    live linearisation, and its assembly a sparse product of that size; the blocks are ~3 MB there.
    """

    def __init__(self, shared: np.ndarray, coupling: np.ndarray, local: np.ndarray, Ms, Ml, size: int | None = None):
        self.shared = 0.5 * (shared + shared.T)
        self.coupling = coupling
        G, l, _ = local.shape
        local = 0.5 * (local + np.swapaxes(local, 1, 2))
        self.local = sps.block_diag(list(local), format="csr") if G * l else sps.csr_matrix((0, 0))
        n = Ms.shape[1] if size is None else size
        Ms, self.Ml = sps.csc_matrix(Ms)[:, :n], sps.csc_matrix(Ml)[:, :n]
        self.shape = (n, n)
        # a shared atom is one column with weight 1 (θ, an effect, a probe over every pass, the residual)
        self._shared_of = np.full(n, -1)
        Mc = sps.coo_matrix(Ms)
        self._shared_of[Mc.col] = Mc.row
        if not np.all(Mc.data == 1.0) or np.unique(Mc.col).size != Mc.col.size:
            # internal: BlockGram is built by campaign._block_gram alone, whose shared atoms are unit columns by construction
            raise ValueError("BlockGram: each shared atom must be one column with weight 1")
        self._local = np.diff(self.Ml.indptr) > 0

    def _atoms(self, A):
        """(Ms A (s, a), Ml A (G·l, a) or None when A reaches no local atom) for coefficients A over the first
        A.shape[0] columns, reading the rows of A in use."""
        ra = _support(A)
        sh = self._shared_of[ra]
        a_s = np.zeros((self.shared.shape[0], A.shape[1]))
        if np.any(sh >= 0):
            a_s[sh[sh >= 0]] = _array(A[ra[sh >= 0]])
        rl = ra[self._local[ra]]
        return a_s, (self.Ml[:, rl] @ A[rl] if rl.size else None)

    def quad(self, A, B):
        """Aᵀ G B for coefficients A (n', a), B (n', b) over the first n' ≤ n columns (arrays or sparse)."""
        a_s, a_l = self._atoms(A)
        b_s, b_l = (a_s, a_l) if B is A else self._atoms(B)
        res: Any = a_s.T @ (self.shared @ b_s)
        if b_l is not None:
            res = res + a_s.T @ _array(self.coupling @ b_l)
        if a_l is not None:
            res = res + _array(b_s.T @ _array(self.coupling @ a_l)).T
        if a_l is not None and b_l is not None:
            loc = a_l.T @ (self.local @ b_l)
            loc = _dense_if_small(sps.csr_matrix(loc)) if sps.issparse(loc) else np.asarray(loc)
            if sps.issparse(loc) and not np.any(res):
                res = loc
            else:
                res = res + _array(loc)
        return 0.5 * (res + res.T) if B is A else res

    def __array__(self, dtype=None, copy=None):
        """The whole matrix (n, n), for tests on small problems."""
        eye = np.eye(self.shape[0])
        out = np.asarray(self.quad(eye, eye))
        return out.astype(dtype) if dtype is not None else out


def _quad(M: np.ndarray, A, B=None):
    """Aᵀ M B (or Aᵀ m for a vector m = M (p,) when B is None) for coefficient matrices A (p, a), B (p, b)
    (arrays or sparse) over the p columns of a Gram matrix, reading only the rows and columns of M where A
    and B are non-zero.

    DECISION: ``Columns`` select or combine a few of the many columns of a diagnosis (the probes and the
    scanned ``alignment_step`` add 7 per pass: p ≈ 480 at 60 passes, ≈ 4 300 at 600); a product over the
    whole Gram costs p² per call and made every fit, test and withdrawal quadratic in the passes. Only
    terms with a zero coefficient are left out: equal to the whole product to round-off."""
    ra = _support(A)
    if B is None:
        out = A[ra].T @ M[ra]
        return np.asarray(out).reshape(-1) if sps.issparse(A) else out
    rb = ra if B is A else _support(B)
    Ab = A[ra].T @ M[np.ix_(ra, rb)]
    res = Ab @ B[rb]
    if sps.issparse(res) or isinstance(res, np.matrix):
        res = _dense_if_small(sps.csr_matrix(res))
    return res


def gram_problem(lin: Linearization, extra: np.ndarray | None = None) -> tuple[GramProblem, Columns | None]:
    """The :class:`GramProblem` of a row-form problem, with optional extra columns (n, k) appended
    after the fitted ones (returned as :class:`Columns`). The nuisance columns are eliminated by a
    QR factorisation (no Gram subtraction)."""
    X = np.asarray(lin.X, float)
    nf = lin.n_fitted
    extra = np.zeros((X.shape[0], 0)) if extra is None else np.asarray(extra, float).reshape(X.shape[0], -1)
    A = np.column_stack([X[:, :nf], extra, lin.z])
    raw = A[:, :-1].T @ A[:, :-1]
    Nu = X[:, nf:]
    Q = np.zeros((X.shape[0], 0))
    if Nu.shape[1]:
        Q, _ = np.linalg.qr(Nu)
        A = A - Q @ (Q.T @ A)
    gram = A.T @ A
    nd = int(lin.n_data)
    hq = np.einsum("ij,ij->i", Q[:nd], Q[:nd])

    def rows(x, cov, use):
        Ad = A[:nd, :-1]
        r = A[:nd, -1] - Ad @ x
        Au = Ad[:, use]
        return r, hq + np.einsum("ij,jk,ik->i", Au, cov, Au), r

    g = GramProblem(0.5 * (gram + gram.T), raw, nd, nf, rows)
    return g, (g.columns(nf, nf + extra.shape[1]) if extra.shape[1] else None)


class BaseFit:
    """Least squares of z on the base columns ``T`` (p, nb) of a :class:`GramProblem`, from its
    Gram matrix: the base Gram is equilibrated (columns scaled to unit norm, ``col_scale``) and
    factorised by Cholesky (``L``) with one step of iterative refinement. Every projection below
    (C⊥ = P⊥ C, B = (XᵀX)⁻¹XᵀC, …) is a product of small Gram blocks, never a row-space array."""

    def __init__(self, lin: GramProblem, T: np.ndarray, dense: Linearization | None = None):
        self.lin = lin
        self.T = T
        self._dense = dense
        Gbb = _array(lin.quad(T))
        gz = lin.score(T)
        norms = np.sqrt(np.clip(np.diag(Gbb), 0, None))
        if np.any(~(norms > 0)):
            from boresight.errors import ObservabilityError

            raise ObservabilityError(f"the base model is not determined by the data (column {int(np.argmin(norms))} is zero)")
        S = 1.0 / norms
        N = Gbb * S[:, None] * S[None, :]
        try:
            L = np.linalg.cholesky(N)
        except np.linalg.LinAlgError:
            L = None
        # DECISION: the pivots of the Cholesky factor of the equilibrated Gram matrix bound its
        # conditioning from below (cheap; an eigen-decomposition costs ~10× the factorisation).
        piv = np.diag(L) ** 2 if L is not None else np.zeros(1)
        if L is None or not piv.min() > 1e-13 * piv.max():
            from boresight.errors import ObservabilityError

            raise ObservabilityError(
                "the base model is not determined by the data (a parameter is a combination of the others;"
                f" smallest Cholesky pivot {piv.min():.3g})"
            )
        self.L, self.col_scale = L, S
        self._Gbb = Gbb
        bs = linalg.cho_solve((L, True), S * gz)
        bs = bs + linalg.cho_solve((L, True), S * gz - N @ bs)  # iterative refinement
        self.b = bs * S
        self.chi2 = float(max(lin.zz - gz @ self.b, 0.0))
        self.n_fitted = T.shape[1]
        self.dof = int(lin.n_data - self.n_fitted)

    # ---------------------------------------------------------------- statistics
    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    @property
    def p_value(self) -> float:
        """P(χ²(dof) ≥ χ²): the base fit's goodness of fit against the noise model."""
        return float(chi2_sf(self.chi2, self.dof)) if self.dof > 0 else float("nan")

    def _solve(self, y):
        """(XᵀX)⁻¹ y for the base columns, y (nb, ·) in unscaled units."""
        S = self.col_scale
        y = np.asarray(y, float)
        Sy = S[:, None] * y if y.ndim == 2 else S * y
        out = linalg.cho_solve((self.L, True), Sy)
        return S[:, None] * out if y.ndim == 2 else S * out

    def covariance(self, k: int | None = None) -> np.ndarray:
        """Covariance of the first ``k`` base coefficients (default all of them), (XᵀX)⁻¹."""
        k = self.n_fitted if k is None else k
        E = np.zeros((self.n_fitted, k))
        E[np.arange(k), np.arange(k)] = 1.0
        cov = self._solve(E)[:k]
        return 0.5 * (cov + cov.T)

    # ---------------------------------------------------------------- projections (Gram form)
    def _cols(self, C) -> Columns:
        if isinstance(C, Columns):
            return C
        raise InputTypeError.expected("BaseFit", "columns", "Columns (coefficients over its Gram problem's column basis)", C)

    def cross(self, C: Columns) -> np.ndarray:
        """Xᵀ C (nb, k)."""
        return _array(self.lin.quad(self.T, self._cols(C).T))

    def regress(self, C: Columns) -> np.ndarray:
        """B = (XᵀX)⁻¹ Xᵀ C, (nb, k): how the base coefficients absorb the columns C."""
        return self._solve(self.cross(C))

    def perp_gram(self, C1: Columns, C2: Columns | None = None) -> np.ndarray:
        """C1⊥ᵀ C2⊥ (k1, k2) with C⊥ = P⊥ C (default C2 = C1)."""
        C2 = C1 if C2 is None else C2
        x1, x2 = self.cross(C1), self.cross(C2)
        out = _array(self.lin.quad(C1.T, C1.T if C2 is C1 else C2.T)) - x1.T @ self._solve(x2)
        return 0.5 * (out + out.T) if C2 is C1 else out

    def perp_score(self, C: Columns) -> np.ndarray:
        """C⊥ᵀ r0 (k,)."""
        return self.lin.score(C.T) - self.cross(C).T @ self.b

    def extended(self, C: Columns) -> "BaseFit":
        """The base model with the columns C added (raises ``ObservabilityError`` when singular)."""
        CT = self._cols(C).T
        T = (
            sps.hstack([sps.csc_matrix(self.T), sps.csc_matrix(CT)], format="csc")
            if sps.issparse(CT)
            else np.concatenate([self.T, CT], axis=1)
        )
        return BaseFit(self.lin, _dense_if_small(T), self._dense)

    def independent(self, C: Columns, tol: float = INDEPENDENCE_TOL) -> np.ndarray:
        """Indices of a subset of C's columns that is independent of the base model and of each
        other (pivoted Cholesky of C⊥ᵀC⊥ with each column normalised by its own norm): a column
        is kept while more than ``tol`` of its signal is left after the base and the columns
        already kept — a rank-revealing reduction, so a set with one column a combination of
        others is reduced, never rejected."""
        P = self.perp_gram(C)
        d = np.diag(_array(self.lin.raw_gram(C))).copy()
        live = np.flatnonzero(d > 0)
        if live.size == 0:
            return live
        s = 1.0 / np.sqrt(d[live])
        Pn = P[np.ix_(live, live)] * s[:, None] * s[None, :]
        _, piv, rank, info = linalg.lapack.dpstrf(Pn, lower=1, tol=tol)
        if info < 0:  # pragma: no cover - LAPACK argument error
            # internal: a LAPACK argument error, a programming error no input reaches (Pn is square, tol a float)
            raise ValueError(f"dpstrf: illegal argument {-info}")
        return np.sort(live[piv[:rank] - 1])

    def max_canonical_correlation(self, C1: Columns, C2: Columns) -> float:
        """Largest canonical correlation between C1⊥ and C2⊥ (the candidates once the base model
        has taken its part)."""
        return _gram_canonical(self.perp_gram(C1), self._perp_isqrt(C2), self.perp_gram(C1, C2), whitened=True)

    def _perp_isqrt(self, C: Columns) -> np.ndarray:
        """``_isqrt`` of C⊥ᵀC⊥, kept for the columns' next call (the ``pass`` probe against each candidate that
        names a per-pass bias its look-alike: one eigen-decomposition of its k × k block, not one per candidate)."""
        cache = self.__dict__.setdefault("_isqrt", {})
        if id(C) not in cache:
            cache[id(C)] = (C, _isqrt(self.perp_gram(C)))
        return cache[id(C)][1]

    # ---------------------------------------------------------------- rows (residual tests)
    def data_residuals(self):
        """(r, h, w): the n_data per-row residuals, their leverages (hat diagonal) and innovations."""
        if "_rows" not in self.__dict__:
            use = _support(self.T)  # the columns of the base model (no p × p covariance)
            x = np.asarray(self.T @ self.b).reshape(-1)
            Tu = self.T[use]
            cov = _array(Tu @ _array(Tu @ self.covariance()).T)
            self._rows = self.lin.rows(x, cov, use)
        return self._rows

    @property
    def residual(self) -> np.ndarray:
        """The n_data per-row residuals (whitened, nuisances at their MAP value)."""
        return self.data_residuals()[0]

    def leverage(self, rows: int) -> np.ndarray:
        """Diagonal of the hat matrix for the first ``rows`` data rows."""
        return self.data_residuals()[1][:rows]

    @property
    def innovations(self) -> np.ndarray:
        """The n_data residuals in a form that is white under the model up to the leverage of
        the fitted and shared parameters (for a campaign: each image whitened by the Cholesky
        factor of its covariance), in acquisition order: what a whiteness test reads."""
        return self.data_residuals()[2]


def _isqrt(G: np.ndarray) -> np.ndarray:
    """W with Wᵀ G W = I on G's range (its eigenvalues above 1e-12 of the largest)."""
    if G.size == 0:
        return np.zeros((G.shape[0], 0))
    w, V = np.linalg.eigh(0.5 * (G + G.T))
    keep = w > 1e-12 * max(w.max(), 1e-300)
    out: np.ndarray = V[:, keep] / np.sqrt(w[keep])
    return out


def _gram_canonical(G11, G22, G12, whitened: bool = False) -> float:
    """Largest canonical correlation from the Gram blocks; ``whitened``: G22 is given as its ``_isqrt``."""
    if G11.size == 0 or G22.size == 0:
        return 0.0
    W1, W2 = _isqrt(G11), (G22 if whitened else _isqrt(G22))
    if W1.shape[1] == 0 or W2.shape[1] == 0:
        return 0.0
    return float(min(1.0, np.linalg.svd(W1.T @ G12 @ W2, compute_uv=False).max()))


def fit_base(lin) -> BaseFit:
    """Least squares of z on the base columns (see :class:`BaseFit`), from a :class:`GramProblem`
    or a row-form :class:`Linearization`. Raises ``ObservabilityError`` when a column of the base
    model is (numerically) a combination of the others."""
    if isinstance(lin, Linearization):
        if lin.X.ndim != 2 or lin.z.shape != (lin.X.shape[0],):
            raise InputValueError(f"Linearization: expected z (n,) and X (n, p), got z {lin.z.shape}, X {lin.X.shape}")
        g, _ = gram_problem(lin)
        return BaseFit(g, _unit_columns(g.p, np.arange(g.n_fitted)), dense=lin)
    return BaseFit(lin, _unit_columns(lin.p, np.arange(lin.n_fitted)))


def _unit_columns(n: int, at: np.ndarray) -> np.ndarray:
    """The columns ``at`` of the n × n identity, (n, len(at)), without forming it (n = p ≈ 4 300 at 600 passes)."""
    out = np.zeros((n, at.size))
    out[at, np.arange(at.size)] = 1.0
    return out


@dataclass(frozen=True)
class Extension:
    """The base model extended by candidate columns C (scaled units), from eq (1).

    ``rho`` (k,) canonical correlations of C with the base model (descending);
    ``rank`` the number of separable directions; ``c`` (k,) and ``cov`` (k, k) the estimate
    and its covariance (pseudo-inverse on the separable subspace: directions that are not
    separable are set to 0 and carry no variance — ``rank < k`` says so); ``delta_chi2`` the
    LR statistic with ``rank`` degrees of freedom; ``base_change`` (nb,) how the base
    coefficients move when C is added; ``information`` (k, k) C⊥ᵀC⊥.
    """

    rho: np.ndarray
    rank: int
    c: np.ndarray
    cov: np.ndarray
    delta_chi2: float
    base_change: np.ndarray
    base_cov_after: np.ndarray
    information: np.ndarray
    basis: np.ndarray  # (k, rank) separable directions in parameter space

    @property
    def p_value(self) -> float:
        return float(chi2_sf(self.delta_chi2, self.rank)) if self.rank else 1.0


def _separable_basis(G0: np.ndarray, G1: np.ndarray, rho_max: float):
    """Generalised eigen-decomposition C⊥ᵀC⊥ v = f CᵀC v (G1 = C⊥ᵀC⊥, G0 = CᵀC)
    → (ρ descending, basis of separable v)."""
    k = G0.shape[0]
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


def extend(base: BaseFit, C, rho_max: float = SEPARABILITY_RHO) -> Extension:
    """Fit the base model extended by columns ``C``; see :class:`Extension`. ``C`` is
    :class:`Columns` of the base's problem or, for a row-form base, an array (n, k)."""
    if not isinstance(C, Columns):
        C = np.asarray(C, float)
        if C.ndim == 1:
            C = C[:, None]
        dense = base._dense
        if dense is None:
            raise InputTypeError.expected("extend", "C", "Columns of the base's problem (the base was not built from rows)", C)
        if C.shape[0] != dense.z.shape[0]:
            raise InputValueError(f"extend: C has {C.shape[0]} rows, the model {dense.z.shape[0]}")
        g, Cc = gram_problem(dense, C)
        nf, k = dense.n_fitted, C.shape[1]
        T = np.zeros((g.p, base.T.shape[1]))
        T[:nf] = base.T[:nf]
        T[nf + k :] = base.T[nf:]
        base = BaseFit(g, T, dense)
        C = Cc
    k = C.k
    nf = base.n_fitted
    info = base.perp_gram(C)
    rho, V = _separable_basis(_array(base.lin.raw_gram(C)), info, rho_max)
    if V.shape[1] == 0:
        zero = np.zeros(k)
        return Extension(rho, 0, zero, np.zeros((k, k)), 0.0, np.zeros(nf), base.covariance(), info, V)
    Na = V.T @ info @ V
    cov_a = np.linalg.inv(Na)
    cov_a = 0.5 * (cov_a + cov_a.T)
    g = V.T @ base.perp_score(C)
    a = cov_a @ g
    c = V @ a
    cov = V @ cov_a @ V.T
    dchi2 = float(g @ a)
    B = base.regress(C @ V)  # (nb, r)
    change = -B @ a
    cov_after = base.covariance() + B @ cov_a @ B.T
    return Extension(rho, V.shape[1], c, cov, dchi2, change, cov_after, info, V)


#: a set of more columns than this whose Gram blocks fall apart into small diagonal blocks (the per-pass probes of
#: a campaign of many passes that share no target) is tested through that structure (:func:`lr_test`,
#: ``BaseFit.max_canonical_correlation``), never by a dense eigen-decomposition of its k × k blocks
# DECISION: 400 columns — below it the dense route costs under ~0.1 s and gives the reference numbers; above it
# the k³ eigen-decompositions grew to seconds each (1 800 columns of the ``pass`` probe at 600 passes) and a
# campaign's diagnosis stopped being linear in its passes.
STRUCTURED_MIN_COLUMNS = 400
#: the largest diagonal block the structured route takes (a group's per-pass columns: 3 per pass of the group)
_STRUCTURED_MAX_BLOCK = 64


def _diagonal_blocks(*mats) -> list[np.ndarray] | None:
    """The index sets of the diagonal blocks common to symmetric (k, k) matrices (arrays or sparse): the connected
    components of their joint pattern, or None when a block is larger than ``_STRUCTURED_MAX_BLOCK``."""
    from scipy.sparse.csgraph import connected_components

    k = mats[0].shape[0]
    pattern = sps.csr_matrix((k, k))
    for A in mats:
        pattern = pattern + abs(sps.csr_matrix(A))
    n, label = connected_components(pattern, directed=False)
    order = np.argsort(label, kind="stable")
    bounds = np.searchsorted(label[order], np.arange(n + 1))
    if np.diff(bounds).max(initial=0) > _STRUCTURED_MAX_BLOCK:
        return None
    return [order[bounds[i] : bounds[i + 1]] for i in range(n)]


def _by_size(blocks: list[np.ndarray]):
    """The blocks grouped by size: (size, (n_b, size) index array) pairs, for batched small eigen-decompositions."""
    sizes = np.array([b.size for b in blocks])
    for s in np.unique(sizes):
        yield int(s), np.stack([blocks[i] for i in np.flatnonzero(sizes == s)])


class _BlockLowRank:
    """M = blockdiag(E_b) − YᵀY (k, k) for small symmetric blocks E_b and Y (r, k), r small: the perp Gram C⊥ᵀC⊥ of
    columns C that fall apart into blocks (each on one group's rows) once the base columns X are regressed out
    (Y = L⁻¹ Xᵀ C, L the base's Cholesky factor). Held in the blocks' eigen-coordinates, M' = diag(λ) − ZᵀZ
    (Z = Y Q, Q the blocks' eigenvectors), so every operation below costs O(k r²): the count of eigenvalues below
    a cut (Haynsworth's inertia additivity on the bordered matrix [[E − c, Yᵀ], [Y, I]]:
    #{f < c} = #{λ < c} + #neg(I − Z (Λ − c)⁻¹ Zᵀ)), the eigenvectors of those few (subspace iteration on
    (M' + c)⁻¹, Woodbury, then Rayleigh–Ritz) and solves on the rest (the separable directions)."""

    def __init__(self, E: dict, Y: np.ndarray):
        # E: size -> (idx (n_b, s), blocks (n_b, s, s)) in the columns' order
        k = Y.shape[1]
        self.k = k
        self.lam = np.empty(k)
        self._Q = []
        for s, (idx, Eb) in E.items():
            w, V = np.linalg.eigh(0.5 * (Eb + np.swapaxes(Eb, 1, 2)))
            self.lam[idx] = w
            self._Q.append((idx, V))
        self.Z = self.to_q(Y.T).T  # (r, k)

    def to_q(self, v: np.ndarray) -> np.ndarray:
        """Qᵀ v for v (k, j)."""
        out = np.empty_like(v)
        for idx, V in self._Q:
            out[idx] = np.einsum("bji,bjc->bic", V, v[idx])
        return out

    def count_below(self, c: float) -> int:
        d = self.lam - c
        if np.any(d == 0):
            return -1
        S = np.eye(self.Z.shape[0]) - (self.Z / d) @ self.Z.T
        return int(np.sum(d < 0) + np.sum(np.linalg.eigvalsh(0.5 * (S + S.T)) < 0))

    def _apply(self, X: np.ndarray) -> np.ndarray:
        return self.lam[:, None] * X - self.Z.T @ (self.Z @ X)

    @staticmethod
    def _woodbury(d: np.ndarray, W: np.ndarray, s: np.ndarray, R: np.ndarray) -> np.ndarray:
        """(diag(d) + W diag(s) Wᵀ)⁻¹ R."""
        DR, DW = R / d[:, None], W / d[:, None]
        cap = np.diag(1.0 / s) + W.T @ DW
        return DR - DW @ np.linalg.solve(cap, W.T @ DR)

    def small_space(self, m: int, c: float) -> np.ndarray | None:
        """The eigenvectors of the m smallest eigenvalues of M' (k, m), orthonormal, or None when they do not
        converge to a residual of 1e-13 ‖M'‖ (the caller then takes the dense route)."""
        k, r = self.k, self.Z.shape[0]
        if m == 0:
            return np.zeros((k, 0))
        d = self.lam + c
        if not np.all(d > 0):
            return None
        size = min(k, m + r + 8)
        start = [self.Z.T / d[:, None]] + [_unit_columns(k, np.argsort(self.lam, kind="stable")[: max(size - r, 0)])]
        X = np.linalg.qr(np.concatenate(start, axis=1)[:, :size])[0]
        scale = max(float(np.abs(self.lam).max()), 1e-300)
        sgn = -np.ones(r)
        for _ in range(200):
            X = np.linalg.qr(self._woodbury(d, self.Z.T, sgn, X))[0]
            MX = self._apply(X)
            f, V = np.linalg.eigh(0.5 * (X.T @ MX + MX.T @ X))
            N, MN = X @ V[:, :m], MX @ V[:, :m]
            if np.max(np.linalg.norm(MN - N * f[:m], axis=0)) <= 1e-13 * scale:
                return np.asarray(np.linalg.qr(N)[0])
        return None

    def solve_separable(self, R: np.ndarray, N: np.ndarray, c: float) -> np.ndarray | None:
        """x (k, j) with M' x = R on the complement of N (R's component along N removed), by Woodbury on
        (M' + c + N Nᵀ) and refinement (each step takes a factor c / (f + c) ≤ 1/2 off the error on the separable
        directions); None when the residual does not fall below 1e-13 ‖R‖."""
        R = R - N @ (N.T @ R)
        d = self.lam + c
        if not np.all(d > 0):
            return None
        W = np.concatenate([self.Z.T, N], axis=1)
        s = np.concatenate([-np.ones(self.Z.shape[0]), np.ones(N.shape[1])])
        x = np.zeros_like(R)
        tol = 1e-13 * max(float(np.linalg.norm(R)), 1e-300)
        for _ in range(200):
            res = R - (self._apply(x) + N @ (N.T @ x))
            if float(np.linalg.norm(res)) <= tol:
                return x - N @ (N.T @ x)
            x = x + self._woodbury(d, W, s, res)
        return None


def _block_dict(blocks: list[np.ndarray], *mats) -> list[dict]:
    """For each matrix (k, k): size -> (idx (n_b, s), its diagonal blocks (n_b, s, s))."""
    out: list[dict] = [{} for _ in mats]
    for s, idx in _by_size(blocks):
        for o, A in zip(out, mats):
            if sps.issparse(A):
                o[s] = (idx, _gather(sps.csr_matrix(A), idx))
            else:
                o[s] = (idx, np.asarray(A)[idx[:, :, None], idx[:, None, :]])
    return out


def _gather(A, idx: np.ndarray) -> np.ndarray:
    """The blocks A[idx_b, idx_b] (n_b, s, s) of a sparse matrix, in one vectorised lookup."""
    n_b, s = idx.shape
    rows = np.repeat(idx, s, axis=1).ravel()
    cols = np.tile(idx, (1, s)).ravel()
    return np.asarray(A[rows, cols]).reshape(n_b, s, s)


def _structured_lr(base: "BaseFit", C: Columns, rho_max: float) -> tuple[int, float] | None:
    """(rank, Δχ²) of ``extend(base, C, rho_max)`` through the block structure of C's Gram blocks (see
    ``_BlockLowRank``), or None when C's blocks do not fall apart or a step does not converge.

    The steps mirror ``_separable_basis`` and ``extend``: each diagonal block of CᵀC (raw metric) scaled and
    eigen-decomposed (its directions with no signal dropped at the same 1e-10 of the largest), T its whitening,
    M = Tᵀ C⊥ᵀC⊥ T = blockdiag(Tᵀ D T) − YᵀY whose eigenvalues are the f = 1 − ρ² of ``_separable_basis``; the
    directions with f < 1 − ρ_max² are counted (Haynsworth) and found (subspace iteration), and Δχ² = gᵀ M⁺ g on
    the others, g = Tᵀ C⊥ᵀ r0 — the same quantities, equal to round-off, without a k × k eigen-decomposition."""
    R = base.lin.raw_gram(C)
    D = base.lin.quad(C.T)
    blocks = _diagonal_blocks(R, D)
    if blocks is None:
        return None
    Rb, Db = _block_dict(blocks, R, D)
    U = base.cross(C)
    Y0 = linalg.solve_triangular(base.L, base.col_scale[:, None] * U, lower=True)
    g = base.perp_score(C)
    # T: each block's raw Gram scaled and whitened (``_separable_basis``'s T), its directions kept at 1e-10 of the
    # largest eigenvalue of all blocks
    whit = {}
    wmax = 0.0
    for s, (idx, Rk) in Rb.items():
        sc = np.sqrt(np.clip(np.einsum("bii->bi", Rk), 0, None))
        live = sc > 1e-300
        Sinv = np.where(live, 1.0 / np.where(live, sc, 1.0), 0.0)
        G0s = Rk * Sinv[:, :, None] * Sinv[:, None, :]
        G0s = np.where(live[:, :, None] & live[:, None, :], G0s, 0.0)
        w0, V0 = np.linalg.eigh(G0s)  # a column without signal: a zero row and column, a zero eigenvalue
        whit[s] = (Sinv, live, w0, V0)
        wmax = max(wmax, float(w0.max(initial=0.0)))
    if not wmax > 0:
        return 0, 0.0
    E_T: dict = {}
    Y_T, g_T = [], []
    pos = 0
    for s, (idx, Dk) in Db.items():
        Sinv, live, w0, V0 = whit[s]
        keep = w0 > 1e-10 * wmax
        for b in range(idx.shape[0]):
            kb = keep[b]
            Tb = Sinv[b][:, None] * V0[b][:, kb] / np.sqrt(w0[b][kb])
            Eb = Tb.T @ Dk[b] @ Tb
            n = Tb.shape[1]
            if n:
                E_T.setdefault(n, ([], []))
                E_T[n][0].append(np.arange(pos, pos + n))
                E_T[n][1].append(Eb)
                Y_T.append(Y0[:, idx[b]] @ Tb)
                g_T.append(Tb.T @ g[idx[b]])
                pos += n
    if pos == 0:
        return 0, 0.0
    lr = _BlockLowRank({n: (np.stack(i), np.stack(e)) for n, (i, e) in E_T.items()}, np.concatenate(Y_T, axis=1))
    c = 1.0 - rho_max**2
    m = lr.count_below(c)
    if m < 0:
        return None
    N = lr.small_space(m, c)
    if N is None:
        return None
    gq = lr.to_q(np.concatenate(g_T)[:, None])
    x = lr.solve_separable(gq, N, c)
    if x is None:
        return None
    h = gq - N @ (N.T @ gq)
    return pos - m, float((h.T @ x)[0, 0]) if pos > m else 0.0


def lr_test(base: "BaseFit", C: Columns, rho_max: float = SEPARABILITY_RHO) -> tuple[int, float]:
    """(rank, Δχ²) of the base model extended by C: ``extend(base, C, rho_max)``'s separable rank and LR
    statistic, through the block structure when C has more than ``STRUCTURED_MIN_COLUMNS`` columns whose Gram
    falls apart into small blocks (``_structured_lr``), else by ``extend``."""
    if C.k > STRUCTURED_MIN_COLUMNS:
        out = _structured_lr(base, C, rho_max)
        if out is not None:
            return out
    ext = extend(base, C, rho_max)
    return ext.rank, ext.delta_chi2


def max_canonical_correlation(A: np.ndarray, B: np.ndarray) -> float:
    """Largest canonical correlation between the column spaces of A (n, a) and B (n, b) (from
    their Gram blocks, as ``BaseFit.max_canonical_correlation``).

    >>> t = np.linspace(0, 1, 50)
    >>> round(max_canonical_correlation(np.c_[t, t**2], np.c_[2 * t + 3 * t**2]), 6)
    1.0
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    if A.shape[1] == 0 or B.shape[1] == 0:
        return 0.0
    return _gram_canonical(A.T @ A, B.T @ B, A.T @ B)


#: the public names of the separability rule's algebra on Gram blocks (the line-scan diagnosis calls them on its
#: reduced information, ``discrepancy.line_scan``)
separable_basis = _separable_basis
canonical_correlation = _gram_canonical
