"""``boresight montecarlo SCENARIO.toml [--runs N] [--algorithm all] [--seed S] [--out DIR] ...``.

Runs the Monte Carlo study of ``boresight.studies.montecarlo`` with a progress bar (stderr), prints a
summary table and writes to DIR (default ``out/<scenario name>``):

* ``montecarlo.ecsv`` — σθ, its χ² interval, mean and max |θ error| per algorithm and number
  of images (arcsec, astropy ``Table`` with units);
* ``montecarlo.json`` — every input: the scenario (as a dict), seed, runs, chunk and block
  sizes, engine, versions of python/numpy/scipy/astropy/boresight;
* ``theta_error_histograms.png`` and ``sigma_vs_images.png`` (matplotlib, if installed).

Reliability (``docs/reliability.md``): the folder is locked while the study runs (a second
study on it is refused, naming the holder's pid); finished blocks of runs are checkpointed in
``DIR/.checkpoint`` as they complete, and ``--resume`` continues a killed study to files
identical to an uninterrupted run; every file is written to a temporary name and renamed.
Exit status 0, or ``EXIT_NOT_CONVERGED`` (3) when some runs' Gauss-Newton did not converge
(counted in the table's ``unconverged_runs`` and printed).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from boresight.cli.noise_options import OVERRIDE_OPTIONS, add_noise_model_args
from boresight.cli.options import (
    SEED,
    add_engine_arguments,
    add_loss_argument,
    add_resume_argument,
    add_strip_argument,
    check_engine_arguments,
    effect_list,
    study_options,
)
from boresight.core import registry
from boresight.files import write_json, write_table
from boresight.reporting.plots import plot_histograms, plot_sigma_vs_images  # noqa: F401 (re-exported)
from boresight.reporting.provenance import scenario_dict, study_payload, versions  # noqa: F401 (re-exported)


def register(sub):
    p = sub.add_parser("montecarlo", help="Monte Carlo accuracy study of the θ estimators")
    p.add_argument(
        "scenario",
        type=Path,
        help="scenario TOML file (see scenarios/), or an observation file FILE.ecsv: a study on the "
        "file's own geometry and noise model (its reported σ against the Monte Carlo scatter)",
    )
    p.add_argument("--runs", type=int, default=45000, help="Monte Carlo runs (default 45000 = required_runs(0.9973, 0.01))")
    add_strip_argument(p)
    p.add_argument(
        "--algorithm",
        action="append",
        default=None,
        help=f"{', '.join(registry.montecarlo_names())}, least_squares or all (repeatable; default all); "
        "kalman_theta is the θ-only study filter ('kalman', the library's filter, has no Monte Carlo kernel)",
    )
    p.add_argument("--seed", type=SEED, default=1, help="random seed (default 1)")
    p.add_argument(
        "--weighting",
        choices=("unit", "diagonal", "gls"),
        default=None,
        help="least-squares weighting of every run (default unit for a scenario: eqs 18/22/31 as printed, gls for a FILE.ecsv); diagonal or gls "
        "estimate each run as `boresight estimate` does with the scenario's noise model, and compare the "
        "sample σ with the σ the estimator reports (kalman_theta always uses the noise model)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default out/<scenario name>)")
    add_engine_arguments(p)
    p.add_argument(
        "--image-counts",
        type=int,
        nargs="+",
        default=None,
        help="numbers of images to estimate with (default 1 2 4 8 12 20 ≤ N, and N)",
    )
    p.add_argument("--beta", type=float, default=0.9973, help="confidence level of the σ intervals (default 0.9973)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="no pre-flight line, progress bar or heartbeat (results are still printed)"
    )
    add_resume_argument(p)
    g = p.add_argument_group("a study on an observation file (FILE.ecsv)")
    g.add_argument(
        "--effects",
        dest="effects",
        type=effect_list,
        default=None,
        metavar="NAMES",
        help="effects fitted jointly with θ in every refit, comma-separated (as boresight estimate --effects; docs/effects.md)",
    )
    add_loss_argument(g, "robust loss of every refit (as boresight estimate --loss)")
    add_noise_model_args(p, title="noise model of FILE.ecsv (each option overrides the file's own)")
    p.set_defaults(func=run)


#: the options that only a study on an observation file takes (refused with a scenario)
FILE_ONLY = {
    "strip": "--strip",
    "effects": "--effects",
    "loss": "--loss",
    **OVERRIDE_OPTIONS,
}


#: the widest line the command prints (file paths, which are never broken, excepted)
WIDTH = 100

_WHAT = {
    "unit": "unit weighting (Kiev 2012 eqs 18/22/31)",
    "diagonal": "diagonal weighting (1/total variance of each residual under the scenario's noise model)",
    "gls": "GLS under the scenario's noise model (boresight.estimate's block-sparse campaign GLS)",
}
_PREDICTED = {
    "unit": "linear propagation at the noise-free nominal geometry (the estimator's sandwich covariance)",
    "diagonal": "the sandwich covariance the estimator reports (√ of its mean variance over the runs)",
    "gls": "the GLS covariance the estimator reports (√ of its mean variance over the runs)",
}


def wrap(text: str, indent: str = "  ") -> str:
    """``text`` folded to ``WIDTH`` columns at spaces (words, e.g. file paths, are never broken)."""
    import textwrap

    return "\n".join(
        textwrap.fill(line, WIDTH, subsequent_indent=indent, break_long_words=False, break_on_hyphens=False) or line
        for line in text.split("\n")
    )


def _num(v: float, decimals: int = 3) -> str:
    """A number in at most 10 characters: fixed point, or 4 significant digits when large."""
    v = float(v)
    return f"{v:.{decimals}f}" if abs(v) < 1e5 or not np.isfinite(v) else f"{v:.3e}"


def summary(result, beta) -> str:
    """The terminal summary (lines ≤ ``WIDTH`` columns): what was estimated and what σ means, σθ per
    axis, total, max |θ error|; the χ² interval factor; σ against the estimator's own prediction."""
    from boresight.studies.montecarlo import achieved_epsilon, required_runs, sigma_interval

    t = result.table(beta)
    weighting = getattr(result, "weighting", "unit")
    lines = [wrap(f"θ̂ − θ over {result.runs} runs of {result.scenario_name}; least squares: {_WHAT[weighting]}")]
    if "kalman_theta" in result.algorithms:
        lines.append("kalman_theta: the θ-only filter, weighted by the noise model")
    lines += [
        wrap("σθ = sample σ of θ̂ − θ over the runs: the accuracy of one such estimate (what a quoted σ should be)"),
        f"{'algorithm':<13}{'images':>6}{'σθx″':>10}{'σθy″':>10}{'σθz″':>10}{'total″':>10}  {'max|err|x″':>11}{'y″':>8}{'z″':>8}",
    ]
    for row in t:
        sig = "".join(f"{_num(row[f'sigma_theta_{a}']):>10}" for a in "xyz")
        mx = f"{_num(row['max_abs_theta_x'], 1):>11}" + "".join(f"{_num(row[f'max_abs_theta_{a}'], 1):>8}" for a in "yz")
        lines.append(f"{row['algorithm'][:12]:<13}{row['n_images']:>6}{sig}{_num(row['sigma_theta_total']):>10}  {mx}")
    lo, hi = sigma_interval(np.ones(1), result.runs, beta)
    eps = achieved_epsilon(result.runs, beta)
    lines.append(
        wrap(
            f"{100 * beta:g} % χ² interval of each σθ: [{lo[0]:.3f}, {hi[0]:.3f}] × σθ; "
            f"achieved ε = {eps:.4f} (0.01 needs {required_runs(beta, 0.01)} runs)"
        )
    )
    lines += _comparison(result, beta, lo[0], hi[0])
    lines.append(f"runs {result.runs} (seed {result.seed}, blocks of {result.block_runs}); {result.elapsed_s:.2f} s")
    return "\n".join(lines)


