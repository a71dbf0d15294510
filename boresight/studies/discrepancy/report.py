"""The diagnosis report: a short summary, ``diagnosis.md``, ``diagnosis.json`` and PNG plots.

Plots show the residuals against the *decisive regressor* of each step — the structure probe
(:mod:`.structure`) whose likelihood-ratio statistic drops most when the step's effect is
added — before and after the step. Field regressors (image radius, position angle, image
scale by pass) show the field part of the residuals (each image's common rotation removed);
image regressors (time in pass, argument of latitude, pass, campaign time, attitude law) show each image's
common rotation.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from boresight.files import atomic_write_text, write_json
from boresight.reporting.outputs import save_figure
from boresight.studies.discrepancy.linear import SEPARABILITY_RHO

__all__ = ["summary_text", "write_report", "decisive_regressor", "withdrawal_lines"]

_FIELD = ("image radius", "position angle", "image scale by pass")


def _fmt(v, unit=""):
    if v is None:
        return "—"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]" + (f" {unit}" if unit else "")
    return f"{v:.4g}" + (f" {unit}" if unit else "")


def _fmt_units(v, units) -> str:
    """Values with their units: one shared unit printed once (``[3.662, 9.218] m``), otherwise one
    unit per value (``[1.2 arcsec, 0.3 arcsec / d]``); a dimensionless ``1`` is not printed.
    ``units``: one unit string for all values, or one per value.

    >>> _fmt_units([3.662, 9.218], ["m", "m"])
    '[3.662, 9.218] m'
    >>> _fmt_units([1.2, 0.3], ["arcsec", "arcsec / d"])
    '[1.2 arcsec, 0.3 arcsec / d]'
    >>> _fmt_units(0.1483, "1")
    '0.1483'
    """
    if v is None:
        return "—"
    values = v if isinstance(v, (list, tuple)) else [v]
    us = [units] * len(values) if isinstance(units, str) else list(units or [""] * len(values))
    us = ["" if u in (None, "1") else str(u) for u in us]
    if len(set(us)) <= 1:
        return _fmt(v, us[0] if us else "")
    return "[" + ", ".join(_fmt(x, u) for x, u in zip(values, us)) + "]"


def _status(e) -> str:
    """The identifiability table's status: separability from the base model (θ and the nuisances),
    then what it is not separable from — the candidates (``confounded_with``) and the look-alikes its
    definition names (``look_alikes``: a per-pass star-tracker bias the noise model does not hold) whose
    correlation is above the same cut —, and why a ``not_separable`` effect whose correlation with θ is
    below the cut is so (undetectable in its physical range). A status is never read beside a correlation
    of 1 it does not mention.

    One rule: a correlation ρ > ``linear.SEPARABILITY_RHO`` is "not separable" — the rule by which
    ``linear`` keeps a direction separable from the base model (ρ ≤ the cut) and ``naming`` fills
    ``confounded_with``; the look-alikes are held to the same comparison here.

    >>> _status({"status": "separable", "max_corr_candidates": {}, "look_alikes": {"per-pass star-tracker bias": 0.9999}})
    'separable from θ; not from per-pass star-tracker bias (ρ 1.000)'
    >>> _status({"status": "separable", "max_corr_candidates": {}, "look_alikes": {"per-pass star-tracker bias": 0.5}})
    'separable'
    """
    s = str(e["status"])
    if s == "not_separable" and e.get("separable_rank", 0) > 0:
        s += " (undetectable in its physical range)"
    conf = {m: e["max_corr_candidates"][m] for m in e.get("confounded_with") or []}
    conf.update({m: r for m, r in (e.get("look_alikes") or {}).items() if r > SEPARABILITY_RHO and m not in conf})
    if conf:
        against = ", ".join(f"{m} (ρ {r:.3f})" for m, r in conf.items())
        # "separable" alone beside a ρ of 1.000 reads as a contradiction: say from what it is separable
        s += f" from θ; not from {against}" if s in ("separable", "partially separable") else f"; nor from {against}"
    return s


def summary_text(d) -> str:
    """A few lines: what was named, what is ambiguous / not separable, θ before and after."""
    lines = []
    det = d.details
    st0 = det.get("base_state")
    if st0 is not None:
        th0 = st0.theta_arcsec()
        lines.append(
            f"base fit        θ = {_fmt(list(th0))} arcsec, χ²/dof = {st0.base.chi2_dof:.3f} (p = {st0.base.p_value:.2g})"
        )
    failed = [t.name for t in det.get("base_tests", []) if t.rejected]
    lines.append(
        "residual tests  "
        + ("fail: " + ", ".join(failed) if failed else "pass (Holm, family-wise α = %g)" % det.get("alpha", 0.01))
    )
    if d.steps:
        for i, s in enumerate(d.steps, 1):
            lines.append(
                f"step {i}          named {s['effect']} = {_fmt(s['estimate'])} ± {_fmt_units(s['sigma'], s['unit'])}"
                f" (Δχ² = {s['statistic']:.1f}, p = {s['p_value']:.2g}); χ²/dof {s['chi2_dof_before']:.3f} → {s['chi2_dof_after']:.3f}"
                + (
                    f"; at the gap after pass {s['after_pass']} (t = {s['boundary_s']:.0f} s; best of {s['boundaries_scanned']} "
                    "scanned, p × that number)"
                    if "boundary_s" in s
                    else ""
                )
            )
    else:
        lines.append("named           nothing")
    fin = getattr(d, "named_final", None) or []
    final_state = det.get("final_state")
    if len(fin) > 1 or (fin and final_state is not None and len(final_state.named) > len(fin)):
        # each step's value is at its naming; the effects' values are those of the final joint fit
        parts = []
        for f in fin:
            parts.append(f"{f['effect']} = {_fmt(f['estimate'])} ± {_fmt_units(f['sigma'], f['unit'])}")
        lines.append("final fit       " + "; ".join(parts) + " (jointly with θ; a step's value is at its naming)")
    lines += withdrawal_lines(d)
    for a in d.ambiguous:
        lines.append(f"ambiguous       {' vs '.join(a['effects'])}: {a['would_split']}")
    for n in getattr(d, "not_decisive", []):
        lines.append(not_decisive_text(n))
    for n in d.not_separable:
        lines.append(
            f"not separable   {n['effect']} (θ shift at a typical size {_fmt(n['theta_shift_arcsec'], 'arcsec')}); separated by: {n['would_separate']}"
        )
    nv = [e["effect"] for e in d.identifiability if e["status"] == "needs velocity"]
    if nv:
        lines.append(f"needs velocity  {', '.join(nv)}")
    lines += power_lines(d)
    if d.unexplained_structure:
        bad = [t.name for t in det.get("final_tests", []) if t.rejected]
        if getattr(d, "not_decisive", []):
            # the catalogue is not silent: the evidence for a candidate is short (rule.py)
            who = ", ".join(n["effect"] for n in d.not_decisive)
            lines.append(f"UNEXPLAINED     structure remains ({', '.join(bad)}); {who} significant, not decisive (above)")
        else:
            lines.append(f"UNEXPLAINED     structure remains that no candidate explains: {', '.join(bad)}")
    tl = getattr(d, "tails", None)
    if tl:
        lines.append(
            f"tails           excess kurtosis {tl['excess_kurtosis']:.2g} of {tl['n']} normalised residuals"
            f"{' (heavy)' if tl['heavy'] else ''}: {tl['loss']} kept — {tl['reason']}"
        )
    lines += variance_component_lines(d)
    lines.append(
        f"θ               {_fmt(d.theta_arcsec)} ± {_fmt(d.theta_sigma_arcsec)} arcsec (GLS under the noise model, named effects fitted)"
    )
    return "\n".join(lines)


def variance_component_lines(d) -> list:
    """The noise model's scales estimated from the data and carried into the names and θ's σ
    (workflow._diagnose_problem), or the failure to estimate them."""
    vc = getattr(d, "variance_components", None)
    if not vc:
        return []
    before = ", ".join(vc["named_before"]) or "nothing"
    was = (
        f"without it (χ²/dof = {vc['chi2_dof_before']:.3f}): named {before}, θ = {_fmt(vc['theta_before_arcsec'])} ± "
        f"{_fmt(vc['theta_sigma_before_arcsec'])} arcsec"
    )
    if vc.get("failed"):
        return [f"NOISE MODEL     the variance components could not be estimated: {vc['failed']}; {vc['note']}; {was}"]
    out = [
        "noise model     rejected by χ²; each source's scale estimated from the residuals (REML) and carried into the names and θ's σ:"
    ]
    out += [f"                {line}" for line in vc["lines"]]
    out.append(f"loss            {vc['loss']}: {vc['loss_reason']}")
    out.append(f"                {was}")
    return out


def _withdrawal_test(w) -> str:
    if w.get("statistic") is None:
        return "not testable"
    return f"Δχ²/scale = {w['statistic']:.1f} on {w['dof']} dof, p = {w['p_value']:.2g} vs α/K = {w['level']:.2g}"


def withdrawal_lines(d) -> list:
    """Terminal lines for the named effects withdrawn (or untestable) against unexplained structure."""
    out = []
    for w in getattr(d, "withdrawn", []) or []:
        tag = "withdrawn " if w["verdict"] == "withdrawn" else "untestable"
        out.append(f"{tag}      {w['effect']} ({_withdrawal_test(w)}): {w['reason']}; not named")
    # a name kept although the failing probes span it (naming.withdraw: kept by parsimony)
    for w in d.details.get("withdrawal_tests") or []:
        if w["verdict"] == "kept" and w.get("statistic") is None:
            out.append(f"kept            {w['effect']}: {w['reason']}")
    sh = d.details.get("theta_shift_after_withdrawal")
    if sh is not None and np.max(np.abs(sh["shift_sigma"])) > THETA_SHIFT_SIGMAS:
        z = np.asarray(sh["shift_sigma"])
        before = ", ".join(sh["named_before"]) or "nothing"
        out.append(
            f"CAUTION         θ differs from the fit before the withdrawals (named {before}: θ = {_fmt(sh['theta_before_arcsec'], 'arcsec')}) "
            f"by {_fmt([float(v) for v in z])} σ while residual tests still fail: θ depends on what the unexplained structure is"
        )
    return out


#: a θ shift after the withdrawals beyond this many σ is printed (``withdrawal_lines``)
THETA_SHIFT_SIGMAS = 3.0


def _withdrawal_markdown(d) -> list:
    tests = d.details.get("withdrawal_tests") or []
    if not tests:
        return []
    L = [
        "## Withdrawal tests",
        "",
        "The final model still failed a residual test, so each named effect was re-tested in a model that also carries the "
        "failing structure probes as free columns (reduced to a subset independent of the model and of each other), with its "
        "Δχ² divided by that model's χ²/dof when above 1. `withdrawn`: no longer significant at α/K; `untestable`: its "
        "signature lies inside the model and the unexplained structure, so the data cannot question it — neither is named.",
        "",
        "| effect | verdict | Δχ²/scale | dof | p | α/K | probes (independent columns, dependent dropped) | reason |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for w in tests:
        st = "—" if w["statistic"] is None else f"{w['statistic']:.4g}"
        p = "—" if w["p_value"] is None else f"{w['p_value']:.3g}"
        L.append(
            f"| {w['effect']} | {w['verdict']} | {st} | {w['dof']} | {p} | {w['level']:.3g} | "
            f"{', '.join(w['probes']) or 'none'} ({w['probe_columns']}, {w['probe_columns_dependent']} dropped) | {w['reason']} |"
        )
    return L + [""]


def not_decisive_text(n) -> str:
    """The verdict of a candidate significant at its Holm level but not decisive by BIC (rule.py)."""
    f = n.get("more_data_factor", float("inf"))
    more = f"about {f:.2g}× the data" if np.isfinite(f) else "more data"
    head = (
        f"not decisive    {n['effect']}: significant, p = {n['p_value']:.2g}, not decisive by BIC "
        f"(Δχ² = {n['statistic']:.1f} ≤ {n['bic_threshold']:.1f})\n"
    )
    if not n.get("explains_structure", True):
        # the data do not say more data would name it: structure remains beyond it (workflow._left_beyond_floated)
        return (
            head
            + f"                — but it leaves the structure the base fit showed ({n['structure_left']}): not its signature alone"
        )
    return head + f"                — more data would name it: {more} (or data that separate it, diagnosis.md)"


def _nameable_cell(e) -> str:
    """An identifiability entry's minimum nameable sizes, with the look-alikes that bind them in brackets."""
    if e.get("min_nameable") is None:
        return "—"
    rivals = sorted({r for r in e.get("nameable_rival") or () if r})
    return _fmt_units(e["min_nameable"], e["unit"]) + (f" ({', '.join(rivals)})" if rivals else "")


