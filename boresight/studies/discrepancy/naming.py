"""Steps 3–5 of the diagnosis (``workflow``'s docstring): identifiability of every candidate on this
data (``identifiability``), naming by the one rule of :mod:`.rule` (``naming_rounds``), and the withdrawal
of a name the unexplained structure can question (``withdraw``, ``leftover*``)."""

from __future__ import annotations

import numpy as np
from scipy import stats

from boresight.studies.discrepancy.linear import (
    SEPARABILITY_RHO,
    Columns,
    extend,
    lr_test,
)
from boresight.studies.discrepancy.result import scalar_or_list
from boresight.studies.discrepancy.rule import (
    AMBIGUITY_DLOGL,
    NAMED,
    NOT_DECISIVE,
    NamingRule,
    bic_threshold,
    classify,
    more_data_factor,
    nameable_noncentrality,
)
from boresight.studies.discrepancy.state import State, named_scales
from boresight.studies.discrepancy.structure import holm_rejections
from orbits.errors import BoresightError

#: a named value this many σ outside the physical range rejects the candidate
RANGE_SIGMAS = 3.0


def identifiability(st: State, names, alpha, power):
    """Step 3: one entry per candidate (status, σ, correlations, minimum detectable size)."""
    cl, bf = st.cl, st.base
    problem = st.problem
    ok = [n for n in names if cl.status.get(n) == "ok"]
    K = max(1, len(ok))
    level = alpha / K
    entries, not_sep, exts = [], [], {}
    blocks = {}
    for n in names:
        c = problem.candidates[n]
        k = c.n_params
        e = {
            "effect": n,
            "parameters": list(c.param_names),
            "unit": list(c.units),
            "status": None,
            "marginal_sigma": None,
            "max_corr_theta": None,
            "max_corr_candidates": {},
            "confounded_with": [],
            "min_detectable": None,
            "min_nameable": None,
            "nameable_rival": None,
            "level": level,
            "power": power,
            "typical_size": None,
            "separable_rank": 0,
        }
        if cl.status.get(n) != "ok":
            e["status"] = "needs velocity" if "velocity" in str(cl.status.get(n)) else str(cl.status.get(n))
            how = (
                "provide the spacecraft velocity (columns v_x v_y v_z) to test it"
                if "velocity" in str(cl.status.get(n))
                else "not testable"
            )
            e["reason"] = f"{n}: {cl.status.get(n)}; {how}"
            entries.append(e)
            continue
        C, at, B, ext = best_block(problem, bf, cl, n)
        sc = cl.scales[n][:k]
        blocks[n] = C
        if at is not None:
            # a scanned boundary: its best block, quoted at the level corrected over the B values scanned
            e["scan"] = {"parameter": c.extra["scan"], "best": float(at), "values_scanned": B}
        e["typical_size"] = [float(v) for v in sc]
        exts[n] = ext
        info = ext.information
        try:
            cov_full = np.linalg.inv(info)
            sig = np.sqrt(np.clip(np.diag(cov_full), 0, None)) * sc
        except np.linalg.LinAlgError:
            sig = np.full(k, np.inf)
        if ext.rank < k:
            # a direction the base model absorbs: its σ is not determined by the data
            sig = np.where(np.diag(info) > 0, sig, np.inf)
        e["marginal_sigma"] = [float(v) for v in sig]
        # correlation with θ in the joint fit [θ, named, nuisance, c]
        e["max_corr_theta"] = 1.0 if ext.rank < k else _max_corr_theta(bf, C, ext, st.nb)
        # the one naming rule (rule.py): LR at α/K *and* BIC, so a multi-parameter effect at this
        # size is named with the stated power, not only detected
        lam = nameable_noncentrality(max(ext.rank, 1), level / B, cl.lin.n_data, power)
        Fd = np.diag(info)
        mde = np.where(Fd > 0, np.sqrt(lam / np.where(Fd > 0, Fd, 1.0)) * sc, np.inf)
        if ext.rank < k:
            mde = np.where(np.isfinite(sig), mde, np.inf)
        e["min_detectable"] = [float(v) for v in mde]
        e["separable_rank"] = int(ext.rank)
        e["canonical_corr_base"] = [float(v) for v in ext.rho]
        rng = np.asarray(c.physical_range, float)
        reach = np.max(np.abs(rng), axis=1)
        undetectable = bool(np.all(mde > reach))
        if ext.rank == 0 or undetectable:
            e["status"] = "not_separable"
            e["reason"] = (
                f"every direction is absorbed by θ and the model's other parameters (canonical correlation > {SEPARABILITY_RHO})"
                if ext.rank == 0
                else "the smallest detectable size lies outside the physical range"
            )
            B = bf.regress(C)[: st.nb] * st.to_display  # θ shift per unit of scaled parameter, i.e. at the typical size
            j = int(np.argmax(np.linalg.norm(B, axis=0)))
            not_sep.append(
                {
                    "effect": n,
                    "theta_shift_arcsec": [float(v) for v in B[:, j]],
                    "would_separate": c.separated_by or "data over which this effect varies differently from θ",
                }
            )
        else:
            e["status"] = "separable" if ext.rank == k else "partially separable"
        entries.append(e)
    _correlations(problem, bf, cl, entries, ok, blocks)
    _nameable(st, entries, exts, blocks, alpha, power)
    return entries, not_sep, exts


