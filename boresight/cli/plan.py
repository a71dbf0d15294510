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

    from boresight.cli import line_scan
    from boresight.studies.planning import plan
    from boresight.studies.planning.report import effect_values_text, rho_text, write_outputs

    if line_scan.is_pushbroom(args.plan):  # a pushbroom scenario: its strips' subsets scored (cli/line_scan.py)
        return line_scan.run_plan(args)
    if _star_scenario(args.plan):  # a scenario with star frames: its segments' subsets scored (studies/planning/segments.py)
        return run_star_plan(args)

    if args.max_candidates is not None and args.max_candidates < 1:
        raise ValueError(f"--max-candidates must be ≥ 1, got {args.max_candidates}")
    if args.mc_check < 0:
        raise ValueError(f"--mc-check must be ≥ 0, got {args.mc_check}")
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
        print(f"chosen        cost {s.cost[c]:g}: {result.describe(c)}")
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
