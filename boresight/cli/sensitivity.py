"""``boresight sensitivity SCENARIO.toml [--runs N] [--seed S] [--rel-step H] [--out DIR] ...``.

The Kiev 2012 eq 28 study (``boresight.studies.sensitivity.sensitivity_study``): sensitivities ∂σθ/∂σs of σθ to
each disturbance by finite differences of Monte Carlo (common random numbers) and by linear
covariance propagation, the CRLB, and the error budget. Prints the comparison with the
seminar's table; writes to DIR (default ``out/<scenario name>-sensitivity``):
``sensitivity_fd.ecsv``, ``sensitivity_linear.ecsv``, ``error_budget.ecsv``,
``sensitivity.json`` (inputs, versions, agreement), ``sensitivity_bars.png``.

A study like ``montecarlo`` (``docs/reliability.md``), through the same machinery
(``montecarlo.checkpoint.study_folder``): DIR is locked while the study runs, finished blocks of
runs are checkpointed in ``DIR/.checkpoint`` as they complete, ``--resume`` continues a killed
study to files identical to an uninterrupted run (a changed scenario, seed, ``--rel-step``, … is
refused, naming what changed), and every file is written to a temporary name and renamed. An
undefined value (a source whose σ is 0) is an empty ECSV cell and a JSON ``null``, never NaN.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from boresight.cli.options import SEED, study_options
from boresight.core import registry
from boresight.reporting.plots import plot_sensitivity_bars as plot_bars  # noqa: F401 (re-exported)
from orbits.errors import InputValueError


def register(sub):
    from boresight.cli.options import add_engine_arguments, add_resume_argument, add_strip_argument

    p = sub.add_parser("sensitivity", help="Kiev 2012 eq 28 sensitivity study (Monte Carlo FD, linear propagation, CRLB)")
    p.add_argument("scenario", type=Path, help="scenario TOML file (see scenarios/), or a pushbroom observation file")
    p.add_argument(
        "--runs", type=int, default=None, help="Monte Carlo runs per case (default 45000; a pushbroom file or scenario: 200)"
    )
    p.add_argument(
        "--algorithm",
        action="append",
        default=None,
        help=f"{', '.join(registry.montecarlo_names())} or least_squares (repeatable; default least_squares)",
    )
    add_strip_argument(p)
    p.add_argument("--seed", type=SEED, default=1, help="random seed (default 1)")
    p.add_argument("--rel-step", type=float, default=1.0, help="finite-difference step: each σs is scaled by 1 + H (default 1)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default out/<scenario name>-sensitivity)")
    add_engine_arguments(p)
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plot")
    p.add_argument(
        "-q", "--quiet", action="store_true", help="no pre-flight line, progress bar or heartbeat (results are still printed)"
    )
    add_resume_argument(p)
    p.set_defaults(func=run)


def format_comparison(study, algorithm, table: bool = True) -> str:
    """The eq 28 table (one row per source and axis, ≤ 100 columns): FD ± SE, analytic, CRLB and
    the seminar; then σθ per axis. ``table=False`` gives the σθ lines only."""
    from boresight.reproductions.kiev2012.eq28 import eq28_comparison
    from boresight.reproductions.kiev2012.published import SEMINAR_EQ28_SIGMA_ARCSEC

    lines = []
    if table:
        lines.append(f"∂σθ/∂σs, {algorithm}: Monte Carlo FD ± its standard error, linear (analytic), CRLB, seminar")
        lines.append(f"  {'source':<6} {'unit':<14} axis {'FD':>11} {'± SE':>9} {'analytic':>11} {'CRLB':>11} {'seminar':>9}")
        clamped = False
        for row in eq28_comparison(study, algorithm):
            for a in "xyz":
                fd = _num(row[f"fd_{a}"], 11, ".4g")
                if float(row[f"fd_{a}"]) == 0.0:  # the variance difference was negative: clamped at 0
                    fd, clamped = "0*".rjust(11), True
                lines.append(
                    f"  {row['source']:<6} {row['unit']:<14} {a:^4} {fd} {_num(row[f'fd_se_{a}'], 9, '.2g')} "
                    f"{_num(row[f'analytic_{a}'], 11, '.4g')} {_num(row[f'crlb_{a}'], 11, '.4g')} {_num(row[f'seminar_{a}'], 9, '.3g')}"
                )
        if clamped:
            lines.append("  0*: the Monte Carlo variance did not grow (a negative difference, within its ± SE): shown as 0,")
            lines.append("      which is not a measured sensitivity of 0; the ± SE column bounds it")
    mc = study.montecarlo_sigma_arcsec(algorithm)
    lin = study.linear.meta["sigma_theta_arcsec"][algorithm]
    crlb = study.linear.meta["crlb_sigma_arcsec"]
    s = SEMINAR_EQ28_SIGMA_ARCSEC
    lines.append(f"σθ (arcsec), {algorithm}:  {'x':>7} {'y':>7} {'z':>7} {'total':>7}")
    for label, v in (("Monte Carlo", mc), ("linear", lin), ("CRLB", crlb), ("seminar", s)):
        lines.append(f"  {label:<12}" + " " * (len(algorithm) + 3) + " ".join(_num(x, 7, ".2f") for x in v[:4]))
    lines.append(f"FD vs analytic: max |difference|/SE = {_num(study.agreement[algorithm], 0, '.2f')} over sources and axes")
    return "\n".join(lines)


def _num(v, width: int, spec: str) -> str:
    """A table cell; an undefined value (a source with σ = 0) is "—", never "nan"."""
    v = float(v)
    return (format(v, spec) if np.isfinite(v) else "—").rjust(width)


def masked_nonfinite(table):
    """A copy of ``table`` whose non-finite float cells are masked (written as empty cells in
    ECSV), with the masked (row, column) pairs; a result file never holds NaN or inf."""
    from astropy.table import MaskedColumn, Table

    t = Table(table, copy=True)
    masked = []
    for name in t.colnames:
        col = t[name]
        if col.dtype.kind != "f":
            continue
        bad = ~np.isfinite(np.asarray(col, float))
        if bad.any():
            t[name] = MaskedColumn(
                np.where(bad, 0.0, np.asarray(col, float)), mask=bad, unit=col.unit, name=name, description=col.description
            )
            masked += [(int(i), name) for i in np.flatnonzero(bad)]
    return t, masked


def _pushbroom(args) -> int | None:
    """A pushbroom file or scenario: the line-scan GLS's gain and resimulations (run_pushbroom below); None otherwise
    (and ``--runs`` defaults to 45000)."""
    from boresight.cli import pushbroom_inputs as pb

    if pb.is_pushbroom(args.scenario):
        return run_pushbroom(args)
    if getattr(args, "strip", None):
        from boresight.errors import StudyError

        raise StudyError(f"--strip applies to a pushbroom observation file; {args.scenario} is not one")
    if args.runs is None:
        args.runs = 45000
    return None


def _require_engine(args) -> None:
    if getattr(args, "engine", None) == "dask":  # a missing extra: refused before the output folder exists
        from boresight.studies.montecarlo.engines import require_dask

        require_dask()


def run(args) -> int:
    import orbits
    from boresight.cli.options import check_engine_arguments
    from boresight.errors import StudyError
    from boresight.reporting.outputs import inside, output_folder, writing_outputs
    from boresight.studies import montecarlo as mc
    from boresight.studies import sensitivity as se
    from boresight.studies.montecarlo.checkpoint import resumed_line, study_folder

    routed = _pushbroom(args)
    if routed is not None:
        return routed
    check_engine_arguments(args)
    _require_engine(args)
    # DECISION: each σs is scaled by 1 + H; H in [1e-6, 10] keeps the scaled σ and its square finite
    # and the difference (1 + H)² − 1 resolved in float64 (the default H = 1 doubles σs).
    from boresight.studies.sensitivity import MIN_REL_STEP

    if not (np.isfinite(args.rel_step) and MIN_REL_STEP <= args.rel_step <= 10):
        raise StudyError(f"--rel-step must be in [{MIN_REL_STEP:g}, 10] (each σs is scaled by 1 + H), got {args.rel_step}")
    scenario = orbits.load_scenario(args.scenario)
    from boresight.cli.noise_options import warn_scenario_unit_slips

    warn_scenario_unit_slips(scenario, "sensitivity")
    # the linear propagation and the CRLB weight by the full residual covariance σK² E + (PSD
    # terms): invertible exactly when there is pixel noise
    if not scenario.sigma_pixel_m > 0:
        raise StudyError(
            f"{args.scenario}: a sensitivity study needs pixel noise ([pixel] sigma_m > 0): the linear propagation and the "
            f"Cramér–Rao bound weight by the residual covariance, which is singular without it (got {scenario.sigma_pixel_m:g} m)"
        )
    out = output_folder(args.out if args.out is not None else inside(Path("out"), f"{scenario.name}-sensitivity"))
    with study_folder(out, "sensitivity", se.CHECKPOINT_OPTIONS) as ckpt:
        progress = None if args.quiet else mc.ProgressBar(label=f"{scenario.name} (base + 6 scaled sources)")
        study = se.sensitivity_study(
            scenario,
            args.algorithm or ["least_squares"],
            rel_step=args.rel_step,
            **study_options(args, progress, ckpt),
        )
        with writing_outputs():  # Ctrl-C/SIGTERM: the old set of files or the complete new one
            written, masked_notes = _write_products(args, scenario, study, out)
    first = study.budget.meta["algorithm"]
    # the sensitivity table once (the budget's algorithm); the others' σθ only (all in sensitivity_fd.ecsv)
    print(format_comparison(study, first))

    # DECISION: algorithms whose σθ block prints the same digits are printed once, named together
    # (the three least-squares algorithms agree to ~0.1 % of σ on the seminar's data)
    def key(name):
        return tuple(" ".join(ln.replace(name, "").split()) for ln in format_comparison(study, name, table=False).splitlines())

    groups: dict[tuple, list[str]] = {}
    for name in study.mc.algorithms:
        groups.setdefault(key(name), []).append(name)
    for names in groups.values():
        others = [n for n in names if n != first]
        if first in names:
            if others:
                print(f"σθ of {', '.join(others)}: the same as {first}'s to the printed digits")
            continue
        text = format_comparison(study, names[0], table=False)
        if len(names) > 1:
            text = text.replace(
                f"σθ (arcsec), {names[0]}:", f"σθ (arcsec), {' = '.join(names)} (the same to the printed digits):", 1
            )
        print(text)
    print("error budget (share of σθ² per axis, linear propagation):")
    for row in study.budget:
        print(
            f"  {row['label']:<22} x {100 * row['share_x']:5.1f} %  y {100 * row['share_y']:5.1f} %  z {100 * row['share_z']:5.1f} %"
        )
    print(f"{study.mc.runs} runs per case, seed {study.mc.seed}, {study.mc.elapsed_s:.2f} s")
    if resumed_line(study.mc, ckpt):
        print(resumed_line(study.mc, ckpt))
    for n in study.mc.notes:
        print(f"note: {n}")
    for n in masked_notes:
        print(f"note: {n}")
    for p in written:
        print(f"wrote {p}")
    return 0


def _write_products(args, scenario, study, out: Path):
    """The ECSV tables (undefined values masked, never NaN), the JSON and the plot; returns
    (written paths, notes on masked values)."""
    from boresight.files import write_json, write_table
    from boresight.reporting.provenance import study_payload

    written, masked_notes = [], []
    for name, t in (("sensitivity_fd", study.fd), ("sensitivity_linear", study.linear), ("error_budget", study.budget)):
        t, masked = masked_nonfinite(t)
        if masked:
            rows = sorted({r for r, _ in masked})
            what = ", ".join(
                f"{t['source'][r]} ({t['algorithm'][r]})" if "source" in t.colnames and "algorithm" in t.colnames else f"row {r}"
                for r in rows
            )
            masked_notes.append(
                f"{name}.ecsv: {len(masked)} undefined value(s) left empty for {what} — a source with σ = 0 in the scenario has no finite-difference sensitivity"
            )
        written.append(write_table(t, out / f"{name}.ecsv"))
    payload = study_payload(
        "sensitivity",
        args,
        scenario,
        study.mc,
        rel_step=args.rel_step,
        workers=args.workers,
        agreement_max_abs_z=study.agreement,
        sigma_theta_linear_arcsec=study.linear.meta["sigma_theta_arcsec"],
        crlb_sigma_arcsec=study.linear.meta["crlb_sigma_arcsec"],
    )
    written.append(write_json(out / "sensitivity.json", payload))
    first = study.budget.meta["algorithm"]
    from boresight.reporting.plots import want_figures

    if want_figures(not args.no_plots):  # matplotlib missing: the one note (reporting.plots.MISSING)
        written.append(plot_bars(study, out / "sensitivity_bars.png", first))  # atomic (plots._save)
    return written, masked_notes


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight sensitivity PUSHBROOM.ecsv`` (or a pushbroom scenario, simulated with seed 1): eq 28's
    sensitivities of σθ to the pixel noise and the tracker's per-sample error, by linear propagation through the GLS
    gain and by finite differences of resimulations (``boresight.studies.sensitivity.line_scan_sensitivities``), and
    the error budget; writes ``DIR/sensitivity.json``."""
    import argparse

    from boresight.cli import pushbroom_inputs as pb
    from boresight.errors import StudyError
    from boresight.files import write_json
    from boresight.reporting.outputs import inside, output_folder, writing_outputs
    from boresight.studies.sensitivity import LINE_SOURCES, MIN_REL_STEP, line_scan_sensitivities

    runs = 200 if args.runs is None else args.runs
    if not (np.isfinite(args.rel_step) and MIN_REL_STEP <= args.rel_step <= 10):
        raise StudyError(f"--rel-step must be in [{MIN_REL_STEP:g}, 10] (each σs is scaled by 1 + H), got {args.rel_step}")
    if runs != 0 and runs < 2:
        raise StudyError(f"--runs must be 0 (the linear propagation alone) or ≥ 2, got {runs}")
    if pb.is_file(args.scenario):
        ns = argparse.Namespace(**{k: v for k, v in vars(args).items() if k != "scenario"}, file=args.scenario)
        sfs, model, unknowns = pb.campaign_files(ns)  # with --strip: a campaign; each checked by the doctor
        strips, head = [sf.obs for sf in sfs], [ln for sf in sfs for ln in pb.file_lines(sf, model)]
        name = Path(str(args.scenario)).stem
    else:
        from boresight.observations.strip import strip_noise_model, strip_unknowns

        if getattr(args, "strip", None):
            raise InputValueError("--strip adds pushbroom observation files to a file; a scenario holds its own strips")
        sc, strips = pb.scenario(args.scenario, 1)
        model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
        head = pb.geometry_lines(sc, strips) + [
            "seed          1 (the scenario simulated as `boresight simulate` does by default)"
        ]
        name = sc.name
    out = output_folder(args.out if args.out is not None else inside(Path("out"), f"{name}-sensitivity"))
    r = line_scan_sensitivities(strips, unknowns, model, runs=runs, seed=args.seed, rel_step=args.rel_step)
    print("\n".join(head))
    print(
        f"fit           θ = {np.array2string(r.theta_arcsec, precision=4)}″ with {', '.join(pb.labels(r.names[3:])) or 'θ alone'} "
        "(the GLS on rows); the sensitivities about it"
    )
    print(
        f"routes        analytic: the GLS gain's linear propagation; FD: {runs} resimulations about the fit, each σ × "
        f"{1 + args.rel_step:g} with common random numbers (seed {args.seed})"
    )
    print("source                                     a_x        a_y        a_z   unit           route")
    for s in r.sources:
        label, _, unit = LINE_SOURCES[s]
        print(f"{label:<38} " + " ".join(f"{v:10.4f}" for v in r.coef[s]) + f"   {unit:<14} analytic")
        if runs:
            cells = " ".join(f"{v:10.4f}" for v in r.fd_coef[s])
            print(f"{'':<38} {cells}   {unit:<14} FD (± {', '.join(f'{v:.4f}' for v in r.fd_se[s])})")
    print(
        "σθ (arcsec)   "
        + " / ".join(f"{v:.4f}" for v in r.sigma_theta_arcsec)
        + " (the GLS σ; the contributions a σ add to it in quadrature)"
    )
    print("error budget (share of σθ² per axis, linear propagation):")
    for s in r.sources:
        label = LINE_SOURCES[s][0]
        sh = r.share(s)
        print(f"  {label:<38} x {100 * sh[0]:5.1f} %  y {100 * sh[1]:5.1f} %  z {100 * sh[2]:5.1f} %")
    doc = dict(
        input=str(args.scenario),
        names=r.names,
        theta_arcsec=r.theta_arcsec.tolist(),
        sigma=r.sigma,
        sigma_theta_arcsec=r.sigma_theta_arcsec.tolist(),
        sources={
            s: dict(
                label=LINE_SOURCES[s][0],
                unit=LINE_SOURCES[s][2],
                coef=r.coef[s].tolist(),
                contribution_arcsec=r.contribution[s].tolist(),
                share=r.share(s).tolist(),
                fd_coef=None if not runs else r.fd_coef[s].tolist(),
                fd_se=None if not runs else r.fd_se[s].tolist(),
            )
            for s in r.sources
        },
        runs=runs,
        seed=int(args.seed),
        rel_step=float(args.rel_step),
    )
    with writing_outputs():
        path = write_json(out / "sensitivity.json", doc)
    print(f"wrote {path}")
    return 0