def undetectable(d) -> list:
    """(effect, parameter, smallest detectable size, typical size, unit, smallest nameable size, binding
    look-alike) for each tested effect (separable or partially separable, not named) the data could not
    have detected at its typical size: every parameter's minimum detectable size (the naming rule's
    two legs, ``rule.nameable_noncentrality``) exceeds its typical size. The parameter quoted is the
    one nearest to being detectable (smallest ratio); its nameable size (``min_nameable``: detected
    *and* not ambiguous with a look-alike, ``naming_power``) and the look-alike that binds it
    (None when none does) come with it."""
    out = []
    for e in d.identifiability:
        if e.get("status") not in ("separable", "partially separable") or e["effect"] in d.named:
            continue  # not separable / needs velocity: reported on their own lines
        mde, typ = e.get("min_detectable"), e.get("typical_size")
        if not mde or not typ:
            continue
        mde, typ = np.asarray(mde, float), np.asarray(typ, float)
        ratio = np.where(typ > 0, mde / np.where(typ > 0, typ, 1.0), np.inf)
        if not np.all(ratio > 1.0) or not np.any(np.isfinite(mde)):
            continue
        j = int(np.argmin(ratio))
        unit = e["unit"][j] if e.get("unit") else ""
        mn = e.get("min_nameable") or [float(mde[j])] * mde.size
        rival = (e.get("nameable_rival") or [None] * mde.size)[j]
        out.append(
            (
                e["effect"],
                e["parameters"][j],
                float(mde[j]),
                float(typ[j]),
                "" if unit in ("", "1") else unit,
                float(mn[j]),
                rival,
            )
        )
    return out