#: bisection steps of the nameable size in log t over its bracket (ln(64 · 1.05) = 4.2): 4.2 / 2¹⁴ = 2.6e-4
#: relative, below the accuracy of the tabulated tails it inverts (~3e-4 in probability).
# DECISION: 14, not the planner's 20: the sizes move by < 3e-4 relative (measured on the catalogue test
# campaign) and the step's cost, ~0.1 s of a 0.25 s diagnosis there, drops by a third.
NAMEABLE_BISECTION_STEPS = 14


def _nameable(st: State, entries, exts, blocks, alpha, power) -> None:
    """Each tested candidate's ``min_nameable`` (per parameter, effect units): the size at which the
    naming step *names* it with the stated power — detected by the rule (``min_detectable``) and not
    made ambiguous by another candidate that explains the data about as well; inf when not within
    ``naming_power.SPAN`` (64) times the detectable size — and ``nameable_rival`` (per parameter: the
    candidate that binds; for an infinite size the first of ``confounded_with`` when there is one; or None).

    The one naming model (``naming_power.nameable_sizes``, the planner's too) on this data: S the
    information of every tested candidate's separable directions (``Extension.basis``; a scanned
    candidate's best block) given θ, the named effects and the nuisances (``BaseFit.perp_gram``), R the
    same columns' per-row-whitened information (``raw_gram``), every other tested candidate a rival.
    Parameter j of e at unit (scaled) size has coordinates a_j = (VᵀFV)⁻¹VᵀF e_j on e's separable basis
    V (F = C⊥ᵀC⊥; a_j = V⁻¹e_j when e is separable in full): its signal's projection on what the test
    of e sees. Naming needs detection, so the size is never below ``min_detectable``
    (``nameable_sizes`` inverts tabulated tails, good to ~3e-4 in probability).

    DECISION: the level of a scanned candidate's test is α/K/B (``best_block``) for the detection leg
    and, in the model, for its rivals' significance too (the model has one level): slightly optimistic
    for ``alignment_step`` alone. A scanned rival is taken at its best block without the 2 ln B charge of
    the ambiguity test, which makes it a stronger rival than it is: conservative."""
    from boresight.studies.discrepancy.naming_power import nameable_sizes

    cl, bf = st.cl, st.base
    tested = [e for e in entries if e["effect"] in exts and exts[e["effect"]].rank > 0]
    if not tested:
        return
    names = [e["effect"] for e in tested]
    cols = [blocks[n] @ exts[n].basis for n in names]
    Call = Columns.concat(cols)
    S = bf.perp_gram(Call)[None]
    R = cl.lin.raw_gram(Call)
    R = (R.toarray() if hasattr(R, "toarray") else np.asarray(R))[None]
    at = np.cumsum([0] + [c.k for c in cols])
    slices = [slice(int(at[i]), int(at[i + 1])) for i in range(len(names))]
    n_rows = float(cl.lin.n_data)
    for i, e in enumerate(tested):
        ext = exts[e["effect"]]
        V, F = ext.basis, ext.information
        k = F.shape[0]
        A = np.linalg.solve(V.T @ F @ V, V.T @ F)  # (rank, k): column j is a_j
        B = e.get("scan", {}).get("values_scanned", 1)
        rule = NamingRule.from_diagnose(e["level"] / B, alpha, power)
        lam = np.einsum("ij,ik,kj->j", A, V.T @ F @ V, A)[:, None]
        # the k parameters as k "campaigns" of one required effect each (one batched call)
        eta, _, _, binding = nameable_sizes(
            np.broadcast_to(S, (k,) + S.shape[1:]),
            np.broadcast_to(R, (k,) + R.shape[1:]),
            np.full(k, n_rows),
            [slices[i]],
            [A.T],
            lam,
            slices,
            rule,
            iterations=NAMEABLE_BISECTION_STEPS,
        )
        sc = np.asarray(e["typical_size"], float)
        size = np.maximum(eta[:, 0] * sc, np.asarray(e["min_detectable"], float))
        e["min_nameable"] = [float(v) for v in size]
        # not nameable within SPAN times the detectable size: a candidate it cannot be told from
        # (``confounded_with``) is the reason where there is one (the model's binding rival is then taken
        # at the typical size, where it means little)
        never = (e.get("confounded_with") or [None])[0]
        e["nameable_rival"] = [
            (never or (names[b] if b >= 0 else None)) if not np.isfinite(v) else (names[b] if b >= 0 else None)
            for b, v in zip(binding[:, 0], size)
        ]


