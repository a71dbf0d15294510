"""``boresight plan PLAN.toml [--out DIR] [--max-candidates N] [--mc-check RUNS] [--no-plots]``.

Plans a calibration campaign (``boresight.studies.planning``, ``docs/planning.md``): prints the chosen
campaign and its predicted σθ and detectable sizes, and writes ``DIR/front.ecsv`` (the Pareto
front), ``DIR/chosen.toml`` (a scenario ``boresight simulate`` runs as is), ``DIR/plan.png``,
``DIR/plan.json`` and ``DIR/summary.md``. ``--mc-check RUNS`` confirms the chosen campaign's σθ by
Monte Carlo (simulate + GLS estimate, RUNS runs) and writes the result into the summary.

Exit status: 0 when a campaign meets every requirement; ``EXIT_NO_CAMPAIGN`` (5, ``boresight.cli.exit_codes``) when none in
the search space does (the outputs are still written: the front shows the trade-offs).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from boresight.cli.exit_codes import EXIT_NO_CAMPAIGN  # 5: no campaign meets every requirement (outputs written)
from boresight.cli.options import SEED, effect_list
from orbits.errors import InputValueError


def register(sub):
    p = sub.add_parser("plan", help="plan a calibration campaign: what to fly for a target σθ and separable effects")
    p.add_argument("plan", type=Path, help="plan file (TOML; see docs/planning.md), or a shipped plan's name (kiev680)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default out/<plan name>-plan)")
    p.add_argument("--max-candidates", type=int, default=None, help="override [search] max_candidates")
    p.add_argument(
        "--mc-check",
        type=int,
        default=0,
        metavar="RUNS",
        help="Monte Carlo check of the chosen campaign's σθ with RUNS runs (default 0: none)",
    )
    p.add_argument("--seed", type=SEED, default=1, help="seed of the Monte Carlo check (default 1)")
    p.add_argument("--no-plots", "--no-plot", dest="no_plots", action="store_true", help="do not write plan.png")
    g = p.add_argument_group("a scenario with [[star_frames]] (its segments' subsets scored: docs/stars.md)")
    g.add_argument(
        "--effects",
        type=effect_list,
        default=None,
        metavar="NAMES",
        help="effects floated with θ when scoring the subsets, comma-separated (e.g. gnss_bias)",
    )
    g.add_argument(
        "--target-arcsec",
        type=float,
        default=None,
        help="star frames: report the fewest images that reach this worst σθ; a pushbroom scenario: search the rolls for the "
        "fewest strips that reach it",
    )
    ps = p.add_argument_group('a pushbroom scenario (kind = "pushbroom"): with --target-arcsec, the search over roll angles')
    ps.add_argument("--max-roll-deg", type=float, default=30.0, help="candidate rolls from -MAX to +MAX degrees (default 30)")
    ps.add_argument("--roll-step-deg", type=float, default=5.0, help="step of the candidate rolls, degrees (default 5)")
    ps.add_argument("--max-strips", type=int, default=4, help="largest number of strips in a campaign (default 4)")
    ps.add_argument(
        "--target-chip-arcsec", type=float, default=None, help="also require σ ≤ this of every floated chip offset (arcsec)"
    )
    p.set_defaults(func=run)


def _star_scenario(path: Any) -> bool:
    """True when ``path`` (a file or a shipped scenario's name) is a scenario TOML with ``[[star_frames]]``."""
    from orbits.files import read_toml
    from orbits.scenario import scenario_path
    from orbits.scenario_schema import ScenarioError

    try:
        p = scenario_path(path)
        return p.suffix == ".toml" and "star_frames" in read_toml(p, ScenarioError, "scenario")
    except ScenarioError:
        return False


def run_star_plan(args: Any) -> int:
    """``boresight plan SCENARIO.toml`` with star frames: every subset of its passes and star-frame segments scored by
    the GLS on rows (``studies.planning.segments``), with its cost in images."""
    import numpy as np

    import orbits
    from boresight.studies.planning.segments import cheapest, plan_segments

    sc = orbits.load_scenario(args.plan)
    effects = tuple(args.effects or ())
    subsets = plan_segments(sc, effects)
    print(f"scenario      {sc.name}: {sc.description}")
    print(
        "scored by     σθ of the GLS on the subset's rows (noise-free nominal campaign, the scenario's noise model)"
        + (f"; floated: {', '.join(effects)}" if effects else "")
    )

    def cells(v: Any) -> str:
        return (
            "        —        —        —" if v is None else "".join(f"{x:9.3f}" if np.isfinite(x) else f"{'inf':>9}" for x in v)
        )

    head = f"{'segments':<58}{'images':>7}{'σθx″':>9}{'σθy″':>9}{'σθz″':>9}"
    print(head + (f"  {'floated: σθx″':>9}{'y″':>9}{'z″':>9}" if effects else ""))
    for g in subsets:
        mark = " *" if g.best else "  "
        line = f"{', '.join(g.labels)[:56]:<56}{mark}{g.images:>7}{cells(g.sigma_theta_arcsec)}"
        print(line + (f"  {cells(g.sigma_theta_floated_arcsec):>27}" if effects else ""))
    print("* the best subset of its size (smallest worst σθ" + (", with the effects floated" if effects else "") + ")")
    if effects:
        print("— the floated effects are not determined by these rows (a position effect does not reach star rows)")
    from boresight.core.weighting import SEPARABLE_BY_STARS

    missing = [n for n in SEPARABLE_BY_STARS if n not in effects]
    if sc.passes and missing:  # landmark passes and star frames: estimate's default floats these (docs/stars.md)
        print(
            f"note          boresight estimate floats {', '.join(missing)} by default on star and landmark rows "
            f"(docs/stars.md, 'Fusion: the default'): --effects {','.join(missing)} scores the subsets that way"
        )
    if args.target_arcsec is not None:
        c = cheapest(subsets, args.target_arcsec)
        print(
            f"cheapest      no subset reaches {args.target_arcsec:g}″"
            if c is None
            else f"cheapest      {', '.join(c.labels)}: {c.images} images, worst σθ {c.score_arcsec:.3f}″ ≤ {args.target_arcsec:g}″"
        )
    return 0


def run(args) -> int:
    import numpy as np

    from boresight.cli import pushbroom_inputs as pb
    from boresight.studies.planning import plan
    from boresight.studies.planning.report import effect_values_text, rho_text, write_outputs

    if pb.is_pushbroom(args.plan):  # a pushbroom scenario: its strips' subsets scored (run_pushbroom below)
        return run_pushbroom(args)
    if _star_scenario(args.plan):  # a scenario with star frames: its segments' subsets scored (studies/planning/segments.py)
        return run_star_plan(args)

    if args.max_candidates is not None and args.max_candidates < 1:
        raise InputValueError(f"--max-candidates must be ≥ 1, got {args.max_candidates}")
    if args.mc_check < 0:
        raise InputValueError(f"--mc-check must be ≥ 0, got {args.mc_check}")
    from boresight.reporting.outputs import check_output_folder

    check_output_folder(args.out)  # before any work
    result = plan(args.plan, max_candidates=args.max_candidates)
    if args.out is None:
        args.out = Path("out") / f"{Path(str(args.plan)).stem}-plan"
    checks: dict[str, Any] | None = None
    check_line = None
    if args.mc_check and result.chosen is not None:
        from boresight.studies.planning.checks import sigma_check

        chk = sigma_check(result, result.chosen, runs=args.mc_check, seed=args.seed, floated=result.spec.effect_names)
        check_line = chk.text()
        checks = {"sigma": chk.as_dict(), "lines": [check_line]}
    from boresight.reporting.outputs import writing_outputs
    from boresight.reporting.plots import want_figures

    with writing_outputs():  # Ctrl-C/SIGTERM: the old set of files or the complete new one
        paths = write_outputs(result, args.out, checks=checks, make_plot=want_figures(not args.no_plots))
    s = result.scores
    n_star = sum(o.kind == "stars" for o in result.options)
    print(
        f"plan          {result.spec.source}: {len(result.options)} pass options"
        + (f" ({n_star} star-frame segments)" if n_star else "")
        + f", {result.candidates.shape[0]} of {result.space_size} campaigns scored in {result.timings_s['score_s']:.2f} s "
        f"(blocks {result.timings_s['blocks_s']:.2f} s)"
    )
    c = result.chosen
    if c is None:
        print("chosen        NONE: no campaign in the search space meets every requirement (see summary.md)")
        from boresight.studies.planning.report import unmet_requirements

        for line in unmet_requirements(result):  # which requirement failed
            print(f"unmet         {line}")
    else:
        print(f"chosen        cost {s.cost[c]:g} {result.spec.cost_unit}: {result.describe(c)}")
        print(
            f"sigma_theta   {np.array2string(s.sigma_theta_arcsec[c], precision=3)} arcsec (target "
            f"{list(result.spec.sigma_theta_arcsec)}; effects floated, nuisances marginalised)"
        )
        for j, n in enumerate(result.spec.effect_names):
            print(
                f"detectable    {n}: {effect_values_text(n, result.detectable_size(c, n))} (ρ = {rho_text(s.detect_ratio[c, j])})"
            )
            # the three naming arrays are set together (fisher: name_ratio, name_probability, canonical_rho)
            if s.name_ratio is not None and s.name_probability is not None and s.canonical_rho is not None:
                print(
                    f"named         {n}: probability {s.name_probability[c, j]:.3f} at the required size (η = {rho_text(s.name_ratio[c, j])}; "
                    f"canonical ρ {s.canonical_rho[c, j]:.4f})"
                )
        if check_line is not None:
            print(f"check         {check_line}")
    print(f"front         {result.front.size} campaigns")
    for k, v in paths.items():
        print(f"wrote         {v}")
    if c is None:
        import sys

        from boresight.studies.planning.report import unmet_requirements

        print(f"boresight plan: no campaign meets every requirement (exit 5): {unmet_requirements(result)[0]}", file=sys.stderr)
    return 0 if c is not None else EXIT_NO_CAMPAIGN


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight plan PUSHBROOM.toml``: every subset of the scenario's strips scored by its σ; with ``--target-arcsec``
    the search over roll angles for the fewest strips meeting it (``studies.planning.line_scan``)."""
    from boresight.cli import pushbroom_inputs as pb
    from orbits.strip import load_strip_scenario

    if args.target_arcsec is not None:
        return _run_roll_plan(args)
    from boresight.studies.planning.line_scan import plan_strips

    sc = load_strip_scenario(args.plan)
    subsets = plan_strips(sc, args.seed)
    names = subsets[0].names
    print(f"scenario      {sc.name}: {sc.description}")
    print(f"unknowns      {', '.join(pb.labels(names))} (σ from the GLS on rows at a noise-free draw, seed {args.seed})")
    print(
        "strips (rolls)                     worst σθ″  "
        + "  ".join(f"{n[:18]:>18}" for n in pb.labels(names[3:]))
        + "  corr(θy, δt)"
    )
    for g in subsets:
        rolls = ", ".join(f"{r:+g}°" for r in g.rolls_deg)
        cells = "  ".join(f"{pb.sigma_text(n, s):>18}" for n, s in zip(names[3:], g.sigma[3:]))
        mark = " *" if g.best else "  "
        print(
            f"{str(list(g.strips)) + ' (' + rolls + ')':<34}{mark}{g.worst_theta_arcsec:8.3f}  {cells}  {g.corr_pitch_time:11.6f}"
        )
    print("* the best subset of its size (smallest worst σ of θ)")
    print("search        give --target-arcsec (and --target-chip-arcsec) to search the roll angles for the fewest strips")
    return 0


def _roll_lines(plan: Any, sc: Any) -> list[str]:
    """The printed (and summary.md) lines of a roll search."""
    import numpy as np

    from boresight.cli import pushbroom_inputs as pb

    c0 = sc.strips[0]
    cands = plan.candidates
    rolls = [c.roll_deg for c in cands]
    n_scored = len(plan.campaigns)
    out = [
        f"scenario      {sc.name}: {sc.description}",
        f"candidates    {len(cands)} strips at rolls {min(rolls):+g}° … {max(rolls):+g}° "
        f"({', '.join(f'{r:+g}' for r in rolls)}), each the first strip's: site {c0.site_lat_deg:g} N {c0.site_lon_deg:g} E, "
        f"{c0.epoch} UTC, {c0.n_lines} lines, {sc.layout.n_gcps} GCPs ({min(c.n_detections for c in cands)}-"
        f"{max(c.n_detections for c in cands)} detections); noise-free draw, seed {plan.seed}",
        f"noise         {sc.sigma_pixel_px:g} px on line and column; star tracker {sc.tracker.sigma_white_arcsec:g}″ white per sample",
        f"unknowns      {', '.join(pb.labels(plan.names))} (information from the GLS on rows, summed over strips)",
        f"requirement   {plan.requirement_text()}; campaigns of 1 to {plan.max_strips} strips, a roll may be flown on several "
        f"days ({n_scored} scored)",
        "best of each size (rolls)       worst σθ″  "
        + "  ".join(f"{n[:18]:>18}" for n in pb.labels(plan.names))
        + "  corr(θy, δt)  meets",
    ]
    for b in plan.best:
        cells = "  ".join(f"{pb.sigma_text(n, s):>18}" for n, s in zip(plan.names, b.sigma))
        rl = ", ".join(f"{r:+g}°" for r in b.rolls_deg)
        corr = f"{b.corr_pitch_time:12.6f}" if np.isfinite(b.corr_pitch_time) else f"{'—':>12}"
        out.append(f"  {b.n_strips}: {rl:<26}{b.worst_theta_arcsec:9.3f}  {cells}  {corr}  {'yes' if b.meets else 'no'}")
    c = plan.chosen
    if c is None:
        out.append(f"chosen        NONE: no campaign of at most {plan.max_strips} strips meets {plan.requirement_text()}")
        return out
    rl = ", ".join(f"{r:+g}°" for r in c.rolls_deg)
    chip = plan.worst_chip_arcsec(c)
    out.append(
        f"chosen        {c.n_strips} strips at rolls {rl} (strip k on day k): largest σθ {c.worst_theta_arcsec:.3f}″"
        + (f", largest σ of the chip offsets {chip:.4f}″" if np.isfinite(chip) else "")
        + (f", corr(θy, δt) {c.corr_pitch_time:.6f}" if np.isfinite(c.corr_pitch_time) else "")
        + (f", largest |corr| of a chip offset with θ {c.corr_chip_theta:.3f}" if np.isfinite(c.corr_chip_theta) else "")
    )
    for n, s in zip(plan.names, c.sigma):
        out.append(f"  {pb.label(n):<22} σ {pb.sigma_text(n, s)}")
    return out


def _check_lines(chk: Any) -> list[str]:
    from boresight.cli import pushbroom_inputs as pb

    out = [
        f"check         Monte Carlo of chosen.toml: {chk.runs} runs (seed {chk.seed}; run k from default_rng([seed, k])), "
        f"each simulated with the scenario's noise and fitted by estimate_line_scan; the scatter's "
        f"{100 * chk.level:.2f} % interval (Bonferroni over {len(chk.names)} unknowns)"
    ]
    for j, n in enumerate(chk.names):
        out.append(
            f"  {pb.label(n):<22} predicted σ {pb.sigma_text(n, chk.predicted[j]):>16}   scatter {pb.sigma_text(n, chk.scatter[j]):>16} "
            f"(interval {pb.sigma_text(n, chk.low[j]).split()[0]}-{pb.sigma_text(n, chk.high[j])})   mean reported σ "
            f"{pb.sigma_text(n, chk.reported[j])}"
        )
    out.append(
        "verdict       "
        + (
            "agrees: every predicted σ is inside its interval"
            if chk.agrees
            else "DISAGREES: a predicted σ is outside its interval"
        )
    )
    return out


def _run_roll_plan(args: Any) -> int:
    """``boresight plan PUSHBROOM.toml --target-arcsec X``: the roll search, printed and written to ``--out``."""
    from astropy.table import Table

    from boresight.cli.exit_codes import EXIT_NO_CAMPAIGN
    from boresight.files import atomic_write_text, write_json, write_table
    from boresight.reporting.outputs import check_output_folder, writing_outputs
    from boresight.studies.planning.line_scan import chosen_document, plan_rolls, roll_check, roll_grid
    from boresight.studies.planning.toml_out import dumps
    from orbits.files import read_toml
    from orbits.scenario import scenario_path
    from orbits.scenario_schema import ScenarioError
    from orbits.strip import load_strip_scenario

    if args.mc_check < 0:
        raise InputValueError(f"--mc-check must be ≥ 0, got {args.mc_check}")
    if args.mc_check == 1:
        raise InputValueError("--mc-check needs at least 2 runs for a scatter, got 1")
    check_output_folder(args.out)
    sc = load_strip_scenario(args.plan)
    rolls = roll_grid(args.max_roll_deg, args.roll_step_deg)
    plan = plan_rolls(sc, rolls, args.max_strips, args.target_arcsec, args.target_chip_arcsec, args.seed)
    lines = _roll_lines(plan, sc)
    print("\n".join(lines))
    out = Path("out") / f"{sc.name}-plan" if args.out is None else Path(args.out)
    doc = None
    check = None
    if plan.chosen is not None:
        doc = chosen_document(read_toml(scenario_path(args.plan), ScenarioError, "scenario"), plan, plan.chosen)
        if args.mc_check:
            check = roll_check(doc, plan, plan.chosen, args.mc_check, args.seed)
            more = _check_lines(check)
            print("\n".join(more))
            lines += more
    t = Table(
        dict(
            n_strips=[c.n_strips for c in plan.campaigns],
            rolls_deg=[" ".join(f"{r:g}" for r in c.rolls_deg) for c in plan.campaigns],
            worst_sigma_theta_arcsec=[c.worst_theta_arcsec for c in plan.campaigns],
            corr_pitch_time=[c.corr_pitch_time for c in plan.campaigns],
            corr_chip_theta=[c.corr_chip_theta for c in plan.campaigns],
            meets=[c.meets for c in plan.campaigns],
            **{f"sigma_{n}": [c.sigma[j] for c in plan.campaigns] for j, n in enumerate(plan.names)},
        )
    )
    t.meta.update(scenario=sc.name, requirement=plan.requirement_text(), seed=int(args.seed), units="sigma_* in SI (rad, s, 1)")
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    with writing_outputs():
        paths.append(write_table(t, out / "campaigns.ecsv"))
        if doc is not None:
            paths.append(atomic_write_text(out / "chosen.toml", dumps(doc, header=f"planned by boresight plan {sc.name}")))
        payload = dict(
            scenario=sc.name,
            requirement=dict(target_theta_arcsec=plan.target_theta_arcsec, target_chip_arcsec=plan.target_chip_arcsec),
            rolls_deg=list(rolls),
            max_strips=plan.max_strips,
            names=plan.names,
            chosen=None
            if plan.chosen is None
            else dict(
                rolls_deg=list(plan.chosen.rolls_deg),
                sigma=plan.chosen.sigma.tolist(),
                corr_pitch_time=plan.chosen.corr_pitch_time,
                corr_chip_theta=plan.chosen.corr_chip_theta,
            ),
            best=[dict(rolls_deg=list(b.rolls_deg), sigma=b.sigma.tolist(), meets=b.meets) for b in plan.best],
            check=None if check is None else check.as_dict(),
        )
        paths.append(write_json(out / "plan.json", payload))
        paths.append(atomic_write_text(out / "summary.md", "```\n" + "\n".join(lines) + "\n```\n"))
    for p in paths:
        print(f"wrote         {p}")
    if plan.chosen is None:
        import sys

        print(f"boresight plan: no campaign meets {plan.requirement_text()} (exit 5)", file=sys.stderr)
        return EXIT_NO_CAMPAIGN
    return 0