#: a nameable size this much above the detectable one is quoted beside it (below: the same size to the 2 digits printed)
NAMEABLE_QUOTED_ABOVE = 1.02


def _entry(d, name):
    """The identifiability entry of candidate ``name``."""
    return next(e for e in d.identifiability if e["effect"] == name)


def _never_named(e, rival) -> str:
    """The power line's clause for an effect with no finite nameable size."""
    if rival and rival in (e.get("confounded_with") or ()):
        return f", nor name it at any size: {rival} cannot be told from it"
    from boresight.studies.discrepancy.naming_power import SPAN

    return f", nor name it within {SPAN:g} times that" + (f": {rival} looks alike" if rival else "")


def power_lines(d) -> list:
    """The power statement of the summary: one line per effect the data could not have detected, with
    the larger size it would need to be *named* (not only detected) when a look-alike makes them differ."""
    lines = []
    for name, par, m, t, unit, n, rival in undetectable(d):
        what = name if par in ("scale", "k1", "kappa") or len(par) < 2 else f"{name} ({par})"
        u = f" {unit}" if unit else ""
        named = ""
        if not n <= NAMEABLE_QUOTED_ABOVE * m:
            why = f": {rival} looks alike" if rival else ""
            named = f", nor name it below {n:.2g}{u}{why}" if np.isfinite(n) else _never_named(_entry(d, name), rival)
        lines.append(f"low power       could not detect {what} below {m:.2g}{u}{named} (typical {t:.2g}{u})")
    return lines


