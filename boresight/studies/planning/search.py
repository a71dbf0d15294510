"""The search: enumerate candidate campaigns, score them, find the Pareto front and the choice.

A candidate campaign is a multiset of pass options (the same option twice is the same site and
attitude law on another day: its per-pass errors are drawn afresh). Candidates are enumerated
in full, number of passes by number of passes, while they fit ``max_candidates``; the remaining
budget samples the larger campaigns uniformly at random (seeded; the summary says how many of
how many were scored).

The choice (DECISION, ``docs/planning.md``): among the campaigns that meet every requirement
(σθ ≤ target on each axis with the required effects floated, and each required effect named
by ``boresight.diagnose`` at its required size with the stated power, η ≤ 1 — ``naming``;
without the per-image-whitened blocks, detectable at it, ρ ≤ 1), the one of least cost; ties
go to the one with the most margin (smallest max(σθ/target, η)). The Pareto front is over
(cost, max σθ/target, worst η), all three minimised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from boresight.errors import InputValueError
from boresight.stats import minimum_detectable_noncentrality
from boresight.studies.planning.fisher import (
    NOT_SEPARABLE_RATIO,
    Scores,
    score_candidates,
)
from boresight.studies.planning.options import PassOption, scenario_document
from boresight.studies.planning.spec import PlanSpec

__all__ = ["PlanResult", "enumerate_candidates", "pareto_front", "choose"]


def _count(O, n):
    return math.comb(O + n - 1, n)


def enumerate_candidates(n_options: int, n_min: int, n_max: int, budget: int, rng) -> tuple[np.ndarray, int, bool]:
    """Candidates as option indices (C, n_max), −1 padded; the size of the whole space; and
    whether it was enumerated in full."""
    from itertools import chain, combinations_with_replacement

    total = sum(_count(n_options, n) for n in range(n_min, n_max + 1))
    rows = []
    used = 0
    full = True
    for n in range(n_min, n_max + 1):
        c = _count(n_options, n)
        if used + c <= budget:
            a = np.fromiter(chain.from_iterable(combinations_with_replacement(range(n_options), n)), np.int64, c * n).reshape(
                c, n
            )
            used += c
        else:
            full = False
            left = budget - used
            remaining = n_max - n + 1
            take = max(left // remaining, 0)
            if take == 0:
                continue
            seen = np.zeros((0, n), np.int64)
            for _ in range(20):  # draw until `take` distinct multisets (the space has more than `take`)
                extra = np.sort(rng.integers(0, n_options, size=(2 * (take - seen.shape[0]) + 16, n)), axis=1)
                seen = np.unique(np.concatenate([seen, extra]), axis=0)
                if seen.shape[0] >= take:
                    break
            a = seen[rng.permutation(seen.shape[0])[:take]]
            a = a[np.lexsort(a.T[::-1])]
            used += a.shape[0]
        rows.append(np.pad(a, ((0, 0), (0, n_max - n)), constant_values=-1))
    if not rows:
        raise InputValueError("no candidate campaigns: max_candidates is too small for the search space")
    return np.concatenate(rows), total, full


def pareto_front(cost, theta_ratio, worst_ratio) -> np.ndarray:
    """Indices of the non-dominated candidates (all three objectives minimised), by cost.

    >>> pareto_front(np.array([1, 1, 2, 2]), np.array([3.0, 2.0, 1.0, 2.5]), np.array([1.0, 1.0, 1.0, 0.5])).tolist()
    [1, 2, 3]
    """
    cost = np.asarray(cost, float)
    a = np.asarray(theta_ratio, float)
    b = np.asarray(worst_ratio, float)
    front = np.zeros(0, np.int64)
    for c in np.unique(cost):
        ids = np.flatnonzero(cost == c)
        # within a cost level: 2-D non-dominated set
        order = ids[np.lexsort((b[ids], a[ids]))]
        best_b = np.minimum.accumulate(b[order])
        keep = np.ones(order.size, bool)
        keep[1:] = b[order][1:] < best_b[:-1]
        cand = order[keep]
        # drop duplicates of the same (a, b) and those dominated by cheaper front members
        if front.size:
            dom = (a[front][None, :] <= a[cand][:, None]) & (b[front][None, :] <= b[cand][:, None])
            cand = cand[~dom.any(axis=1)]
        front = np.concatenate([front, cand])
    return front


@dataclass
class PlanResult:
    """What ``boresight.plan`` returns (``docs/planning.md``).

    Attributes
    ----------
    spec : PlanSpec
        The plan as read.
    options : list
        The pass options (site, attitude law, …) a campaign is built from.
    blocks : numpy.ndarray
        (O, P, P) the Fisher information of each option over the P parameters.
    labels : tuple
        (P,) the parameter names (θ, the effects, the nuisances).
    candidates : numpy.ndarray
        (C, n_max) option indices of each candidate campaign (−1 = none).
    scores : Scores
        σθ (arcsec), detectable-size ratios ρ (≤ 1 meets a requirement) and cost of each candidate.
    feasible : numpy.ndarray
        (C,) whether each candidate meets every requirement.
    front : numpy.ndarray
        Indices of the Pareto front (σθ against cost).
    chosen : int or None
        The chosen candidate, or None when none is feasible.
    space_size, enumerated_in_full : int, bool
        The size of the search space and whether it was enumerated in full.
    lam_star : numpy.ndarray
        (E,) the non-centralities a detectable effect must reach.
    effect_slices, lookalike_slices : list of slice
        The columns of ``labels`` of each required effect, and of each look-alike (``spec.lookalikes``).
    required : list of numpy.ndarray
        Each required effect's size to detect, in its parameters' units (``spec.effects``).
    timings_s : dict
        Where the search spent its time (``blocks_s``, ``score_s``) and how many candidates were
        scored in full (``scored_in_full``; the others were proved dominated).
    raw_blocks, option_rows : numpy.ndarray or None
        (O, P, P) each option's information without the shared nuisances marginalised, and (O,) its
        number of residuals, for the naming scores; None when the plan does not score naming.
    rule : NamingRule or None
        The naming rule the scores use (``diagnose``'s, at the plan's level and power).
    step : bool
        Whether ``alignment_step`` is scored as a look-alike and rival (the last of each; ``fisher.step_terms``).
    """

    spec: PlanSpec
    options: list
    blocks: np.ndarray
    labels: tuple
    candidates: np.ndarray
    scores: Scores
    feasible: np.ndarray
    front: np.ndarray
    chosen: int | None
    space_size: int
    enumerated_in_full: bool
    effect_slices: list
    required: list
    lam_star: np.ndarray
    timings_s: dict = field(default_factory=dict)
    lookalike_slices: list = field(default_factory=list)
    raw_blocks: np.ndarray | None = None
    option_rows: np.ndarray | None = None
    rule: object = None
    step: bool = False

    def step_terms(self, campaigns):
        """``fisher.step_terms`` of campaigns (C, n) or lists of option indices in flight order; None when the plan
        does not score ``alignment_step`` (``spec.scanned_rivals``)."""
        from boresight.studies.planning.fisher import step_terms

        return step_terms(self.blocks, campaigns, self.raw_blocks) if self.step else None

    def score(self, info, raw=None, n_rows=None):
        """``fisher.score_information`` of one information matrix (P, P) with this plan's settings
        (and the naming scores when ``raw`` (P, P) and ``n_rows`` are given). A summed matrix has no
        pass order, so ``alignment_step`` is not scored here (``step_terms``)."""
        from boresight.studies.planning.fisher import score_information

        kw: dict = {} if raw is None else dict(raw=np.asarray(raw)[None], n_rows=np.array([float(n_rows)]), rule=self.rule)
        return score_information(
            np.asarray(info)[None], self.effect_slices, self.required, self.lam_star, self.lookalike_slices, **kw
        )

    def score_every_candidate(self) -> Scores:
        """``fisher.score_candidates`` of every candidate with this plan's settings: the look-alike and naming
        scores that the pruned search (``pruned_scores``) leaves NaN for the candidates it proves dominated, computed
        for all of them (the cost of the search without pruning; its front and choice are the plan's)."""
        return score_candidates(
            self.blocks,
            self.candidates,
            np.array([o.cost for o in self.options]),
            self.effect_slices,
            self.required,
            self.lam_star,
            self.lookalike_slices,
            raw_blocks=self.raw_blocks,
            option_rows=self.option_rows,
            rule=self.rule,
            step=self.step,
        )

    def raw_information(self, c_or_indices) -> np.ndarray:
        """Candidate c's information with only the per-image errors marginalised (``naming``)."""
        ids = self.candidates[c_or_indices] if np.isscalar(c_or_indices) else np.asarray(c_or_indices)
        ids = ids[ids >= 0]
        return self.raw_blocks[ids].sum(axis=0)

    def n_rows(self, c: int) -> int:
        ids = self.candidates[c]
        return int(self.option_rows[ids[ids >= 0]].sum())

    def rival_names(self) -> list:
        """Names indexed by ``scores.binding_rival``: the required effects, then the look-alikes."""
        return list(self.spec.effect_names) + list(self.spec.lookalikes) + (list(self.spec.scanned_rivals) if self.step else [])

    @property
    def theta_ratio(self) -> np.ndarray:
        return np.max(self.scores.sigma_theta_arcsec / np.asarray(self.spec.sigma_theta_arcsec), axis=-1)

    @property
    def requirement_ratio(self) -> np.ndarray:
        """(C, E): what the requirement tests per effect — the nameable-size ratio η when the
        naming scores exist, else the detectable-size ratio ρ."""
        s = self.scores
        return s.name_ratio if s.name_ratio is not None else s.detect_ratio

    @property
    def worst_ratio(self) -> np.ndarray:
        r = self.requirement_ratio
        return r.max(axis=-1) if r.shape[-1] else np.zeros(r.shape[0])

    def passes(self, c: int) -> list[PassOption]:
        return [self.options[i] for i in self.candidates[c] if i >= 0]

    def information(self, c_or_indices) -> np.ndarray:
        ids = self.candidates[c_or_indices] if np.isscalar(c_or_indices) else np.asarray(c_or_indices)
        ids = ids[ids >= 0]
        return self.blocks[ids].sum(axis=0)

    def detectable_size(self, c: int, name: str) -> np.ndarray:
        """The minimum detectable size of effect ``name`` in candidate c (vector, the effect's units)."""
        j = self.spec.effect_names.index(name)
        return self.scores.detect_ratio[c, j] * self.required[j]

    def scenario_document(self, c: int, name: str | None = None, effects: dict | None = None) -> dict:
        """Candidate c as a scenario document (``orbits.scenario_from_dict`` / a TOML file)."""
        ps = self.passes(c)
        n_star = sum(p.kind == "stars" for p in ps)
        desc = (
            f"campaign planned by boresight plan from {self.spec.source}: {len(ps) - n_star} passes, "
            + (f"{n_star} star-frame segments, " if n_star else "")
            + f"{sum(p.images for p in ps)} images, cost {self.scores.cost[c]:g}"
        )
        return scenario_document(
            self.spec,
            [p.entry for p in ps if p.kind != "stars"],
            name=name or f"{self.spec.name}-chosen",
            description=desc,
            effects=effects,
            star_entries=[p.entry for p in ps if p.kind == "stars"],
        )

    def describe(self, c: int) -> str:
        return "; ".join(p.label for p in self.passes(c))


def choose(scores: Scores, feasible: np.ndarray, theta_ratio: np.ndarray, worst_ratio: np.ndarray) -> int | None:
    """Cheapest feasible candidate, ties to the largest margin; None if none is feasible."""
    ids = np.flatnonzero(feasible)
    if ids.size == 0:
        return None
    margin = np.maximum(theta_ratio[ids], worst_ratio[ids])
    order = np.lexsort((margin, scores.cost[ids]))
    return int(ids[order[0]])


def _progress(done: int, total: int, t0: float, state: dict):
    """A progress line on stderr when the scoring has already run 2 s."""
    import sys
    import time

    now = time.perf_counter()
    if now - t0 > 2.0 and now - state.get("last", t0) > 2.0:
        state["last"] = now
        print(
            f"plan: {total} candidate campaigns bounded, {done} of them on the bounds' front scored in full "
            f"({now - t0:.0f} s); scoring the rest that may matter",
            file=sys.stderr,
            flush=True,
        )


def pruned_scores(spec, blocks, cand, cost, slices, required, lam, look, raw_blocks, option_rows, rule, step=False):
    """Scores of every candidate, the expensive part (look-alikes, naming) only where it can matter.

    DECISION (docs/planning.md, "The search"): every candidate gets the cheap scores of
    ``fisher.bound_scores`` (σθ, ρ joint and a lower bound b_c of its requirement ratio — naming
    needs detection). A candidate is scored in full unless a candidate scored in full and strictly
    cheaper has max σθ/target ≤ its own and worst ratio ≤ b_c: such a candidate is dominated, so it is on no Pareto front and is not the cheapest
    feasible one (its dominator is cheaper and also feasible). The front and the choice are
    therefore exactly those of scoring everything. The candidates not scored in full keep the cheap
    scores and NaN for the look-alike, naming and requirement ratios (not feasible, on no front).
    Returns (``Scores``, number scored in full).
    """
    import time

    from boresight.studies.planning.fisher import bound_scores

    t0 = time.perf_counter()
    C = cand.shape[0]
    target = np.asarray(spec.sigma_theta_arcsec, float)
    sig, sig_only, rho_joint, singular, lower = bound_scores(
        blocks, cand, slices, required, lam, option_rows=option_rows, rule=rule
    )
    theta_ratio = np.max(sig / target, axis=-1)
    bound = np.minimum(lower.max(axis=-1), NOT_SEPARABLE_RATIO) if slices else np.zeros(C)
    ccost = np.where(cand >= 0, cost[np.maximum(cand, 0)], 0.0).sum(axis=1)
    E, F = len(slices), len(look) + bool(step)
    nan = lambda *shape: np.full(shape, np.nan)  # noqa: E731
    full = dict(detect_ratio=nan(C, E), detect_ratio_joint=rho_joint.copy(), lookalike_ratio=nan(C, E, F))
    naming = rule is not None
    if naming:
        full.update(name_ratio=nan(C, E), name_probability=nan(C, E), canonical_rho=nan(C, E), binding_rival=np.full((C, E), -1))
    scored = np.zeros(C, bool)
    worst = np.full(C, np.nan)

    def score(ids):
        if ids.size == 0:
            return
        s = score_candidates(
            blocks,
            cand[ids],
            cost,
            slices,
            required,
            lam,
            look,
            raw_blocks=raw_blocks,
            option_rows=option_rows,
            rule=rule,
            step=step,
        )
        for k in full:
            full[k][ids] = getattr(s, k)
        req = s.name_ratio if naming else s.detect_ratio
        worst[ids] = np.minimum(req.max(axis=-1), NOT_SEPARABLE_RATIO) if E else 0.0
        scored[ids] = True

    # two passes: (1) the candidates on the Pareto front of the bounds (cost, σθ ratio, bound),
    # scored in full; (2) every candidate no scored one dominates (strictly cheaper, σθ ratio ≤ its
    # own, worst ratio ≤ its bound), scored in full. What is left is dominated by a scored candidate.
    seed = pareto_front(ccost, theta_ratio, bound)
    score(seed)
    dom_ids = seed[pareto_front(ccost[seed], theta_ratio[seed], worst[seed])]
    dominated = np.zeros(C, bool)
    for b in range(0, dom_ids.size, 256):
        d = dom_ids[b : b + 256]
        dominated |= (
            (ccost[d][None, :] < ccost[:, None])
            & (theta_ratio[d][None, :] <= theta_ratio[:, None])
            & (worst[d][None, :] <= bound[:, None])
        ).any(axis=1)
    _progress(seed.size, C, t0, {})
    score(np.flatnonzero(~dominated & ~scored))
    # the choice (cheapest feasible) and the θ-only choice the report compares with: scored in full
    # (a candidate that can be feasible and is not dominated is already scored; this is insurance)
    maybe = (theta_ratio <= 1.0) & (bound <= 1.0)
    while True:
        feas = scored & maybe & (worst <= 1.0)
        cstar = ccost[feas].min() if feas.any() else np.inf
        todo = np.flatnonzero(maybe & ~scored & (ccost <= cstar))
        if todo.size == 0:
            break
        score(todo)
    ok = np.flatnonzero(theta_ratio <= 1.0)
    if ok.size:  # report.theta_only_choice
        t_only = ok[np.lexsort((theta_ratio[ok], ccost[ok]))[0]]
        score(np.array([t_only]) if not scored[t_only] else np.zeros(0, np.int64))
    if E:
        full["detect_ratio"] = np.where(scored[:, None], full["detect_ratio"], np.nan)
    return Scores(sigma_theta_arcsec=sig, sigma_theta_only_arcsec=sig_only, cost=ccost, singular=singular, **full), int(
        scored.sum()
    )


def _effect_columns(labels, name: str) -> slice:
    """The columns of effect ``name`` in the Fisher blocks, whose labels are ``"<effect>.<parameter>"`` (an effect's
    parameters are adjacent)."""
    cols = [k for k, lab in enumerate(labels) if lab.split(".")[0] == name]
    return slice(cols[0], cols[-1] + 1)


def run_search(
    spec: PlanSpec, options, blocks, labels, max_candidates=None, timings=None, raw_blocks=None, option_rows=None
) -> PlanResult:
    """Enumerate, score, front and choice (the blocks are computed by ``boresight.studies.planning.plan``)."""
    import time

    timings = {} if timings is None else timings
    names = spec.effect_names
    level = spec.alpha / spec.n_candidates
    slices = [_effect_columns(labels, n) for n in names]
    required = [np.asarray(spec.effects[n], float) for n in names]
    lam = np.array([minimum_detectable_noncentrality(sl.stop - sl.start, level, spec.power) for sl in slices])
    t0 = time.perf_counter()
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed))
    cand, total, full = enumerate_candidates(
        len(options), spec.passes_min, spec.passes_max, max_candidates or spec.max_candidates, rng
    )
    cost = np.array([o.cost for o in options])
    look = [_effect_columns(labels, n) for n in spec.lookalikes]
    from boresight.studies.planning.naming import NamingRule

    rule = NamingRule.from_diagnose(level, spec.alpha, spec.power)
    step = bool(spec.scanned_rivals) and bool(names)
    scores, n_full = pruned_scores(
        spec,
        blocks,
        cand,
        cost,
        slices,
        required,
        lam,
        look,
        raw_blocks,
        option_rows,
        rule if raw_blocks is not None else None,
        step=step,
    )
    timings["score_s"] = time.perf_counter() - t0
    timings["scored_in_full"] = n_full
    theta_ratio = np.max(scores.sigma_theta_arcsec / np.asarray(spec.sigma_theta_arcsec), axis=-1)
    req = scores.name_ratio if scores.name_ratio is not None else scores.detect_ratio
    worst = req.max(axis=-1) if names else np.zeros(cand.shape[0])
    feasible = (theta_ratio <= 1.0) & (worst <= 1.0)  # NaN (not scored in full: dominated) is not feasible
    live = np.flatnonzero(~np.isnan(worst))
    front = live[pareto_front(scores.cost[live], theta_ratio[live], np.minimum(worst[live], NOT_SEPARABLE_RATIO))]
    chosen = choose(scores, feasible, theta_ratio, worst)
    return PlanResult(
        spec=spec,
        options=options,
        blocks=blocks,
        labels=labels,
        candidates=cand,
        scores=scores,
        feasible=feasible,
        front=front,
        chosen=chosen,
        space_size=total,
        enumerated_in_full=full,
        effect_slices=slices,
        required=required,
        lam_star=lam,
        timings_s=timings,
        lookalike_slices=look,
        raw_blocks=raw_blocks,
        option_rows=option_rows,
        rule=rule,
        step=step,
    )
