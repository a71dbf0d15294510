"""What ``boresight plan`` writes: the Pareto front (ECSV), the chosen campaign (a scenario TOML),
a plot (PNG), a JSON summary and a Markdown summary that says *why*.

The "why" is computed, not written by hand: for the chosen campaign, each pass is removed in
turn and the campaign rescored (σθ and every effect's requirement ratio: η, the nameable size
over the required size, or ρ, the detectable one, without naming scores); each pass is also
scored alone. A pass whose removal makes an effect unnameable at its required size is
the pass that breaks that effect's degeneracy with θ; an effect no single pass separates needs
the combination (e.g. thermal: passes at different arguments of latitude). The catalogue's own
``separated_by`` text says what physics is at work. The cheapest campaign that meets the σθ
target alone is shown with what it would miss.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from boresight.files import atomic_write_text, write_json, write_table
from boresight.reporting.outputs import save_figure
from boresight.studies.planning.fisher import NOT_SEPARABLE_RATIO
from boresight.studies.planning.search import PlanResult
from boresight.studies.planning.toml_out import dumps

__all__ = ["why", "front_table", "write_outputs", "summary_text", "rho_text"]


def rho_text(r: float) -> str:
    return "not separable" if r >= NOT_SEPARABLE_RATIO else f"{r:.3g}"


def _score_batch(result: PlanResult, campaigns: list) -> list:
    """Scores (``fisher.score_information``: a tuple of arrays (C, …)) of the campaigns made of the
    option indices in ``campaigns`` (a list of lists), in one batch, with the naming scores when the
    plan has them."""
    from boresight.studies.planning.fisher import score_information

    info = np.stack([result.blocks[ids].sum(axis=0) for ids in campaigns])
    kw = {}
    if result.raw_blocks is not None:
        kw = dict(
            raw=np.stack([result.raw_blocks[ids].sum(axis=0) for ids in campaigns]),
            n_rows=np.array([float(result.option_rows[ids].sum()) for ids in campaigns]),
            rule=result.rule,
        )
    kw["step"] = result.step_terms(campaigns)
    return score_information(info, result.effect_slices, result.required, result.lam_star, result.lookalike_slices, **kw)


def _row(scored, k: int) -> tuple:
    """Candidate k of a batch of scores, as a batch of one (the layout of ``score_information``)."""
    return tuple(None if a is None else a[k : k + 1] for a in scored)


def _searched(result: PlanResult, c: int) -> tuple:
    """Candidate c's scores as the search computed them (the layout of ``score_information``): the
    summary reuses them rather than scoring the campaign again."""
    s = result.scores
    row = (
        s.sigma_theta_arcsec,
        s.sigma_theta_only_arcsec,
        s.detect_ratio,
        s.singular,
        s.detect_ratio_joint,
        s.lookalike_ratio,
        s.name_ratio,
        s.name_probability,
        s.canonical_rho,
        s.binding_rival,
    )
    return tuple(None if a is None else a[c : c + 1] for a in row)


def _req(scored):
    """The requirement ratio per effect of one scored campaign: η (naming) when present, else ρ."""
    return scored[6][0] if scored[6] is not None else scored[2][0]


def why(result: PlanResult, c: int) -> dict:
    """Leave-one-pass-out and pass-alone scores of candidate c, and the effects' correlations.

    Candidate c itself keeps the scores the search gave it (``result.scores``); its variants
    without one pass and each pass alone are scored together, in one batch."""
    ids = [int(i) for i in result.candidates[c] if i >= 0]
    full = _searched(result, c)
    n = len(ids)
    variants = ([ids[:j] + ids[j + 1 :] for j in range(n)] if n > 1 else []) + [[i] for i in ids]
    batch = _score_batch(result, variants)
    out = {"passes": [], "effects": {}}
    for j, i in enumerate(ids):
        s_wo = _row(batch, j) if n > 1 else None
        s_alone = _row(batch, j + (n if n > 1 else 0))
        out["passes"].append(
            {
                "pass": j,
                "option": result.options[i].label,
                "sigma_theta_without_arcsec": None if s_wo is None else s_wo[0][0].tolist(),
                "rho_without": None if s_wo is None else _req(s_wo).tolist(),
                "rho_alone": _req(s_alone).tolist(),
                "sigma_theta_alone_arcsec": s_alone[0][0].tolist(),
            }
        )
    if result.spec.effect_names:
        out["effects"] = _why_effects(result, c, full, out["passes"])
    return out


def _why_effects(result: PlanResult, c: int, full: tuple, passes: list) -> dict:
    """Per required effect: its ratios, correlations, the critical/needed passes and look-alikes."""
    from boresight.studies.planning.fisher import covariance_batch

    names = result.spec.effect_names
    cov, _ = covariance_batch(result.information(c)[None])
    cov = cov[0]
    sd = np.sqrt(np.diag(cov))
    corr = cov / np.outer(sd, sd)
    rivals = result.rival_names()
    look = list(result.spec.lookalikes) + (list(result.spec.scanned_rivals) if result.step else [])
    named = full[6] is not None
    out = {}
    for e, (name, sl) in enumerate(zip(names, result.effect_slices)):
        rho_e = float(_req(full)[e])
        critical = [p["pass"] for p in passes if p["rho_without"] is not None and p["rho_without"][e] > max(3.0 * rho_e, 1.0)]
        needed = [
            p["pass"] for p in passes if p["rho_without"] is not None and p["rho_without"][e] > 1.0 and p["pass"] not in critical
        ]
        rl = full[5][0][e] if len(look) else np.zeros(0)
        binding = look[int(np.argmax(rl))] if len(look) and rl.max() > full[4][0][e] * (1 + 1e-6) else None
        others = [k for k in range(len(names)) if k != e]
        out[name] = {
            "requirement_ratio": rho_e,
            "eta": float(full[6][0][e]) if named else None,
            "p_name": float(full[7][0][e]) if named else None,
            "canonical_rho": float(full[8][0][e]) if named else None,
            "binding_rival": (rivals[int(full[9][0][e])] if full[9][0][e] >= 0 else None) if named else None,
            "rho": float(full[2][0][e]),
            "max_abs_corr_with_theta": float(np.abs(corr[sl, :3]).max()),
            "max_abs_corr_with_other_effects": float(
                max((np.abs(corr[sl, result.effect_slices[k]]).max() for k in others), default=0.0)
            ),
            "critical_passes": critical,
            "needed_passes": needed,
            "rho_theta_and_required_floated": float(full[4][0][e]),
            "binding_lookalike": binding,
            "rho_with_binding_lookalike": None if binding is None else float(rl.max()),
            "separating_alone": [p["pass"] for p in passes if p["rho_alone"][e] <= 1.0],
        }
    return out


def _separated_by(name: str) -> str:
    try:
        from orbits.effects import EFFECTS
    except ImportError:
        return ""
    return EFFECTS[name].separated_by if name in EFFECTS else ""


def theta_only_choice(result: PlanResult):
    """The cheapest candidate meeting the σθ target alone (what a θ-only planner would pick)."""
    ok = np.flatnonzero(result.theta_ratio <= 1.0)
    if ok.size == 0:
        return None
    order = np.lexsort((result.theta_ratio[ok], result.scores.cost[ok]))
    return int(ok[order[0]])


def front_table(result: PlanResult):
    """The Pareto front as an astropy Table (units on the columns), by cost."""
    from astropy import units as u
    from astropy.table import Table

    f = result.front
    s = result.scores
    t = Table()
    t["cost"] = s.cost[f]
    t["cost"].description = f"campaign cost, in {result.spec.cost_unit} ([cost] unit of the plan)"
    t["n_passes"] = (result.candidates[f] >= 0).sum(axis=1)
    t["n_images"] = [sum(p.images for p in result.passes(int(c))) for c in f]
    for i, ax in enumerate("xyz"):
        t[f"sigma_theta_{ax}"] = s.sigma_theta_arcsec[f, i] * u.arcsec
    for i, ax in enumerate("xyz"):
        t[f"sigma_theta_only_{ax}"] = s.sigma_theta_only_arcsec[f, i] * u.arcsec
    t["theta_ratio"] = result.theta_ratio[f]
    for j, name in enumerate(result.spec.effect_names):
        t[f"rho_{name}"] = s.detect_ratio[f, j]
        if s.name_ratio is not None:
            t[f"eta_{name}"] = s.name_ratio[f, j]
            t[f"p_name_{name}"] = s.name_probability[f, j]
    t["worst_ratio"] = result.worst_ratio[f]
    t["meets_requirements"] = result.feasible[f]
    t["chosen"] = f == (result.chosen if result.chosen is not None else -1)
    t["passes"] = [result.describe(int(c)) for c in f]
    t.meta.update(_meta(result))
    return t


def _meta(result: PlanResult) -> dict:
    spec = result.spec
    return {
        "format": "boresight-plan-front",
        "version": "1.0",
        "plan": spec.source,
        "sigma_theta_target_arcsec": list(spec.sigma_theta_arcsec),
        "required_effects": {k: np.asarray(v).tolist() for k, v in spec.effects.items()},
        "alpha_familywise": spec.alpha,
        "n_candidates_bonferroni": spec.n_candidates,
        "level_per_test": spec.alpha / spec.n_candidates,
        "power": spec.power,
        "noncentrality": result.lam_star.tolist(),
        "cost_model": _cost_model(spec),
        "cost_unit": spec.cost_unit,
        "space_size": result.space_size,
        "scored": int(result.candidates.shape[0]),
        "scored_in_full": result.timings_s.get("scored_in_full"),
        "enumerated_in_full": bool(result.enumerated_in_full),
        "columns": {
            "sigma_theta_*": "predicted 1σ of θ (Fisher/Cramér–Rao, linearised) with the required effects floated, all nuisances marginalised",
            "sigma_theta_only_*": "the same with no effect floated",
            "theta_ratio": "max over axes of sigma_theta / target",
            "rho_<effect>": "minimum detectable size / required size, with the required effects and each look-alike floated",
            "eta_<effect>": "smallest size boresight.diagnose names with the stated power / required size (≤ 1 meets the requirement)",
            "p_name_<effect>": "predicted probability that boresight.diagnose names the effect hidden at its required size",
            "worst_ratio": "the largest eta (the requirement) over the required effects",
        },
    }


def _cost_model(spec) -> str:
    return (
        f"cost ({spec.cost_unit}) = {spec.cost_per_pass:g} per pass + {spec.cost_per_image:g} per image + "
        f"{spec.cost_per_site_tracking_pass:g} per site-tracking pass + {spec.cost_per_nadir_pass:g} per nadir pass "
        "+ the site's own cost per pass over it"
        + (
            f"; a star-frame segment {spec.cost_per_pass:g} + {spec.cost_per_star_segment:g} + "
            f"{spec.cost_per_image:g} per frame that sees a star"
            if spec.star_segments
            else ""
        )
    )


def _options_text(result) -> str:
    """ "N pass options", and the star-frame segments among them when the plan has some."""
    n_star = sum(getattr(o, "kind", "pass") == "stars" for o in result.options)
    if not n_star:
        return f"{len(result.options)} pass options"
    return f"{len(result.options)} pass options ({n_star} of them star-frame segments: passes count both)"


def _fmt3(v) -> str:
    """Three σ values; a σ above 10⁴ (a direction the campaign cannot determine) as 'undetermined'."""
    return "[" + ", ".join("undetermined" if x > 1e4 else f"{x:.3g}" for x in v) + "]"


def summary_text(result: PlanResult, checks: dict | None = None, why_: dict | None = None) -> str:
    """The Markdown summary (``summary.md``); ``why_`` is ``why(result, result.chosen)`` when the
    caller has it already (``write_outputs``), else it is computed."""
    spec = result.spec
    L = [f"# Calibration campaign plan: {spec.name}", ""]
    L.append(f"Plan file `{spec.source}`. {spec.description}".strip())
    L.append("")
    L += _requirements_lines(result)
    L.append("")
    if result.chosen is None:
        L += _closest_lines(result)
    else:
        L += _chosen_lines(result)
        L += _why_lines(result, why(result, result.chosen) if why_ is None else why_)
        L += _theta_only_lines(result)
    if checks:
        L += ["", "## Monte Carlo spot check"] + [f"- {line}" for line in checks.get("lines", [])]
    L.append("")
    L += _front_lines(result)
    L.append("")
    return "\n".join(L)


def effect_values_text(name: str, values) -> str:
    """An effect's parameter values with their names and units, as the catalogue names them
    (``orbits.effects.EFFECTS[name].param_names`` carry the unit), the components that are not 0:
    ``sin_x_arcsec = 13.78, cos_y_arcsec = 13.78``.

    >>> effect_values_text("time_tag", [0.02])
    'dt_s = 0.02'
    """
    from orbits.effects import EFFECTS

    v = np.atleast_1d(np.asarray(values, float))
    names = EFFECTS[name].param_names if name in EFFECTS and len(EFFECTS[name].param_names) == v.size else None
    if names is None:
        return ", ".join(f"{x:.4g}" for x in v)
    keep = [k for k in range(v.size) if v[k] != 0] or list(range(v.size))  # the components a size is given for
    return ", ".join(f"{names[k]} = {v[k]:.4g}" for k in keep)


def _requirements_lines(result: PlanResult) -> list:
    spec = result.spec
    L = [
        "## Requirements and models",
        f"- target σθ (1σ, per axis): {_fmt3(spec.sigma_theta_arcsec)} arcsec, met with the required effects floated",
    ]
    for name, v in spec.effects.items():
        L.append(
            f"- `{name}` hidden at {effect_values_text(name, v)} must be named by `boresight diagnose` with probability ≥ {spec.power:g}"
        )
    if spec.effects:
        L.append(
            f"- detection: likelihood-ratio test at level α/K = {spec.alpha:g}/{spec.n_candidates} = {spec.alpha / spec.n_candidates:.4g} "
            f"(the diagnosis' Bonferroni level for K candidate effects), power {spec.power:g}; non-centrality λ* = "
            + ", ".join(f"{lam:.2f} ({n})" for n, lam in zip(spec.effect_names, result.lam_star))
        )
        L.append(
            "- naming (docs/planning.md): the diagnosis tests an effect only if every direction keeps ≥ 1 − ρ_max² of its signal "
            "(canonical ρ ≤ 0.995), names it if the LR test passes α/K and BIC, and calls it ambiguous when another significant "
            "candidate's fit is within ΔlogL < 2 or it adds nothing at α once that one is in; η = the smallest multiple of the "
            "required size named with the stated power"
        )
    L.append(f"- {_cost_model(spec)}")
    t = result.timings_s
    L.append(
        f"- search: {_options_text(result)}; {spec.passes_min}–{spec.passes_max} passes; "
        f"{result.candidates.shape[0]} of {result.space_size} candidate campaigns scored"
        + (" (all)" if result.enumerated_in_full else " (larger campaigns sampled at random)")
        + (f", {t['scored_in_full']} of them in full (the others are dominated)" if "scored_in_full" in t else "")
        + f"; blocks {t.get('blocks_s', float('nan')):.2f} s, scoring {t.get('score_s', float('nan')):.2f} s"
    )
    L.append(
        "- predictions: Fisher information (Cramér–Rao bound) of the linearised model; the noise model's pixel, "
        "per-image and per-pass star-tracker/GNSS and catalogue errors are marginalised as nuisances"
    )
    return L


def unmet_requirements(result: PlanResult) -> list[str]:
    """When no campaign meets every requirement: each requirement that no campaign of the search
    space meets even alone, with the best any campaign reaches; or, when each can be met alone,
    that none meets them together (``plan`` exit 5 never said which). Empty when a
    campaign was chosen."""
    if result.chosen is not None:
        return []
    s, spec = result.scores, result.spec
    target = np.asarray(spec.sigma_theta_arcsec, dtype=np.float64)
    out = []
    best_theta = np.nanmin(s.sigma_theta_arcsec / target, axis=0)  # per axis, over the campaigns
    if np.any(best_theta > 1.0):
        k = int(np.nanargmin(result.theta_ratio))
        out.append(
            f"[requirements] sigma_theta_arcsec = {spec.sigma_theta_arcsec}: no campaign reaches it; the best "
            f"reaches {_fmt3(s.sigma_theta_arcsec[k])} arcsec ({result.theta_ratio[k]:.3g}× the target on its worst axis)"
        )
    ratio = result.requirement_ratio
    what = "named" if s.name_ratio is not None else "detected"
    for j, name in enumerate(spec.effect_names):
        col = ratio[:, j]
        if not np.any(col <= 1.0):
            best = np.nanmin(col) if np.any(np.isfinite(col)) else np.inf
            out.append(
                f"[requirements.effects] {name}: no campaign lets it be {what} at the required size; the best needs "
                f"{rho_text(best)}× that size"
            )
    if not out:
        out.append(
            "every requirement is met by some campaign, but none meets [requirements] sigma_theta_arcsec and every "
            "[requirements.effects] entry together"
        )
    return out


def _closest_lines(result: PlanResult) -> list:
    s, spec = result.scores, result.spec
    best = int(np.nanargmin(np.maximum(result.theta_ratio, result.worst_ratio)))  # NaN: dominated, not scored in full
    return [
        "## No campaign in the search space meets every requirement",
        *(f"- {line}" for line in unmet_requirements(result)),
        "",
        f"Closest: {result.describe(best)} — σθ {_fmt3(s.sigma_theta_arcsec[best])} arcsec, "
        + ", ".join(f"{n} η = {rho_text(r)}" for n, r in zip(spec.effect_names, result.requirement_ratio[best])),
        "Widen the search (more passes, sites, images, landmarks) or relax a requirement; the Pareto front below shows the trade-offs.",
    ]


def _chosen_lines(result: PlanResult) -> list:
    s, spec, c = result.scores, result.spec, result.chosen
    L = [
        "## Chosen campaign",
        f"Cost {s.cost[c]:g} {spec.cost_unit}; σθ {_fmt3(s.sigma_theta_arcsec[c])} arcsec with the effects floated "
        f"({_fmt3(s.sigma_theta_only_arcsec[c])} arcsec with none floated).",
        "",
        "| pass | site | direction | attitude | u (deg) | images | landmarks/image |",
        "|---|---|---|---|---|---|---|",
    ]
    for j, p in enumerate(result.passes(c)):
        L.append(
            f"| {j} | {p.site} | {p.direction} | {p.attitude}{f' yaw {p.yaw_deg:g}°' if p.yaw_deg else ''} | {p.u_deg:.1f} | {p.images} | {p.landmarks_per_image} |"
        )
    L.append("")
    for j, name in enumerate(spec.effect_names):
        L.append(
            f"- `{name}`: minimum detectable size {effect_values_text(name, result.detectable_size(c, name))} "
            f"(ρ = {rho_text(s.detect_ratio[c, j])} of the required size)"
            + (
                ""
                if s.name_ratio is None
                else f"; named by the diagnosis with probability {s.name_probability[c, j]:.3f} at the required size, "
                f"with power {spec.power:g} from η = {rho_text(s.name_ratio[c, j])} of it; canonical ρ with θ and the nuisances "
                f"{s.canonical_rho[c, j]:.4f}"
            )
        )
    return L


def _why_lines(result: PlanResult, w: dict) -> list:
    names = result.spec.effect_names
    L = ["", "## Why this campaign"]
    for p in w["passes"]:
        if p["sigma_theta_without_arcsec"] is not None:
            L.append(
                f"- without pass {p['pass']} ({p['option']}): σθ {_fmt3(p['sigma_theta_without_arcsec'])} arcsec"
                + ("".join(f"; {n} η {rho_text(r)}" for n, r in zip(names, p["rho_without"])))
            )
    for name, e in w["effects"].items():
        L += [
            "",
            f"**{name}** (η = {rho_text(e['requirement_ratio'])}, largest |correlation| with θ {e['max_abs_corr_with_theta']:.2f}, "
            f"with the other effects {e['max_abs_corr_with_other_effects']:.2f}). ",
        ]
        L += _effect_why_sentences(name, e)
    return L


def _effect_why_sentences(name: str, e: dict) -> list:
    L = []
    if e["critical_passes"]:
        L.append(
            f"Passes {e['critical_passes']} break its degeneracy with θ: without any one of them the size it is named at grows more than threefold (or it is no longer separable at all). "
        )
    if e["needed_passes"]:
        L.append(
            f"Passes {e['needed_passes']} supply the precision: without any one of them it is named only above the required size. "
        )
    if not e["critical_passes"] and not e["needed_passes"]:
        L.append("No single pass is critical (each can be dropped and it stays nameable). ")
    if e.get("binding_rival"):
        L.append(f"The candidate that most often makes it ambiguous is `{e['binding_rival']}`. ")
    if e["binding_lookalike"]:
        L.append(
            f"Its closest look-alike is `{e['binding_lookalike']}`: with it floated ρ = {e['rho_with_binding_lookalike']:.3g} "
            f"(ρ = {e['rho_theta_and_required_floated']:.3g} with θ and the required effects only). "
        )
    if not e["separating_alone"]:
        L.append("No pass alone separates it: it needs the combination. ")
    else:
        L.append(f"Passes {e['separating_alone']} alone would separate it. ")
    sep = _separated_by(name)
    if sep:
        L.append(f"Catalogue: separated by {sep}.")
    return L


def _theta_only_lines(result: PlanResult) -> list:
    s, spec = result.scores, result.spec
    t0 = theta_only_choice(result)
    if not spec.effects or t0 is None or t0 == result.chosen:
        return []
    ratios = list(zip(spec.effect_names, result.requirement_ratio[t0]))
    return [
        "",
        f"A plan for σθ alone would fly {result.describe(t0)} (cost {s.cost[t0]:g} {result.spec.cost_unit}, σθ {_fmt3(s.sigma_theta_arcsec[t0])} arcsec floated): "
        + ", ".join(f"{n} η = {rho_text(r)}" for n, r in ratios)
        + " — it would leave "
        + (", ".join(n for n, r in ratios if r > 1) or "nothing")
        + " unnamed at the required size.",
    ]


def _front_lines(result: PlanResult) -> list:
    s, c = result.scores, result.chosen
    theta_ratio, worst_ratio = result.theta_ratio, result.worst_ratio  # over every candidate: once, not per row
    L = [
        "## Pareto front (cost vs σθ/target vs worst η)",
        "",
        f"| cost ({result.spec.cost_unit}) | passes | images | σθ x, y, z (″) | σθ/target | worst η | meets | campaign |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for f in result.front[:25]:
        f = int(f)
        L.append(
            f"| {s.cost[f]:g} | {(result.candidates[f] >= 0).sum()} | {sum(p.images for p in result.passes(f))} | "
            f"{', '.join(f'{x:.2f}' for x in s.sigma_theta_arcsec[f])} | {theta_ratio[f]:.2f} | {rho_text(worst_ratio[f])} | "
            f"{'yes' if result.feasible[f] else 'no'}{' (chosen)' if f == c else ''} | {result.describe(f)} |"
        )
    if result.front.size > 25:
        L.append(f"| … {result.front.size - 25} more in front.ecsv | | | | | | | |")
    return L


def plot(result: PlanResult, path: Path) -> Path:
    """cost vs σθ/target and cost vs worst η: every candidate (20 000 of them at most), the front and
    the choice.

    DECISION (the figure was 1.1 of plan's 6 CPU s): a ``Figure`` without pyplot
    (``reporting.plots.figure``), the candidates as one rasterised marker line rather than a
    scatter collection, fixed margins rather than the constrained layout (which measured the
    20 000 points' extents) and the legends placed, not searched for a free corner."""
    from boresight.reporting.plots import figure

    s = result.scores
    rng = np.random.default_rng(0)
    C = s.cost.size
    sub = rng.choice(C, size=min(C, 20000), replace=False)
    ncols = 2 if result.spec.effects else 1
    fig = figure(figsize=(6 * ncols, 5.6))
    axes = fig.subplots(1, ncols, squeeze=False)
    fig.subplots_adjust(left=0.09 / ncols, right=0.99, bottom=0.33, top=0.93, wspace=0.22)
    at = "drawn at 10" + str(round(np.log10(NOT_SEPARABLE_RATIO))).translate(_SUPERSCRIPT)
    series = [("max σθ / target (dimensionless)", result.theta_ratio, f"σθ/target = ∞ (θ not determined), {at}")]
    if result.spec.effects:
        series.append(("worst nameable size / required (η, dimensionless)", result.worst_ratio, f"η = ∞ (not separable), {at}"))
    for ax, (lab, y_all, never_label) in zip(axes[0], series):
        # the candidates with an infinite (or ≥ 10⁴) ratio would vanish from a log axis (matplotlib skips
        # inf): both panels draw them as a row at the cap, marked and named, so that row is never
        # mistaken for measured values and no candidate is dropped silently
        never = y_all >= NOT_SEPARABLE_RATIO  # inf or ≥ the cap (NaN: dominated, not scored in full — not drawn)
        y = np.where(never, NOT_SEPARABLE_RATIO, y_all)
        shown = sub[~never[sub] & np.isfinite(y_all[sub])]
        unscored = int(np.isnan(y_all[sub]).sum())
        notes = ([f"a random {sub.size} of {C}"] if sub.size < C else []) + (
            [f"{unscored} of them dominated, not scored in full: not drawn"] if unscored else []
        )
        label = "candidates" + (f" ({'; '.join(notes)})" if notes else "")
        ax.plot(s.cost[shown], y[shown], "o", ms=2.8, mec="none", color="0.75", label=label, rasterized=True)
        if never[sub].any():
            cut = sub[never[sub]]
            ax.plot(s.cost[cut], y[cut], "x", ms=4, color="0.45", label=never_label, zorder=4)
        front = result.front
        ax.plot(s.cost[front[~never[front]]], y[front[~never[front]]], "o", ms=5, mec="none", color="C0", label="Pareto front")
        if never[front].any():  # hollow, so the × of the row at the cap shows through
            ax.plot(
                s.cost[front[never[front]]],
                y[front[never[front]]],
                "o",
                ms=7,
                mfc="none",
                mec="C0",
                label="Pareto front, at the cap",
            )
        if result.chosen is not None:
            ax.plot([s.cost[result.chosen]], [y[result.chosen]], "*", ms=14, mec="none", color="C3", label="chosen", zorder=5)
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
        _decade_labels(ax.yaxis)
        ax.set_xlabel(f"cost ({result.spec.cost_unit})")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=1)  # below the axes: off the data
    fig.suptitle(f"boresight plan: {result.spec.name}")
    save_figure(fig, path, dpi=110)
    return path


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _decade_labels(axis) -> None:
    """Log-axis labels 10⁻¹, 10⁰, 10¹ … in plain text (the default formatter builds them with
    mathtext, whose parser costs ~0.05 s to set up for one figure)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    def label(v, _pos):
        e = round(float(np.log10(v))) if v > 0 else None
        if e is not None and abs(np.log10(v) - e) < 1e-9:
            return "10" + str(e).translate(_SUPERSCRIPT)
        return f"{v:g}"

    axis.set_major_formatter(FuncFormatter(label))
    axis.set_minor_formatter(NullFormatter())


def write_outputs(result: PlanResult, out_dir, checks: dict | None = None, make_plot: bool = True) -> dict:
    """Write front.ecsv, chosen.toml (if any), plan.json, summary.md and plan.png (with matplotlib:
    ``reporting.plots.available``) into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    t = front_table(result)
    paths["front"] = out / "front.ecsv"
    write_table(t, paths["front"])
    if result.chosen is not None:
        doc = result.scenario_document(result.chosen)
        header = (
            f"Chosen by `boresight plan {result.spec.source}`: the cheapest campaign meeting every requirement.\n"
            f"Run it as is: boresight simulate {out / 'chosen.toml'} --out DIR\n"
            f"Predicted sigma_theta (effects floated) {_fmt3(result.scores.sigma_theta_arcsec[result.chosen])} arcsec."
        )
        paths["scenario"] = out / "chosen.toml"
        atomic_write_text(paths["scenario"], dumps(doc, header=header))
    w = None if result.chosen is None else why(result, result.chosen)  # once: plan.json and summary.md
    js = dict(_meta(result))
    js.update(
        {
            "format": "boresight-plan",
            "chosen": None
            if result.chosen is None
            else {
                "passes": [p.label for p in result.passes(result.chosen)],
                "cost": float(result.scores.cost[result.chosen]),
                "sigma_theta_arcsec": result.scores.sigma_theta_arcsec[result.chosen].tolist(),
                "sigma_theta_only_arcsec": result.scores.sigma_theta_only_arcsec[result.chosen].tolist(),
                "detectable_size": {n: result.detectable_size(result.chosen, n).tolist() for n in result.spec.effect_names},
                "rho": dict(zip(result.spec.effect_names, result.scores.detect_ratio[result.chosen].tolist())),
                "eta": None
                if result.scores.name_ratio is None
                else dict(zip(result.spec.effect_names, result.scores.name_ratio[result.chosen].tolist())),
                "p_name": None
                if result.scores.name_ratio is None
                else dict(zip(result.spec.effect_names, result.scores.name_probability[result.chosen].tolist())),
                "why": w,
            },
            "front_size": int(result.front.size),
            "timings_s": result.timings_s,
            "checks": checks,
        }
    )
    paths["json"] = out / "plan.json"
    write_json(paths["json"], js)
    paths["summary"] = out / "summary.md"
    atomic_write_text(paths["summary"], summary_text(result, checks, why_=w))
    from boresight.reporting.plots import available

    if make_plot and available():  # without matplotlib the plot is skipped, the rest written
        paths["plot"] = plot(result, out / "plan.png")
    return paths
