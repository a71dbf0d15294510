"""``boresight sensitivity SCENARIO.toml [--runs N] [--seed S] [--rel-step H] [--out DIR] ...``.

The Kiev 2012 eq 28 study (``boresight.sensitivity.study``): sensitivities ∂σθ/∂σs of σθ to
each disturbance by finite differences of Monte Carlo (common random numbers) and by linear
covariance propagation, the CRLB, and the error budget. Prints the comparison with the
seminar's table; writes to DIR (default ``out/<scenario name>-sensitivity``):
``sensitivity_fd.ecsv``, ``sensitivity_linear.ecsv``, ``error_budget.ecsv``,
``sensitivity.json`` (inputs, versions, agreement), ``sensitivity_bars.png``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from boresight.plots import plot_sensitivity_bars as plot_bars  # noqa: F401 (re-exported)


def register(sub):
    from .montecarlo import add_engine_arguments

    p = sub.add_parser("sensitivity", help="Kiev 2012 eq 28 sensitivity study (Monte Carlo FD, linear propagation, CRLB)")
    p.add_argument("scenario", type=Path, help="scenario TOML file (see scenarios/)")
    p.add_argument("--runs", type=int, default=45000, help="Monte Carlo runs per case (default 45000)")
    p.add_argument("--algorithm", action="append", default=None, help="image_plane, ground_plane, unit_vector, kalman_theta or least_squares (repeatable; default least_squares)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--rel-step", type=float, default=1.0, help="finite-difference step: each σs is scaled by 1 + H (default 1)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default out/<scenario name>-sensitivity)")
    add_engine_arguments(p)
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plot")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def format_comparison(study, algorithm) -> str:
    """The eq 28 table: FD ± SE, analytic, CRLB and the seminar, per source and axis."""
    from boresight.kiev2012.published import SEMINAR_EQ28_SIGMA_ARCSEC

    c = study.comparison(algorithm)
    lines = [f"∂σθ/∂σs ({algorithm}; FD ± MC standard error | analytic | CRLB | seminar)"]
    for row in c:
        cells = []
        for a in "xyz":
            cells.append(f"{row[f'fd_{a}']:.4g}±{row[f'fd_se_{a}']:.2g} | {row[f'analytic_{a}']:.4g} | {row[f'crlb_{a}']:.4g} | {row[f'seminar_{a}']:.3g}")
        lines.append(f"  {row['source']:<6}{row['unit']:<14}" + "   ".join(f"{ax}: {cell}" for ax, cell in zip("xyz", cells)))
    mo = study.mc.moments[algorithm]
    sd = mo.std[0]
    lin = study.linear.meta["sigma_theta_arcsec"][algorithm]
    crlb = study.linear.meta["crlb_sigma_arcsec"]
    s = SEMINAR_EQ28_SIGMA_ARCSEC
    lines.append(f"σθ x/y/z/total (″): Monte Carlo {sd[0]:.2f}/{sd[1]:.2f}/{sd[2]:.2f}/{np.sqrt((sd**2).sum()):.2f}; "
                 f"linear {lin[0]:.2f}/{lin[1]:.2f}/{lin[2]:.2f}/{lin[3]:.2f}; CRLB {crlb[0]:.2f}/{crlb[1]:.2f}/{crlb[2]:.2f}/{crlb[3]:.2f}; "
                 f"seminar {s[0]}/{s[1]}/{s[2]}/{s[3]}")
    lines.append(f"FD vs analytic: max |difference|/SE = {study.agreement[algorithm]:.2f} over sources and axes")
    return "\n".join(lines)


def run(args) -> int:
    import orbits
    from boresight import montecarlo as mc
    from boresight import sensitivity as se

    from boresight.provenance import scenario_dict, versions, write_json

    scenario = orbits.load_scenario(args.scenario)
    out = Path(args.out) if args.out is not None else Path("out") / f"{scenario.name}-sensitivity"
    out.mkdir(parents=True, exist_ok=True)
    progress = None if args.quiet else mc.ProgressBar(label=f"{scenario.name} (base + 6 scaled sources)")
    study = se.study(
        scenario, args.algorithm or ["least_squares"], runs=args.runs, seed=args.seed, rel_step=args.rel_step,
        chunk_runs=args.chunk_runs, block_runs=args.block_runs, workers=args.workers, engine=args.engine,
        scheduler=args.scheduler, progress=progress,
    )
    written = []
    for name, t in (("sensitivity_fd", study.fd), ("sensitivity_linear", study.linear), ("error_budget", study.budget)):
        p = out / f"{name}.ecsv"
        t.write(p, format="ascii.ecsv", overwrite=True)
        written.append(p)
    payload = {
        "command": "boresight sensitivity",
        "argv": sys.argv[1:],
        "scenario_file": str(args.scenario),
        "scenario": scenario_dict(scenario),
        **study.mc.inputs,
        "rel_step": args.rel_step,
        "workers": args.workers,
        "agreement_max_abs_z": study.agreement,
        "sigma_theta_linear_arcsec": study.linear.meta["sigma_theta_arcsec"],
        "crlb_sigma_arcsec": study.linear.meta["crlb_sigma_arcsec"],
        "elapsed_s": study.mc.elapsed_s,
        "versions": versions(),
    }
    written.append(write_json(out / "sensitivity.json", payload))
    first = study.budget.meta["algorithm"]
    if not args.no_plots:
        try:
            written.append(plot_bars(study, out / "sensitivity_bars.png", first))
        except ImportError:
            print("boresight: matplotlib is not installed (pip install 'boresight[plot]'): plot skipped", file=sys.stderr)
    for name in study.mc.algorithms:
        print(format_comparison(study, name))
    print("error budget (share of σθ² per axis, linear propagation):")
    for row in study.budget:
        print(f"  {row['label']:<22} x {100 * row['share_x']:5.1f} %  y {100 * row['share_y']:5.1f} %  z {100 * row['share_z']:5.1f} %")
    print(f"{study.mc.runs} runs per case, seed {study.mc.seed}, {study.mc.elapsed_s:.2f} s")
    for p in written:
        print(f"wrote {p}")
    return 0