def _comparison(result, beta, lo, hi) -> list:
    """σθ against the estimator's own predicted σ, per least-squares algorithm and image count.

    The ratio sample/predicted is flagged ``*`` outside the χ² interval of a sample σ at β
    (σθ/σ_pred ∈ [1/hi, 1/lo] when the prediction is the true σ)."""
    weighting = getattr(result, "weighting", "unit")
    pred = {}
    for a in result.algorithms:
        p = result.reported_sigma_arcsec(a) if weighting != "unit" else getattr(result, "predicted", {}).get(a)
        if p is not None:
            pred[a] = p
    if not pred:
        return []
    lines = [
        wrap(f"predicted σ: {_PREDICTED[weighting]}"),
        wrap(
            f"ratio = σθ / predicted σ; * = outside its {100 * beta:g} % χ² interval [{1 / hi:.3f}, {1 / lo:.3f}] "
            f"(1 in {1 / (1 - beta):.0f} by chance)"
        ),
        f"{'algorithm':<13}{'images':>6}{'pred σθx″':>11}{'y″':>9}{'z″':>9}{'ratio x':>10}{'y':>8}{'z':>8}",
    ]
    for a, p in pred.items():
        sd = result.sigma_arcsec(a)
        for j, k in enumerate(result.image_counts):
            cells = f"{_num(p[j, 0]):>11}{_num(p[j, 1]):>9}{_num(p[j, 2]):>9}"
            r = sd[j] / p[j]
            flags = ["*" if not (1 / hi <= v <= 1 / lo) else " " for v in r]
            ratios = f"{r[0]:>9.3f}{flags[0]}" + "".join(f"{v:>7.3f}{f}" for v, f in zip(r[1:], flags[1:]))
            lines.append(f"{a[:12]:<13}{k:>6}{cells}{ratios}".rstrip())
    return lines