def _correlations(problem, bf, cl, entries, ok, blocks) -> None:
    """Each testable candidate's largest canonical correlation with every other (``blocks``: its
    columns, a scanned one's best block), the candidates it cannot be told from (``confounded_with``:
    correlation above ``SEPARABILITY_RHO``) and its correlation with the look-alikes its definition names."""
    for e in entries:
        n = e["effect"]
        if n not in ok:
            continue
        for m in ok:
            if m != n:
                e["max_corr_candidates"][m] = bf.max_canonical_correlation(blocks[n], blocks[m])
        # DECISION: ``status`` is separability from the base model (θ and the nuisances); two candidates
        # can each be separable from it and not from each other (a radial GNSS bias and a landmark height
        # bias both lift the scene: canonical correlation 1.000 on the test campaign). The same cut as
        # against the base model names them here, so a status is never read against a correlation of 1;
        # if the data call for one of them, the naming step's ambiguity test (ΔlogL of the single fits)
        # decides whether the data can say which.
        e["confounded_with"] = [m for m, r in e["max_corr_candidates"].items() if r > SEPARABILITY_RHO]
        # the look-alikes its definition names: catalogue effects, or a generic pattern of the
        # residual probes (a per-pass star-tracker bias is a rotation per pass: the "pass" probe)
        la = {}
        for m in problem.candidates[n].extra.get("look_alikes", ()):
            if m in e["max_corr_candidates"]:
                la[m] = e["max_corr_candidates"][m]
            elif LOOK_ALIKE_PROBES.get(m) in cl.probes:
                la[m] = bf.max_canonical_correlation(blocks[n], cl.probes[LOOK_ALIKE_PROBES[m]])
        if la:
            e["look_alikes"] = la


#: look-alikes that are not catalogue effects, tested through the residual probe that spans them
LOOK_ALIKE_PROBES = {"per-pass star-tracker bias": "pass"}


def _max_corr_theta(bf, C, ext, nb=3) -> float:
    """Largest |correlation| between a candidate parameter and a θ component in the joint fit
    [base, C], from the bordered inverse: cov(c) = F⁻¹ (F = C⊥ᵀC⊥), cov(θ, c) = −B_θ F⁻¹,
    cov(θ) = cov₀(θ) + B_θ F⁻¹ B_θᵀ, with B = (XᵀX)⁻¹XᵀC."""
    try:
        Finv = np.linalg.inv(ext.information)
    except np.linalg.LinAlgError:
        return 1.0
    B = bf.regress(C)[:nb]
    cov_tc = -B @ Finv
    cov_tt = bf.covariance(nb) + B @ Finv @ B.T
    dc, dt = np.diag(Finv), np.diag(cov_tt)
    if np.any(~(dc > 0)) or np.any(~(dt > 0)):
        return 1.0
    return float(min(1.0, np.max(np.abs(cov_tc / np.sqrt(np.outer(dt, dc))))))