def decisive_regressor(before_tests, after_tests) -> str:
    """The probe whose LR statistic drops most from ``before_tests`` to ``after_tests``."""
    a = {t.name: t.statistic for t in after_tests}
    best, drop = None, -np.inf
    for t in before_tests:
        if t.name in ("chi2", "normalised residuals", "whiteness") or t.name not in a:
            continue
        dd = t.statistic - a[t.name]
        if dd > drop:
            best, drop = t.name, dd
    return best or "image radius"


def _binned(x, y, nb=8):
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size == 0:
        return np.array([]), np.array([]), np.array([])
    ux = np.unique(x)
    if ux.size <= nb:
        centres = ux
        idx = np.searchsorted(ux, x)
    else:
        edges = np.quantile(x, np.linspace(0, 1, nb + 1))
        edges[-1] += 1e-12 * max(1.0, abs(edges[-1]))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, nb - 1)
        centres = np.array([x[idx == b].mean() if np.any(idx == b) else np.nan for b in range(nb)])
    m = np.array([y[idx == b].mean() if np.any(idx == b) else np.nan for b in range(centres.size)])
    s = np.array(
        [y[idx == b].std(ddof=1) / np.sqrt((idx == b).sum()) if (idx == b).sum() > 1 else np.nan for b in range(centres.size)]
    )
    return centres, m, s