def _plot_atomic(fn, path: Path, *args):
    from boresight.files import atomic_path

    with atomic_path(path) as tmp:
        fn(*args[:1], tmp, *args[1:])
    return path


def run(args) -> int:
    import orbits
    from boresight.cli.exit_codes import EXIT_NOT_CONVERGED, EXIT_OK
    from boresight.reporting.outputs import inside, output_folder, writing_outputs
    from boresight.studies import montecarlo as mc
    from boresight.studies.montecarlo.checkpoint import resumed_line, study_folder

    check_engine_arguments(args)
    if getattr(args, "engine", None) == "dask":  # a missing extra: refused before the output folder exists
        from boresight.studies.montecarlo.engines import require_dask

        require_dask()
    routed = _other_input(args)
    if routed is not None:
        return routed
    from boresight.errors import StudyError

    for dest, opt in FILE_ONLY.items():
        if getattr(args, dest, None) is not None:
            raise StudyError(
                f"{opt} applies to a study on an observation file (FILE.ecsv); {args.scenario} is a scenario: "
                "its noise model is the scenario's"
            )
    if args.weighting is None:
        args.weighting = "unit"
    scenario = orbits.load_scenario(args.scenario)
    from boresight.cli.noise_options import warn_scenario_unit_slips

    warn_scenario_unit_slips(scenario, "montecarlo")
    out = output_folder(args.out if args.out is not None else inside(Path("out"), scenario.name))
    with study_folder(out, "montecarlo") as ckpt:
        progress = (
            None
            if args.quiet
            else mc.ProgressBar(label=scenario.name + ("" if args.weighting == "unit" else f" ({args.weighting})"))
        )
        result = mc.montecarlo_study(
            scenario,
            args.algorithm or ["all"],
            image_counts=args.image_counts,
            beta=args.beta,
            weighting=args.weighting,
            **study_options(args, progress, ckpt),
        )
        with writing_outputs():  # Ctrl-C/SIGTERM: the old set of files or the complete new one
            written, notes = _write_products(args, scenario, result, out)
    print(summary(result, args.beta))
    if scenario.name == "kiev2012-sensitivity":
        from boresight.reproductions.kiev2012.published import SEMINAR_EQ28_SIGMA_ARCSEC as s

        print(
            wrap(f"seminar (Kiev 2012 eq 28): σθ = {s[0]}″ / {s[1]}″ / {s[2]}″, total {s[3]}″ (one image: docs/reproduction.md)")
        )
    resumed = resumed_line(result, ckpt)
    if resumed:
        print(wrap(resumed))
    for n in result.notes:
        print(wrap(f"note: {n}"))
    for p in written:
        print(f"wrote {p}")
    for n in notes:
        print(wrap(n))
    if result.any_unconverged:
        for name, nc in result.unconverged.items():
            for k, c in zip(result.image_counts, nc):
                if c:
                    print(
                        wrap(
                            f"warning: {name} with {k} image(s): {int(c)} of {result.runs} runs did not converge in "
                            f"{result.inputs['max_iterations']} Gauss-Newton iterations (kept in the statistics)"
                        )
                    )
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _other_input(args) -> int | None:
    """A study on an observation file (``run_file``) or on a pushbroom scenario (``run_pushbroom`` below: strips fitted on
    rows run by run); None for a frame scenario."""
    if Path(args.scenario).suffix.lower() == ".ecsv":
        return run_file(args)
    from boresight.cli import pushbroom_inputs as pb

    if pb.is_pushbroom(args.scenario):
        return run_pushbroom(args)
    return None