def _range_violation(c, est, sig):
    rng = np.asarray(c.physical_range, float)
    lo, hi = rng[:, 0], rng[:, 1]
    s = np.where(np.isfinite(sig), sig, 0.0)
    return bool(np.any((est < lo - RANGE_SIGMAS * s) | (est > hi + RANGE_SIGMAS * s)))


def naming_rounds(problem, st, pool, alpha, max_steps):
    """Step 4 from state ``st`` over the candidates in ``pool``; returns the record."""
    pool = list(pool)
    for n in pool:  # a scanned boundary is chosen afresh by this naming
        getattr(problem, "scan_choice", {}).pop(n, None)
    steps, named_order, ambiguous, rejected, rounds, not_decisive = [], [], [], [], [], []
    states = [st]
    n_rows = st.cl.lin.n_data
    while pool and len(named_order) < max_steps:
        bf = st.base
        rows = []
        for n in pool:
            C, at, B, ext = best_block(problem, bf, st.cl, n)
            if ext.rank == 0:
                continue
            sc = st.cl.scales[n][: problem.candidates[n].n_params]
            rows.append(
                {
                    "effect": n,
                    "ext": ext,
                    "cols": C,
                    "at": at,
                    "scan_size": B,
                    "delta_chi2": ext.delta_chi2,
                    "dof": ext.rank,
                    # a scanned boundary: Bonferroni over the B values scanned (the best of B tests)
                    "p_value": min(1.0, B * ext.p_value),
                    "delta_bic": float(bic_threshold(ext.rank, n_rows)) - ext.delta_chi2,
                    "estimate": ext.c * sc,
                    "sigma": np.sqrt(np.clip(np.diag(ext.cov), 0, None)) * sc,
                }
            )
        if not rows:
            break
        rows.sort(key=lambda r: (r["p_value"], -r["delta_chi2"]))
        K = len(rows)
        # Holm over the p-values; the rule (rule.classify) adds BIC to each significant one
        significant = holm_rejections([r["p_value"] for r in rows], alpha)
        for i, r in enumerate(rows):
            level_i = alpha / (K - i) / r["scan_size"]
            r["verdict"] = classify(r["delta_chi2"], r["dof"], level_i, n_rows) if significant[i] else "not significant"
        rounds.append(
            {
                "chi2_dof": bf.chi2_dof,
                "candidates": [
                    {
                        k: (scalar_or_list(v) if k in ("estimate", "sigma") else v)
                        for k, v in r.items()
                        if k not in ("ext", "cols")
                    }
                    for r in rows
                ],
            }
        )
        winner = None
        for i, r in enumerate(rows):
            if r["verdict"] != NAMED:
                nd = [x for x in rows[i:] if x["verdict"] == NOT_DECISIVE]
                _fix_scans(problem, nd)  # floated at their best boundary
                not_decisive = [_not_decisive_entry(problem, x, n_rows) for x in nd]
                break
            c = problem.candidates[r["effect"]]
            if _range_violation(c, r["estimate"], r["sigma"]):
                rejected.append(
                    {
                        "effect": r["effect"],
                        "estimate": scalar_or_list(r["estimate"]),
                        "sigma": scalar_or_list(r["sigma"]),
                        "reason": "fitted value outside the physical range",
                    }
                )
                pool.remove(r["effect"])
                continue
            winner = r
            break
        if winner is None:
            break
        not_decisive = []
        # ambiguity: another significant candidate that explains the data about as well
        rivals = []
        for r in rows:
            if r is winner or r["effect"] not in pool or not r["p_value"] <= alpha / K:
                continue
            dlogl = 0.5 * (_selected_delta_chi2(winner) - _selected_delta_chi2(r))
            p_extra = _p_given(bf, r["cols"] @ r["ext"].basis, winner["cols"])
            if dlogl < AMBIGUITY_DLOGL or p_extra > alpha:
                rivals.append((r, dlogl, p_extra))
        if rivals:
            group = [winner["effect"]] + [r["effect"] for r, _, _ in rivals]
            _fix_scans(problem, [winner] + [r for r, _, _ in rivals])  # floated at their best boundary
            seps = [f"{g}: {problem.candidates[g].separated_by}" for g in group if problem.candidates[g].separated_by]
            ambiguous.append(
                {
                    "effects": group,
                    "would_split": "; ".join(seps) or "data over which these effects' signatures differ",
                    "delta_logL": [float(d) for _, d, _ in rivals],
                    "p_winner_given_rival": [float(p) for _, _, p in rivals],
                }
            )
            break
        name = winner["effect"]
        c = problem.candidates[name]
        _fix_scans(problem, [winner])
        named = dict(st.named)
        named[name] = np.zeros(c.n_params)
        new = State(problem, st.theta, named, [n for n in pool if n != name])
        i0 = new.nb + sum(new.named[m].size for m in list(new.named)[:-1])
        k = c.n_params
        sig = np.sqrt(np.diag(new.cov)[i0 : i0 + k]) * named_scales(problem, name)
        steps.append(
            {
                "effect": name,
                "estimate": scalar_or_list(new.named[name]),
                "sigma": scalar_or_list(sig),
                "unit": c.units[0] if k == 1 else list(c.units),
                "statistic": float(winner["delta_chi2"]),
                "p_value": float(winner["p_value"]),
                "chi2_dof_before": float(st.base.chi2_dof),
                "chi2_dof_after": float(new.base.chi2_dof),
                "theta_before_arcsec": [float(v) for v in st.theta_arcsec()],
                "theta_after_arcsec": [float(v) for v in new.theta_arcsec()],
                **_scan_fields(problem, winner),
            }
        )
        named_order.append(name)
        pool.remove(name)
        st = new
        states.append(st)
    return {
        "steps": steps,
        "named": named_order,
        "ambiguous": ambiguous,
        "rejected": rejected,
        "rounds": rounds,
        "states": states,
        "not_decisive": not_decisive,
    }