#: regressors whose values are categories (drawn as categories, not on a continuous axis)
_CATEGORICAL = {"pass": None, "attitude law": ("nadir", "pointed")}


def _series(problem, state, regressor):
    """(x label, x values, {label: y values}, y label) for one state and regressor."""
    reg = problem.regressors
    omega, field = problem.split_residuals(state.cl.residual_xy_m, state.cl.G)
    if regressor in _FIELD:
        rad = reg["radius_m"]
        rh = np.column_stack([reg["x_m"], reg["y_m"]]) / np.where(rad > 0, rad, 1.0)[:, None]
        radial = np.einsum("ij,ij->i", field, rh) * 1e6
        tang = (field[:, 1] * rh[:, 0] - field[:, 0] * rh[:, 1]) * 1e6
        if regressor == "position angle":
            return (
                "position angle (deg)",
                np.degrees(reg["position_angle_rad"]),
                {"radial": radial, "tangential": tang},
                "field residual (µm)",
            )
        return "image radius (mm)", rad * 1e3, {"radial": radial, "tangential": tang}, "field residual (µm)"
    img = np.unique(reg["image"])
    per_img = {
        "time in pass": ("time in pass (s)", reg["t_in_pass_s"]),
        "argument of latitude": ("argument of latitude (deg)", np.degrees(reg["arg_latitude_rad"])),
        "pass": ("pass", reg["pass"].astype(float)),
        "campaign time": ("campaign time (days)", (reg["t_s"] - reg["t_s"].min()) / 86400.0),
        "attitude law": ("attitude law", (reg["attitude_law"].astype(str) != "nadir").astype(float)),
    }
    label, x = per_img.get(regressor, per_img["time in pass"])
    return label, x[img], {f"ω{a}": omega[img, i] for i, a in enumerate("xyz")}, "image common rotation (arcsec)"