def run_file(args) -> int:
    """``boresight montecarlo FILE.ecsv``: the file's own geometry and noise model
    (``boresight.studies.montecarlo.file_study``); prints the reported σ against the scatter."""
    import argparse

    from boresight.cli.exit_codes import EXIT_OK
    from boresight.cli.noise_options import model_from_args
    from boresight.errors import StudyError
    from boresight.observations.flight.culprit import read_checked_naming_inputs as read_checked  # names input slips
    from boresight.studies import montecarlo as mc
    from boresight.studies.montecarlo.file_study import file_study

    path = Path(args.scenario)
    if not path.exists():
        raise FileNotFoundError(f"no such observation file: {path}")
    for opt in ("image_counts", "chunk_runs", "block_runs"):
        if getattr(args, opt, None) is not None:
            raise StudyError(
                f"--{opt.replace('_', '-')} applies to a scenario study; a study on {path} refits the whole file in blocks of 100 runs"
            )
    algs = args.algorithm or ["image_plane"]
    if len(algs) != 1 or algs[0] in ("all", "least_squares"):
        raise StudyError(
            f"a study on {path} refits with one estimator: give one --algorithm (as boresight estimate), got {', '.join(algs)}"
        )
    ns = argparse.Namespace(**vars(args))
    ns.scenario, ns.file = None, path
    from boresight.cli import pushbroom_inputs as pb

    unknowns = None
    if pb.is_pushbroom(path):  # pushbroom lines: resimulated and refitted by the line-scan GLS (run_pushbroom below)
        if args.effects or args.loss:
            raise StudyError(
                f"--effects and --loss do not apply to a pushbroom file ({path}): its unknowns are the file's 'estimate' "
                "(docs/data-format.md, 'The pushbroom observation file'), fitted by the line-scan GLS"
            )
        sfs, model, unknowns = pb.campaign_files(ns)  # with --strip: a campaign; each checked by the doctor
        obs = sfs[0].obs if len(sfs) == 1 else [sf.obs for sf in sfs]
        source, effects = "the file's (pixel σ on line and column, tracker σ per sample)", tuple(unknowns.names[3:])
    else:
        if getattr(args, "strip", None):
            raise StudyError(f"--strip applies to a pushbroom observation file; {path} is not one")
        obs = read_checked(path, check=True)  # a convention slip: ConventionError, exit 4
        model, source = model_from_args(ns, obs)
        effects = tuple(args.effects or ())  # names checked against the catalogue by effect_list
    progress = None if args.quiet else mc.ProgressBar(label=f"{path.name} (its own geometry)")
    fs = file_study(
        obs,
        model,
        algorithm=algs[0],
        weighting=args.weighting,
        effects=effects,
        loss=args.loss,
        runs=args.runs,
        seed=args.seed,
        beta=args.beta,
        progress=progress,
        preflight=getattr(progress, "preflight", None),
        where=str(path),
        unknowns=unknowns,
    )
    from boresight.observations.stars import targets_text

    sets = obs if isinstance(obs, list) else [obs]
    more = f" and {len(sets) - 1} more strip file(s)" if len(sets) > 1 else ""
    # the targets by their kind (stars / landmarks / both: observations.stars.targets_text); several strip files: landmarks
    targets = targets_text(sets[0]) if len(sets) == 1 else f"{sum(o.n_landmarks for o in sets)} landmark(s)"
    print(
        f"file          {path}{more} ({sum(o.n_images for o in sets)} image(s), {targets}, "
        f"{sum(o.n_observations for o in sets)} observations); noise model: {source}"
    )
    # a line file's unknowns by their quantity (theta_x, chip1_along: core.line_scan.quantity_and_unit), as the line
    # estimate names them; ``effects`` itself keeps the SI names file_study takes
    from boresight.core.line_scan import quantity_and_unit

    shown = [quantity_and_unit(n)[0] for n in effects] if fs.algorithm == "line_scan" else list(effects)
    fit = (
        f"{fs.algorithm} ({fs.weighting} weighting)"
        + (f", floated: {', '.join(shown)}" if shown else "")
        + (f", loss {fs.loss}" if fs.loss else "")
    )
    print(f"estimate      {fit}: θ = " + " / ".join(f"{v:+.4f}" for v in fs.theta_arcsec) + " arcsec")
    print(
        wrap(
            f"Monte Carlo   {fs.runs} runs on the file's geometry (seed {fs.seed}): the same images, landmarks and attitudes, new errors "
            f"drawn from the noise model, each run refitted the same way; θ = the file's estimate, "
            + (
                "the lines' true (line, pixel) located at the fitted unknowns, the file's trajectory the truth"
                if fs.algorithm == "line_scan"
                else "floated effects simulated at 0"
            ),
            "              ",
        )
    )
    lo, hi = fs.interval()
    sd = fs.sigma_arcsec
    inside = fs.inside()
    print(f"axis   reported σ   Monte Carlo σ   interval ({100 * fs.beta:.2f} %)   reported inside")
    for i, ax in enumerate("xyz"):
        print(
            f"{ax:<6} {fs.reported_sigma_arcsec[i]:10.4f}   {sd[i]:13.4f}   [{lo[i]:.4f}, {hi[i]:.4f}]      {'yes' if inside[i] else 'NO'}"
        )
    print(
        "mean error    "
        + " / ".join(f"{m:+.4f} ± {s:.4f}" for m, s in zip(fs.mean_error_arcsec, fs.mean_error_se_arcsec))
        + " arcsec (θ̂ − θ over the runs ± its standard error)"
    )
    if fs.unconverged:
        print(wrap(f"warning: {fs.unconverged} of {fs.runs} refits did not converge (kept in the statistics)"))
    if not inside.all():
        what = ", ".join(
            f"{ax} ({'too small: optimistic' if fs.reported_sigma_arcsec[i] < lo[i] else 'too large'})"
            for i, ax in enumerate("xyz")
            if not inside[i]
        )
        print(
            wrap(
                f"warning: the reported σ is outside the Monte Carlo interval on axis {what}: the σ this fit reports does not "
                "describe its scatter on this geometry under this noise model"
            )
        )
    else:
        print(
            wrap(
                f"verdict       the reported σ is inside the Monte Carlo interval on every axis ({fs.runs} runs, {fs.elapsed_s:.1f} s)"
            )
        )
    return EXIT_OK