def best_block(problem, bf, cl, name):
    """(columns, boundary, B, extension) of candidate ``name`` beyond the base fit ``bf``.

    For a candidate with a scanned parameter (``Candidate.extra["scan"]``: ``alignment_step``'s
    boundary) the linearisation carries the columns at each of the B values scanned side by side
    (``candidates.scan_candidate``): each block is tested and the one with the largest Δχ² is
    returned — the maximum of B likelihood-ratio statistics, whose p-value the caller multiplies
    by B (Bonferroni over the scan, as a jitter frequency scanned over a grid would be; conservative,
    since neighbouring boundaries are correlated). When the boundary has been chosen
    (``problem.scan_choice``) the columns are that block alone. Otherwise (None, 1)."""
    c = problem.candidates[name]
    C = cl.candidates[name]
    if not c.extra.get("scan"):
        return C, None, 1, extend(bf, C)
    k = c.n_params
    if name in getattr(problem, "scan_choice", {}) and C.k == k:
        return C, problem.scan_choice[name], 1, extend(bf, C)
    from boresight.studies.discrepancy.candidates import scan_boundaries

    ats = scan_boundaries(problem.obs)
    best = None
    for i, a in enumerate(ats):
        Cb = C[:, i * k : (i + 1) * k]
        ext = extend(bf, Cb)
        if best is None or ext.delta_chi2 > best[3].delta_chi2:
            best = (Cb, float(a), len(ats), ext)
    if best is None:
        return C, None, 1, extend(bf, C)
    return best


def _selected_delta_chi2(r) -> float:
    """A candidate's Δχ² as the ambiguity test compares it: a scanned one's is the best of B and is
    charged 2 ln B for the choice.

    DECISION: the best of B boundaries fits better than any one boundary by chance; in a
    likelihood comparison with a candidate that chose nothing, the choice among B models costs ln B
    of log-likelihood (the Bonferroni factor B on the p-value, in the exponent: a χ² tail e^(−x/2)
    times B is the tail at x − 2 ln B). Uncharged, ``alignment_step`` (B = 3 on the 4-pass test
    campaign) made ``aberration`` ``ambiguous`` in 3 of 40 seeds where aberration alone was hidden
    (named 36/40, was 39/40 before the step joined the catalogue)."""
    return float(r["delta_chi2"]) - 2.0 * np.log(max(int(r.get("scan_size", 1)), 1))