def _plot_step(problem, before, after, regressor, title, path):
    from boresight.reporting.plots import figure

    fig = figure(figsize=(10, 3.8))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, st, tag in ((axes[0], before, "before"), (axes[1], after, "after")):
        xl, x, ys, yl = _series(problem, st, regressor)
        if regressor in _CATEGORICAL:
            # categories (pass index, attitude law): one position per category, the series side
            # by side, no line joining categories that have no order in between
            cats = np.unique(x[np.isfinite(x)])
            names = _CATEGORICAL[regressor] or [f"{int(v)}" for v in cats]
            pos = np.arange(cats.size)
            width = 0.6 / max(len(ys), 1)
            for j, (lab, y) in enumerate(ys.items()):
                m = np.array([np.mean(y[x == v]) for v in cats])
                s = np.array(
                    [np.std(y[x == v], ddof=1) / np.sqrt((x == v).sum()) if (x == v).sum() > 1 else np.nan for v in cats]
                )
                ax.errorbar(pos + (j - (len(ys) - 1) / 2) * width, m, yerr=s, fmt="o", ms=4, capsize=2, label=lab)
            ax.set_xticks(pos, [names[int(v)] if _CATEGORICAL[regressor] else names[i] for i, v in enumerate(cats)])
        else:
            for lab, y in ys.items():
                c, m, s = _binned(x, y)
                ax.errorbar(c, m, yerr=s, marker="o", ms=4, capsize=2, label=lab)
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set_xlabel(xl)
        ax.set_title(f"{tag}: χ²/dof = {st.base.chi2_dof:.3f}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(yl + ", bin mean ± s.e.")
    axes[1].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _plot_collocation(colloc, path):
    from boresight.reporting.plots import figure

    fig = figure(figsize=(5.5, 5))
    ax = fig.subplots()
    k = 1e3
    scale = max(np.abs(colloc.mean_xy_m).max(), 1e-30)
    for xy, color, label in (
        (colloc.mean_xy_m, "0.6", "cell mean field residual"),
        (colloc.h_xy_m, "C3", "collocation G X + h (Tang 2014)"),
    ):
        ax.quiver(colloc.x_m * k, colloc.y_m * k, xy[:, 0] / scale, xy[:, 1] / scale, color=color, angles="xy", label=label)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"unexplained field structure, rms {colloc.h_rms_m * 1e6:.2f} µm\n(longest arrow {scale * 1e6:.2f} µm)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_aspect("equal")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def write_report(d, out_dir, *, inputs=(), plots: bool = True) -> dict:
    """Write ``diagnosis.json``, ``diagnosis.md`` and the PNG plots into ``out_dir``; returns
    {kind: path}. Without matplotlib (``reporting.plots.available``) the plots are skipped and the
    rest is written (``paths["figures"]`` empty)."""
    from boresight.reporting.plots import available
    from boresight.studies.discrepancy.structure import residual_tests

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Any] = {}
    js = out / "diagnosis.json"
    write_json(js, d.as_json())
    paths["json"] = js
    det = d.details
    problem = det.get("problem")
    states = det.get("states", [])
    figs = []
    if plots and available() and problem is not None and hasattr(problem, "split_residuals"):
        alpha = det.get("alpha", 0.01)
        tests = det.get("state_tests") or [residual_tests(s.base, s.cl.probes, alpha) for s in states]
        for i, s in enumerate(d.steps):
            if i + 1 >= len(states):
                break
            regressor = decisive_regressor(tests[i], tests[i + 1])
            p = out / f"step{i + 1}_{s['effect']}.png"
            _plot_step(problem, states[i], states[i + 1], regressor, f"step {i + 1}: {s['effect']} — residuals vs {regressor}", p)
            figs.append((f"Step {i + 1}: {s['effect']}, residuals against {regressor}", p.name))
        if not d.steps and states:
            failed = [
                t
                for t in det.get("final_tests", [])
                if t.rejected and t.name not in ("chi2", "normalised residuals", "whiteness")
            ]
            regressor = max(failed, key=lambda t: t.statistic).name if failed else "image radius"
            p = out / "residuals.png"
            _plot_step(problem, states[0], states[-1], regressor, f"base model — residuals vs {regressor}", p)
            figs.append((f"Residuals of the base model against {regressor}", p.name))
        colloc = det.get("collocation")
        if colloc is not None:
            p = out / "unexplained_collocation.png"
            _plot_collocation(colloc, p)
            figs.append(("Unexplained structure: field residuals and the Tang 2014 collocation fit", p.name))
    md = out / "diagnosis.md"
    atomic_write_text(md, markdown(d, inputs, figs))
    paths["md"] = md
    paths["figures"] = [out / f for _, f in figs]
    return paths