def _write_products(args, scenario, result, out: Path):
    table = result.table(args.beta)
    written = [write_table(table, out / "montecarlo.ecsv")]
    payload = study_payload("montecarlo", args, scenario, result, workers=args.workers, scheduler=args.scheduler, beta=args.beta)
    written.append(write_json(out / "montecarlo.json", payload))
    notes = []
    from boresight.reporting.plots import want_figures

    if want_figures(not args.no_plots):  # matplotlib missing: the one note (reporting.plots.MISSING)
        plots = [_plot_atomic(plot_histograms, out / "theta_error_histograms.png", result)]
        # DECISION: a one-point "σθ versus number of images" plot says nothing; skip it and say why.
        if len(result.image_counts) > 1:
            plots.append(_plot_atomic(plot_sigma_vs_images, out / "sigma_vs_images.png", result, args.beta))
        else:
            notes.append(
                f"no sigma_vs_images.png: the scenario has {result.image_counts[0]} image(s); "
                "use a scenario with more images (e.g. scenarios/kiev2012-kalman20.toml) or --image-counts"
            )
        written += [p for p in plots if p is not None]
    return written, notes


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight montecarlo PUSHBROOM.toml --runs N --seed S``: the reported σ against the scatter, and the runs within
    3σ (``boresight.studies.montecarlo.line_scan``)."""
    from boresight.cli import pushbroom_inputs as pb
    from boresight.studies.montecarlo.line_scan import line_scan_montecarlo
    from orbits.strip import load_strip_scenario

    sc = load_strip_scenario(args.scenario)
    mc = line_scan_montecarlo(sc, args.runs, args.seed)
    print(f"scenario      {sc.name}: {sc.description}")
    print(f"runs          {args.runs} (seed {args.seed}; run k draws from default_rng([seed, k]))")
    ratio, count, rate, interval = mc.sigma_over_scatter, mc.count_within_3_sigma, mc.within_3_sigma, mc.within_3_sigma_interval()
    for j, nm in enumerate(mc.names):
        print(
            f"  {pb.label(nm):<22} σ / scatter {ratio[j]:.3f}   within 3σ {count[j]}/{mc.runs} "
            f"({100 * rate[j]:.2f} %, 95 % interval {100 * interval[j, 0]:.2f}-{100 * interval[j, 1]:.2f} %)"
        )
    return 0