def _fix_scans(problem, rows) -> None:
    """The boundary of each scanned candidate among ``rows`` fixed at its best value (before it is
    named or floated, so its columns are that boundary's)."""
    for r in rows:
        if r.get("at") is not None and hasattr(problem, "scan_choice"):
            problem.scan_choice[r["effect"]] = r["at"]


def _scan_fields(problem, r) -> dict:
    """A named scanned effect's boundary, as reported in its step: the value (``boundary_s``), how
    many were scanned, and how many passes lie before it (``after_pass``, 1 = after the first)."""
    if r.get("at") is None:
        return {}
    obs = problem.obs
    firsts = [obs.t_s[obs.pass_index == p].min() for p in np.unique(obs.pass_index)]
    return {
        "boundary_s": float(r["at"]),
        "after_pass": int(sum(f < r["at"] for f in firsts)),
        "boundaries_scanned": int(r["scan_size"]),
    }


def _not_decisive_entry(problem, r, n_rows) -> dict:
    """A candidate significant at its Holm level but not decisive by BIC (rule.py), as reported."""
    c = problem.candidates[r["effect"]]
    return {
        "effect": r["effect"],
        "statistic": float(r["delta_chi2"]),
        "dof": int(r["dof"]),
        "p_value": float(r["p_value"]),
        "bic_threshold": float(bic_threshold(r["dof"], n_rows)),
        "more_data_factor": more_data_factor(r["delta_chi2"], r["dof"], n_rows),
        "estimate": scalar_or_list(r["estimate"]),
        "sigma": scalar_or_list(r["sigma"]),
        "unit": c.units[0] if c.n_params == 1 else list(c.units),
        "would_separate": c.separated_by or "data over which this effect varies differently from θ",
    }


def _p_given(bf, R_cols, W_cols) -> float:
    """p-value of adding W_cols to the base model already extended by R_cols (LR on W's rank
    separable from base + R); 1 when nothing of W is separable from them."""
    try:
        b2 = bf.extended(R_cols)
    except BoresightError:
        return 1.0
    # DECISION: here the question is "does W still improve the fit", not "is W separable": every
    # direction with signal left counts (ρ up to 1 − 1e-9), tested at its LR significance
    ext = extend(b2, W_cols, rho_max=1.0 - 1e-9)
    return ext.p_value


GENERIC_TESTS = ("chi2", "normalised residuals", "whiteness")