def _not_decisive_markdown(d) -> list:
    if not getattr(d, "not_decisive", None):
        return []
    L = [
        "## Significant but not decisive",
        "",
        "Significant at their Holm level but Δχ² ≤ k ln n (BIC does not prefer the larger model): the data show "
        "the structure, not yet strongly enough to name it. θ and its σ above are from the model with these "
        "floated (unnamed).",
        "",
        "| candidate | Δχ² | dof | p | BIC threshold k ln n | data needed (≈×) | estimate | σ | separated by |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for n in d.not_decisive:
        L.append(
            f"| {n['effect']} | {n['statistic']:.2f} | {n['dof']} | {n['p_value']:.3g} | {n['bic_threshold']:.1f} | "
            f"{n['more_data_factor']:.2g} | {_fmt(n['estimate'])} | {_fmt(n['sigma'])} | {n['would_separate']} |"
        )
    return L + [""]


def markdown(d, inputs=(), figs=()) -> str:
    det = d.details
    L = ["# Diagnosis", ""]
    if inputs:
        L += ["Input: " + ", ".join(f"`{p}`" for p in inputs), ""]
    L += ["## Summary", "", "```", summary_text(d), "```", ""]
    L += [
        "## Residual tests of the base model",
        "",
        f"Holm step-down at family-wise α = {det.get('alpha', 0.01):g}; each test in the whitened GLS space (see docs/discrepancy.md).",
        "",
        "| test | statistic | dof | p | rejected |",
        "|---|---|---|---|---|",
    ]
    for t in det.get("base_tests", []):
        L.append(f"| {t.name} | {t.statistic:.4g} | {t.dof:g} | {t.p_value:.3g} | {'**yes**' if t.rejected else 'no'} |")
    L += [
        "",
        "## Identifiability on this data (before naming)",
        "",
        "Minimum detectable size: the size at which the naming rule's test — the LR test at α/K *and* ΔBIC < 0 "
        f"(`boresight/studies/discrepancy/rule.py`) — passes with power {det.get('power', 0.8):g} "
        "(non-central χ²): the effect is then reported, named or as ambiguous with a look-alike. "
        f"Minimum nameable size: the size at which it is *named* with power {det.get('power', 0.8):g} — detected and "
        "not ambiguous with another candidate that explains the data about as well "
        "(`boresight/studies/discrepancy/naming_power.py`); the look-alike that makes it larger than the detectable "
        "size is given in brackets.",
        "",
        "Status: separability from the base model (θ and the nuisances, canonical correlation ≤ "
        f"{SEPARABILITY_RHO:g}), then any candidate or look-alike the effect cannot be told from (correlation ρ above the same "
        'cut): "separable from θ; not from X (ρ 1.000)".',
        "",
        "| effect | status | marginal σ | max corr with θ | max corr with another candidate | look-alikes (canonical corr) | min detectable | min nameable | typical size |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for e in d.identifiability:
        mc = e.get("max_corr_candidates") or {}
        top = max(mc.items(), key=lambda kv: kv[1]) if mc else None
        la = ", ".join(f"{k} {v:.3f}" for k, v in (e.get("look_alikes") or {}).items()) or "—"
        L.append(
            f"| {e['effect']} | {_status(e)} | {_fmt_units(e['marginal_sigma'], e['unit'])} | {_fmt(e['max_corr_theta'])} | "
            f"{(top[0] + ' ' + format(top[1], '.3f')) if top else '—'} | {la} | {_fmt_units(e['min_detectable'], e['unit'])} | "
            f"{_nameable_cell(e)} | {_fmt_units(e['typical_size'], e['unit'])} |"
        )
    if det.get("rounds"):
        units = {e["effect"]: e["unit"] for e in d.identifiability}
        L += ["", "## Naming rounds", ""]
        for i, rd in enumerate(det["rounds"], 1):
            L += [
                f"Round {i} (χ²/dof {rd['chi2_dof']:.3f}):",
                "",
                "| candidate | Δχ² | dof | p | ΔBIC | estimate | σ |",
                "|---|---|---|---|---|---|---|",
            ]
            for c in rd["candidates"]:
                unit = units.get(c["effect"], "")
                L.append(
                    f"| {c['effect']} | {c['delta_chi2']:.2f} | {c['dof']} | {c['p_value']:.3g} | {c['delta_bic']:.1f} | "
                    f"{_fmt_units(c['estimate'], unit)} | {_fmt_units(c['sigma'], unit)} |"
                )
            L.append("")
    L += _withdrawal_markdown(d)
    if getattr(d, "variance_components", None):
        L += [
            "## Noise model: variance components",
            "",
            "The χ² test still failed after naming: the data reject the noise model's scales. The scale of each error source "
            "was estimated from the residuals of the final model by REML (`boresight.core.variance_components`) and the "
            "diagnosis above was redone under it (`variance_components` in diagnosis.json).",
            "",
            *[f"    {x.strip()}" for x in variance_component_lines(d)],
            "",
        ]
    L += _not_decisive_markdown(d)
    if det.get("rejected"):
        L += [
            "Rejected (fitted value outside the physical range): "
            + ", ".join(f"{r['effect']} = {_fmt(r['estimate'])}" for r in det["rejected"]),
            "",
        ]
    if d.unexplained_structure:
        L += ["## Unexplained structure", "", "Tests still rejected after the last step:", ""]
        for t in det.get("final_tests", []):
            if t.rejected:
                L.append(f"- {t.name}: {t.detail} (p = {t.p_value:.2g})")
        c = det.get("collocation")
        if c is not None:
            L += [
                "",
                f"Tang 2014 collocation of the field residuals on {c.x_m.size} image cells: smooth signal rms "
                f"{c.h_rms_m * 1e6:.3f} µm, reproducing {100 * c.explained:.0f} % of the cell means' sum of squares.",
            ]
        L.append("")
    if figs:
        L += ["## Figures", ""]
        for cap, f in figs:
            L += [f"![{cap}]({f})", "", f"*{cap}*", ""]
    return "\n".join(L)
