"""Will ``boresight.diagnose`` *name* an effect of a given size? The probability that the one naming
rule (:mod:`.rule`) names it, and the **nameable size**: the size at which it does so with the stated
power. One model, two users: the diagnosis' identifiability step (``naming.identifiability``: the
``min_nameable`` size it reports beside ``min_detectable``) and the campaign planner
(``boresight.studies.planning.naming``: the requirement η ≤ 1), so it sits below both.

Detectability (the LR test at α/K *and* BIC have the stated power: ``rule.nameable_noncentrality``)
is necessary but not sufficient: the diagnosis names e only if (``naming.naming_rounds``,
``docs/discrepancy.md``)

1. e is **separable**: in the base model (θ + the nuisances, shared errors as columns with a
   prior row) every direction of e keeps a fraction 1 − ρ² ≥ 1 − ρ_max² of its signal, ρ the
   canonical correlations, ρ_max = ``linear.SEPARABILITY_RHO``; otherwise e is not
   tested at all (or only on its separable subspace);
2. its LR statistic Δχ²_e passes Holm's first step at α/K **and** ΔBIC < 0 (Δχ²_e > k ln n,
   n the whitened data rows) — the one rule of :mod:`.rule`, whose ``critical_value`` this model calls;
3. no other significant candidate f is an *alternative*: e and f are ``ambiguous`` when
   ΔlogL = ½(Δχ²_e − Δχ²_f) < 2 (``AMBIGUITY_DLOGL``) or e adds nothing significant (p > α)
   once f is in the model.

Everything is a quadratic form of the whitened residual, so it is predicted from the information
of the effects given θ and the nuisances (linear-Gaussian model, first order; derivations below):
``nameable_sizes`` takes it as S (effects × effects, θ and the nuisances eliminated) with R, the same
columns' information with only the per-image errors eliminated. The diagnosis has both on its own
data (``BaseFit.perp_gram``, ``raw_gram``); the planner forms them from each campaign's summed
Fisher blocks (``planning.naming.naming_scores``).

**Separability (1).** Let R = Xᵀ D⁻¹ X be the information of [θ, effects] with only the
per-image errors in D (the whitening of ``discrepancy.campaign``; the shared per-pass and
catalogue errors are the base model's nuisance columns), and S_ee the information of e given θ
with every nuisance marginalised (the Schur complement of the plan's block I over θ). Then
C_eᵀC_e = R_ee and C⊥ᵀC⊥ = S_ee, so the canonical correlations are ρ_i² = 1 − f_i with f_i the
generalised eigenvalues of S_ee v = f R_ee v. Both R and I are sums over passes, so the planner
keeps one R block per option beside the I block. Required: min f ≥ 1 − ρ_max² (e tested with
its full rank, as the detection model assumes). A rival f enters the diagnosis' pool only if at
least one of its directions is separable (max f ≥ 1 − ρ_max²).

**Detection (2).** Δχ²_e ~ χ²(k, λ_e), λ_e = pᵀ (P_ee)⁻¹ p with the required effects floated
(conservative: in the first round the others are not in the model); P_det = P(χ²(k, λ_e) >
max(χ²_{1−α/K}(k), k ln n)).

**Ambiguity (3).** With e hidden at δ = t p (t the multiple of the required size), let
S = [[S_ee, S_ef], [S_fe, S_ff]] be the information of (e, f) given θ and the nuisances. In the
whitened space y = Qᵀ r₀ ~ N(μ, E) on the span of both effects' projected columns, μ = the
projected signal of e; Δχ²_e = yᵀ P_e y, Δχ²_f = yᵀ P_f y. The difference D = yᵀ (P_e − P_f) y
has, with P_e μ = μ,

    E[D]   = k_e − k_f + λ_sep,               λ_sep = δᵀ (S_ee − S_ef S_ff⁻¹ S_fe) δ = ‖(E − P_f) μ‖²
    Var[D] = 2 tr (P_e − P_f)² + 4 μᵀ (P_e − P_f)² μ = 2 (k_e + k_f − 2 Σκ²) + 4 λ_sep

(Σκ² = tr(S_ee⁻¹ S_ef S_ff⁻¹ S_fe), the squared canonical correlations between e and f given
the base; for k_e = k_f = 1 this is the exact variance of y_e² − y_f², 4(1 − κ² + λ_sep)).
λ_sep is what f's best fit to e's signature leaves. We take D ≈ N(E, Var): P(ΔlogL ≥ 2) =
Φ((E[D] − 4)/√Var[D]). The second leg, "e adds something once f is in", is the LR test of e in
the model base + f: χ²(k_e, λ_sep) > χ²_{1−α}(k_e). Both events are driven by the same
component of y (e's signal orthogonal to f), so P(not ambiguous via f) is taken as the smaller
of the two; and f only matters when it is itself significant at α/K (Δχ²_f ~ χ²(k_f, λ_f),
λ_f = δᵀ S_ef S_ff⁻¹ S_fe δ, its share of e's signal), so the chance that f makes the pair
ambiguous is bounded by min(1 − P(not ambiguous), P(f significant)).

**The naming probability** at size t p is then

    P_name(t) = 1[separable] · P_det(t) · Π_f (1 − min(P(f ambiguous with e), P(f significant)))

(independence across rivals assumed; the events share e's own noise, which makes the product
conservative in the usual case). The **nameable size** of e is η p with η the smallest t with
P_name(t) ≥ power (bisection in log t, from the detection-only size — P_name ≤ P_det — up to
``SPAN`` = 64 times it; a campaign that needs more is "not nameable", η = inf: a rival's
signature then practically contains e's); the planner's requirement is η ≤ 1, the diagnosis reports η p as ``min_nameable``.
``tests/studies/test_planning_mc.py`` and ``tests/studies/test_discrepancy_naming.py`` compare the predicted
P_name with the rate at which ``boresight.diagnose`` names the effect in simulated campaigns (binomial intervals).

Not modelled (limits, ``docs/planning.md``): a rival with more degrees of freedom than e can
rank ahead of e by p-value while Δχ²_e > Δχ²_f (only for multi-parameter e); a partially
separable rival is treated with its full rank; the physical-range rejection and the withdrawal
of names explained by unexplained structure (neither acts on a correctly modelled campaign).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import special

from boresight.stats import chi2_isf, ncx2_sf
from boresight.studies.discrepancy.rule import NamingRule

__all__ = ["NamingRule", "NcxSf", "canonical_fractions", "detection_only_size", "nameable_sizes", "theta_schur"]

#: the nameable size is searched up to SPAN times the detection-only size; beyond, "not nameable"
SPAN = 64.0
#: ridge (relative to the diagonal) for the small solves of nearly singular effect blocks
_RIDGE = 1e-12


# NamingRule and the threshold max(χ²_{1−α/K}(k), k ln n) are the rule's (``boresight.studies.discrepancy.rule``).


_GRID_POINTS = 4001


@lru_cache(maxsize=4096)
def _sf_row(k: int, crit: float):
    top = max(400.0, 4.0 * crit + 200.0)
    lam = np.linspace(0.0, top, _GRID_POINTS)
    return top, ncx2_sf(crit, k, np.maximum(lam, 1e-12))


class NcxSf:
    """P(χ²(k, λ) > crit_c) for a fixed set of critical values crit (C,), as a function of λ (C,):
    cached tables of 4 001 points in λ up to 4·crit + 200 (1 beyond) on a grid of crit with step
    0.5, interpolated linearly in λ and in crit. Accurate to ~3e-4 in probability (tested
    against ``scipy.stats.ncx2``). A critical value equal to ``exact`` (the LR leg's threshold,
    the same for every campaign the BIC leg does not bind) has its own table, not interpolated
    in crit.

    DECISION: each value's probability depends on its own critical value only, never on the
    other values of the batch (an earlier version used one exact table whenever a whole batch
    shared one critical value): a campaign scores the same in any batch, which is what makes
    the search's lower bound of η exact (``LOWER_BOUND_SLACK``).

    >>> float(np.round(NcxSf(1, np.array([3.841]))(np.array([7.85]))[0], 3))
    0.8
    """

    STEP = 0.5

    def __init__(self, k: int, crit, exact: float | None = None):
        crit = np.atleast_1d(np.asarray(crit, float))
        at = np.zeros(crit.shape, bool) if exact is None else crit == float(exact)
        lo = np.floor(crit / self.STEP) * self.STEP
        self.u = np.where(at, 0.0, (crit - lo) / self.STEP)
        self.single = bool(at.all())  # one exact table: no interpolation in crit
        first, second = np.where(at, crit, lo), np.where(at, crit, lo + self.STEP)
        nodes, inv = np.unique(np.concatenate([first, second]), return_inverse=True)
        rows = [_sf_row(int(k), float(c)) for c in nodes]
        top = np.array([r[0] for r in rows])
        self.table = np.stack([r[1] for r in rows]).ravel()
        n = crit.size
        self.rows = (inv[:n], inv[n:])
        self.tops = (top[inv[:n]], top[inv[n:]])

    def _row(self, lam, row, top):
        x = np.clip(lam / top, 0.0, 1.0) * (_GRID_POINTS - 1)
        i = np.minimum(x.astype(np.int64), _GRID_POINTS - 2)
        j = i + row * _GRID_POINTS
        v = self.table[j] + (x - i) * (self.table[j + 1] - self.table[j])
        return np.where(lam >= top, 1.0, v)

    def __call__(self, lam) -> np.ndarray:
        lam = np.asarray(lam, float)
        a = self._row(lam, self.rows[0], self.tops[0])
        if self.single:
            return a
        b = self._row(lam, self.rows[1], self.tops[1])
        return a + self.u * (b - a)

    def inverse(self, p: float) -> np.ndarray:
        """λ (C,) at which the probability reaches p (bisection on the interpolated tables)."""
        lo = np.zeros(self.u.shape)
        hi = np.maximum(self.tops[0], self.tops[1])
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            up = self(mid) >= p
            hi = np.where(up, mid, hi)
            lo = np.where(up, lo, mid)
        return hi


def _exact_sf(k: int, crit: float) -> NcxSf:
    """The tail table of one critical value, exact in crit."""
    return NcxSf(k, [crit], exact=crit)


def _solve(A, B):
    d = np.sqrt(np.clip(np.abs(np.diagonal(A, axis1=-2, axis2=-1)), 1e-300, None))
    As = A / (d[..., :, None] * d[..., None, :]) + _RIDGE * np.eye(A.shape[-1])
    return np.linalg.solve(As, B / d[..., :, None]) / d[..., :, None]


def theta_schur(info: np.ndarray) -> np.ndarray:
    """Information (C, P−3, P−3) of the effect parameters given θ (the first three), every
    nuisance already marginalised in ``info`` (C, P, P)."""
    Itt, Ite, Iee = info[..., :3, :3], info[..., :3, 3:], info[..., 3:, 3:]
    S = Iee - np.swapaxes(Ite, -1, -2) @ _solve(Itt, Ite)
    return 0.5 * (S + np.swapaxes(S, -1, -2))


def canonical_fractions(S_ee: np.ndarray, R_ee: np.ndarray) -> np.ndarray:
    """f (C, k) ascending: generalised eigenvalues of S v = f R v, i.e. 1 − ρ² per canonical
    direction (ρ the canonical correlation of the effect with the base model)."""
    d = np.sqrt(np.clip(np.diagonal(R_ee, axis1=-2, axis2=-1), 1e-300, None))
    Rs = R_ee / (d[..., :, None] * d[..., None, :]) + _RIDGE * np.eye(R_ee.shape[-1])
    Ss = S_ee / (d[..., :, None] * d[..., None, :])
    L = np.linalg.cholesky(Rs)
    A = np.linalg.solve(L, np.swapaxes(np.linalg.solve(L, Ss), -1, -2))
    return np.clip(np.linalg.eigvalsh(0.5 * (A + np.swapaxes(A, -1, -2))), 0.0, 1.0)


@dataclass
class _Rival:
    lam_sep: np.ndarray  # (C,) at t = 1
    lam_f: np.ndarray  # (C,) at t = 1
    kf: int
    ke: int
    kappa2: np.ndarray  # (C,)
    live: np.ndarray  # (C,) bool: f is in the diagnosis' pool
    charge: np.ndarray | float = 0.0  # 2 ln B: a scanned rival's Δχ² is the best of B (``naming._selected_delta_chi2``)


def _rival_terms(S, es, fs, p, f_live) -> _Rival:
    See, Sef, Sff = S[..., es, es], S[..., es, fs], S[..., fs, fs]
    Sfe = np.swapaxes(Sef, -1, -2)
    X = _solve(Sff, Sfe)  # S_ff⁻¹ S_fe (C, kf, ke)
    proj = Sef @ X  # S_ef S_ff⁻¹ S_fe
    lam_f = np.einsum("...i,...ij,...j->...", p, proj, p)
    lam_e = np.einsum("...i,...ij,...j->...", p, See, p)
    kappa2 = np.trace(_solve(See, proj), axis1=-2, axis2=-1)
    ke, kf = See.shape[-1], Sff.shape[-1]
    kappa2 = np.clip(kappa2, 0.0, min(ke, kf))
    return _Rival(lam_sep=np.maximum(lam_e - lam_f, 0.0), lam_f=np.maximum(lam_f, 0.0), kf=kf, ke=ke, kappa2=kappa2, live=f_live)


def _p_ok(t2, rv, extra_sf, rule):
    """P(e is not made ambiguous by f | f significant): ΔlogL ≥ margin (normal D) and e adds
    something at α once f is in (χ²(k_e, λ_sep)), the smaller of the two."""
    ls = t2 * rv.lam_sep
    mean = rv.ke - rv.kf + ls + rv.charge
    var = np.maximum(2.0 * (rv.ke + rv.kf - 2.0 * rv.kappa2) + 4.0 * ls, 1e-12)
    p_d = special.ndtr((mean - 2.0 * rule.dlogl) / np.sqrt(var))
    return np.minimum(p_d, extra_sf(ls))


def _sig_sf(rv: _Rival, rule: NamingRule, scan) -> NcxSf:
    """P(f significant) as a function of λ_f: at the rule's level, or for a scanned rival of B (C,)
    boundaries at level/B with its Δχ² charged 2 ln B (set on ``rv``: the diagnosis' Bonferroni over the scan)."""
    if scan is None:
        return _exact_sf(rv.kf, chi2_isf(rule.level, rv.kf))
    B = np.maximum(np.asarray(scan, float), 1.0)
    rv.charge = 2.0 * np.log(B)
    return NcxSf(rv.kf, chi2_isf(rule.level / B, rv.kf))


def _p_name(t2, lam_det, det_sf, rivals, rule, separable):
    """P_name at t² (module docstring); ``rivals``: (terms, P(e|f) table, P(f significant) table)."""
    p = det_sf(t2 * lam_det)
    for rv, extra_sf, sig_sf in rivals:
        p_sig = sig_sf(t2 * rv.lam_f)
        p = p * np.where(rv.live, 1.0 - np.minimum(1.0 - _p_ok(t2, rv, extra_sf, rule), p_sig), 1.0)
    return np.where(separable, p, 0.0)


def detection_only_size(lam_det, n_rows, ke: int, rule: "NamingRule"):
    """The size t_det (multiple of the required size) at which an effect of ``ke`` parameters with
    non-centrality ``lam_det`` (C,) at the required size is *detected* with the stated power by
    the diagnosis' test (χ² at α/K and BIC with ``n_rows`` (C,) rows), and that test's tail table.

    Naming needs at least detection (P_name ≤ P_det), so η ≥ t_det / ``LOWER_BOUND_SLACK``: the
    planner's search bound (``planning.search``) and the start of η's bisection (``nameable_sizes``).
    """
    # the diagnosis' rule (discrepancy/rule.py); the LR leg's threshold has its own exact table
    det_sf = NcxSf(ke, rule.critical_value(ke, n_rows), exact=chi2_isf(rule.level, ke))
    lam_det = np.asarray(lam_det, float)
    return np.sqrt(det_sf.inverse(rule.power) / np.maximum(lam_det, 1e-300)), det_sf


#: η ≥ t_det / LOWER_BOUND_SLACK. P_name(t) ≤ P_det(t) on the same table (``NcxSf`` gives every
#: campaign the table of its own critical value, whatever batch it is scored in), so η — the upper
#: end of a bisection bracketing P_name's crossing — is ≥ the crossing of P_det, and t_det (the
#: upper end of a 40-step bisection of the table, ≤ 1e-10 relative above that crossing) is within
#: round-off of it. The slack covers that and the round-off of λ (≤ 1e-12 relative: the search's
#: bounds and its full scores invert the same summed matrices), a million times over. (It was
#: 1.05 × 1.02 while a batch of one critical value used an exact table and others interpolated
#: ones: then the bound missed 7 % and the search scored ~3× more campaigns in full.)
LOWER_BOUND_SLACK = 1.0 + 1e-6


def nameable_sizes(
    S, raw, n_rows, effect_slices, required, lam_joint, rival_slices, rule: NamingRule, iterations: int = 20, scan_sizes=None
):
    """Nameability of each required effect in C campaigns (module docstring).

    ``S`` (C, Q, Q) the information of the effects (required effects and look-alikes) given θ and
    every nuisance; ``raw`` (C, Q, Q) the same columns' information with only the per-image errors
    marginalised (only its diagonal blocks, each effect's own, are read); ``n_rows`` (C,) whitened
    data rows; ``effect_slices``/``required`` the required effects (slices into S) and their sizes ((k,), or
    (C, k): one per campaign — the diagnosis scores each parameter of an effect as a campaign of its own);
    ``lam_joint`` (C, E) the detection non-centrality of each at its required size with the
    required effects floated; ``rival_slices`` every effect's slice (required and look-alikes);
    ``scan_sizes`` (optional, one entry per rival: None or B (C,)) a scanned rival's number of boundaries B:
    as in the diagnosis (``naming.naming_rounds``) it is significant at level/B and its Δχ² is charged 2 ln B.

    Returns (η (C, E) nameable size / required size — inf when not separable; P_name (C, E)
    at the required size; ρ (C, E) the largest canonical correlation of each required effect
    with the base model; the binding rival (C, E) index into ``rival_slices`` or −1).
    """
    C = S.shape[0]
    fr = {}
    for k, sl in enumerate(rival_slices):
        fr[k] = canonical_fractions(S[..., sl, sl], raw[..., sl, sl])
    floor = 1.0 - rule.rho_max**2
    live = {k: v[..., -1] >= floor for k, v in fr.items()}
    E = len(effect_slices)
    eta = np.full((C, E), np.inf)
    pname = np.zeros((C, E))
    rho = np.ones((C, E))
    binding = np.full((C, E), -1)
    for j, (sl, p) in enumerate(zip(effect_slices, required)):
        ke = sl.stop - sl.start
        me = [k for k, r in enumerate(rival_slices) if r == sl]
        fe = fr[me[0]] if me else canonical_fractions(S[..., sl, sl], raw[..., sl, sl])
        rho[:, j] = np.sqrt(1.0 - fe[..., 0])
        separable = fe[..., 0] >= floor
        rivals = [(k, _rival_terms(S, sl, r, p, live[k])) for k, r in enumerate(rival_slices) if r != sl]
        lam_det = np.asarray(lam_joint[:, j], float)
        t_det, det_sf = detection_only_size(lam_det, n_rows, ke, rule)
        extra_sf = _exact_sf(ke, chi2_isf(rule.alpha, ke))
        rv = [(r, extra_sf, _sig_sf(r, rule, None if scan_sizes is None else scan_sizes[k])) for k, r in rivals]
        pname[:, j] = _p_name(1.0, lam_det, det_sf, rv, rule, separable)
        # η: smallest t with P_name(t) ≥ power, by bisection in log t between the detection-only
        # size (P_name ≤ P_det) and SPAN times it (beyond: "not nameable", η = inf)
        lo = np.log(np.maximum(t_det, 1e-300)) - np.log(1.05)  # the table inversion is good to < 1 % in λ
        hi = lo + np.log(SPAN)
        ok_hi = _p_name(np.exp(2 * hi), lam_det, det_sf, rv, rule, separable) >= rule.power
        # after a few steps, a rival whose factor stays above 1 − 1e-9 over the remaining bracket
        # cannot move η: it is left out of the rest (its factor there is bounded by
        # min(1 − P_ok(t_lo), P_sig(t_hi)))
        keep = rv
        for it in range(iterations):
            if it == 6:
                keep = [
                    x
                    for x in rv
                    if np.any(
                        np.minimum(1.0 - _p_ok(np.exp(2 * lo), x[0], x[1], rule), x[2](np.exp(2 * hi) * x[0].lam_f))[x[0].live]
                        > 1e-9
                    )
                ]
            mid = 0.5 * (lo + hi)
            good = _p_name(np.exp(2 * mid), lam_det, det_sf, keep, rule, separable) >= rule.power
            hi = np.where(good, mid, hi)
            lo = np.where(good, lo, mid)
        eta[:, j] = np.where(ok_hi & separable, np.exp(hi), np.inf)
        # the binding rival: the one whose factor is smallest at the nameable size
        if rivals:
            t2 = np.where(np.isfinite(eta[:, j]), eta[:, j] ** 2, 1.0)
            one = lambda lam: np.ones_like(lam)  # noqa: E731
            factors = np.stack([_p_name(t2, np.zeros(C), one, [x], rule, np.ones(C, bool)) for x in rv], axis=-1)
            worst = np.argmin(factors, axis=-1)
            ids = np.array([k for k, _ in rivals])
            binding[:, j] = np.where(np.min(factors, axis=-1) < 1.0 - 1e-6, ids[worst], -1)
    return eta, pname, rho, binding