def withdraw(problem, names, st, tests, alpha, K):
    """Re-test each named effect against structure no candidate explains; one record per effect.

    When the final residuals still fail, each named effect is re-tested in a model that also
    carries the failing structure probes as free columns (a flexible stand-in for the
    unexplained structure), with its Δχ² divided by that model's χ²/dof when above 1 (the
    noise model understates the scatter). Every fit is a reduction of the one campaign GLS
    (:class:`~boresight.studies.discrepancy.linear.BaseFit` on its Gram matrix). The probe
    columns are first reduced to a subset independent of the model and of each other (pivoted
    Cholesky, ``BaseFit.independent``): probes nest (``attitude law`` is a sum of ``pass``
    columns, and the pass columns sum to θ), and a singular combined fit must never fall back to
    the plain refit, which would keep a name the test could not question.

    Verdicts: ``kept`` (still significant at α/K), ``withdrawn`` (not significant once the
    structure is allowed for) or ``untestable`` (the effect's signature lies inside the model
    and the unexplained structure — the data cannot tell them apart, so the name is not
    established). The records carry the statistic (scaled Δχ²), its degrees of freedom, the
    p-value, the level and the probe columns used.

    A probe that spans the effect cannot test it (the nested case: ``pass`` holds a free rotation
    per pass, so it contains a time tag, a drift, anything constant or linear over a pass). The
    nested comparison is then decided by parsimony, with the one naming rule (``rule.classify``):
    if the χ² test passes and no failing probe is *decisive* beyond the named effects (Δχ² ≤ its
    rank · ln n, the BIC leg), the named effects are the parsimonious explanation of that
    structure and an effect the probes span is ``kept``, saying so (``reason``); otherwise the
    effect cannot be told from the structure: ``untestable``.
    """
    failing = [t.name for t in tests if t.rejected and t.name not in GENERIC_TESTS]
    out = []
    level = alpha / K
    structure = ", ".join(failing) or "excess χ²"
    decisive = _decisive_structure(st, failing, level)
    # parsimony needs a noise model that holds overall: with the χ² test still failing, the scatter
    # is larger than the model says and a name inside the structure is its projection as likely
    chi2_fails = any(t.rejected and t.name == "chi2" for t in tests)
    for name in names:
        others = {m: v for m, v in st.named.items() if m != name}
        # one entry of diagnosis.json's "withdrawn", its keys in the schema's order (docs/discrepancy.md)
        r = {
            "effect": name,
            "verdict": None,
            "statistic": None,
            "dof": 0,
            "p_value": None,
            "level": float(level),
            "probes": [n for n in failing],
            "probe_columns": 0,
            "probe_columns_dependent": 0,
            "reason": "",
        }
        try:
            sub = State(problem, st.theta, others, [name], probes=True)
        except BoresightError as err:
            r.update(verdict="untestable", reason=f"the model without {name} cannot be fitted ({err})")
            out.append(r)
            continue
        bf = sub.base
        probes = [sub.cl.probes[n] for n in failing if n in sub.cl.probes]
        if probes:
            F = Columns.concat(probes)
            keep = bf.independent(F)
            r["probe_columns"] = int(keep.size)
            r["probe_columns_dependent"] = int(F.k - keep.size)
            if keep.size:
                bf = bf.extended(F[:, keep])
        ext = extend(bf, sub.cl.candidates[name])
        scale = max(1.0, bf.chi2_dof)
        if ext.rank == 0:
            if decisive or chi2_fails:
                why = (
                    f"which is decisive beyond the named effects ({decisive})"
                    if decisive
                    else "and the χ² test still fails (the noise model understates the scatter)"
                )
                r.update(
                    verdict="untestable",
                    dof=0,
                    reason=f"its signature lies within θ, the other named effects and the unexplained structure ({structure}), "
                    f"{why}: the data cannot tell them apart",
                )
            else:
                r.update(
                    verdict="kept",
                    dof=0,
                    reason=f"not testable against {structure} (its signature lies within it), but what that structure adds "
                    f"beyond the named effects is not decisive by BIC ({_leftover_text(st, failing, level)}): "
                    f"{name} is the parsimonious explanation",
                )
            out.append(r)
            continue
        stat = ext.delta_chi2 / scale
        p = float(stats.chi2.sf(stat, ext.rank))
        r.update(statistic=float(stat), dof=int(ext.rank), p_value=p)
        if p > level:
            r.update(verdict="withdrawn", reason=f"not significant once the unexplained structure ({structure}) is allowed for")
        else:
            r.update(verdict="kept", reason=f"still significant with the unexplained structure ({structure}) allowed for")
        out.append(r)
    return out


def leftover(st, probe_names, level):
    """(name, Δχ², rank, verdict) of each probe beyond the model of state ``st`` (its columns reduced
    to a subset independent of the model; ``rule.classify`` on the LR statistic)."""
    out = []
    n = st.cl.lin.n_data
    for name in probe_names:
        P = st.cl.probes.get(name)
        if P is None:
            continue
        keep = st.base.independent(P)
        if keep.size == 0:
            continue
        rank, dchi2 = lr_test(st.base, P[:, keep], rho_max=1.0 - 1e-9)
        out.append((name, float(dchi2), int(rank), classify(dchi2, rank, level, n) if rank else "not significant"))
    return out


def _decisive_structure(st, probe_names, level) -> str:
    """The failing probes that the naming rule would call decisive beyond the model of ``st``
    (as text; empty when none is): structure the named effects leave that BIC supports."""
    return ", ".join(f"{p}: Δχ² = {x:.1f} on {k} dof" for p, x, k, v in leftover(st, probe_names, level) if v == NAMED)


def _leftover_text(st, probe_names, level) -> str:
    n = st.cl.lin.n_data
    return (
        "; ".join(
            f"{p}: Δχ² = {x:.1f} on {k} dof ≤ {k} ln {n} = {float(bic_threshold(k, n)):.1f}"
            for p, x, k, v in leftover(st, probe_names, level)
        )
        or "no probe column left"
    )
