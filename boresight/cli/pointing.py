"""``boresight pointing sea-sky [FILE.csv] [--out DIR]``: the USV sea-sky estimates and a plot.

Prints the coarse (eq 23), grid (eq 24) and robust least-squares estimates of the
perpendicularity error with standard errors, the residual diagnostics, and writes
``sea_sky_fit.png`` (measured vs fitted h' against azimuth) into ``--out`` (default ``out/``).

Example::

    $ boresight pointing sea-sky --out out
"""

from __future__ import annotations

import argparse
from pathlib import Path

from boresight.reporting.outputs import save_figure

__all__ = ["register", "run_sea_sky"]


def register(subparsers) -> None:
    """Add the ``pointing`` command and its ``sea-sky`` sub-command to ``subparsers``."""
    p = subparsers.add_parser("pointing", help="gimbal / platform pointing calibration (USV sea-sky, Tang 2014/2015)")
    sub = p.add_subparsers(dest="pointing_command", metavar="SUBCOMMAND")
    s = sub.add_parser("sea-sky", help="perpendicularity error (alpha, beta) from a sea-sky line scan")
    s.add_argument(
        "file", nargs="?", default=None, help="CSV with the columns of USV sea-sky Table 1 (default: the paper's 120 frames)"
    )
    s.add_argument("--out", default=str(Path("out") / "sea-sky"), help="output folder for the plot (default out/sea-sky)")
    s.add_argument("--no-plots", action="store_true", help="skip the PNG plot")
    s.add_argument("--loss", default="huber", choices=("huber", "linear", "soft_l1", "cauchy"), help="least-squares loss")
    s.add_argument(
        "--json",
        default=None,
        metavar="PATH",
        help="also write the estimates as JSON to this path (sea_sky.json is always written into --out)",
    )
    s.set_defaults(func=run_sea_sky)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_sea_sky(args: argparse.Namespace) -> int:
    """Run the sea-sky estimators on ``args.file`` and write the plot; returns 0."""
    from boresight.pointing.data import load_sea_sky
    from boresight.pointing.sea_sky import special_points_deg
    from boresight.pointing.sea_sky_analysis import analyse_sea_sky
    from boresight.pointing.sea_sky_fit import grid_search_deg
    from boresight.reporting.outputs import check_output_file, check_output_folder
    from boresight.reproductions.usv_sea_sky.published import PAPER_COARSE_DEG, PAPER_FINE_DEG, PAPER_SPECIAL_POINTS_DEG

    check_output_folder(args.out)  # before any work
    check_output_file(args.json, "--json")
    scan = load_sea_sky(args.file)
    paper = args.file is None
    sp = special_points_deg(scan.azimuth_deg, scan.h_meas_deg)
    a0, b0 = (float(v) for v in sp.coarse_estimate_deg())
    print(f"sea-sky scan: {scan.n} frames from {scan.source}")
    print(
        f"coarse (eq 23, special points q1'={sp.q1_deg:.2f} deg, h2'={sp.h2_deg:.4f} deg): alpha = {a0:.4f}, beta = {b0:.4f} deg"
    )
    if paper:
        print(
            f"  paper (its points {PAPER_SPECIAL_POINTS_DEG[0]:.2f}, {PAPER_SPECIAL_POINTS_DEG[1]:.3f}): alpha = {PAPER_COARSE_DEG[0]:.4f}, beta = {PAPER_COARSE_DEG[1]:.4f} deg"
        )
        centre = PAPER_COARSE_DEG
    else:
        centre = (a0, b0)
    g = grid_search_deg(scan.azimuth_deg, scan.h_meas_deg, scan.pitch_deg, scan.roll_deg, *centre)
    print(
        f"grid (eq 24, 2 x 21x21 around {centre[0]:.4f}, {centre[1]:.4f}): alpha = {g.alpha_deg:.4f}, beta = {g.beta_deg:.4f} deg"
        f" ± 0.005 (half the 0.01 deg step), mean |res| = {g.objective_deg:.6f} deg"
    )
    if paper:
        print(f"  paper: alpha = {PAPER_FINE_DEG[0]:.4f}, beta = {PAPER_FINE_DEG[1]:.4f} deg")
    d = analyse_sea_sky(scan, loss=args.loss)
    f = d.fit
    print(
        f"least squares ({f.loss}): alpha = {f.alpha_deg:.4f} ± {f.se[0]:.4f}, beta = {f.beta_deg:.4f} ± {f.se[1]:.4f} deg"
        f" (1 sigma, Newey-West HAC lag {f.max_lag}; iid ± {f.se_iid[0]:.4f}, {f.se_iid[1]:.4f};"
        f" n_eff {f.n_eff:.1f}/{f.n})"
    )
    print("\n".join(d.report().splitlines()[1:]))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from boresight.reporting.outputs import write_json_output

    doc = {
        "source": str(scan.source),
        "frames": int(scan.n),
        "unit": "deg",
        "coarse_eq23": {"alpha": a0, "beta": b0},
        "grid_eq24": {"alpha": float(g.alpha_deg), "beta": float(g.beta_deg), "half_step": 0.005},
        "least_squares": {
            "loss": f.loss,
            "alpha": float(f.alpha_deg),
            "beta": float(f.beta_deg),
            "sigma": [float(v) for v in f.se],
            "sigma_includes": f"1σ, Newey-West HAC lag {f.max_lag}",
            "sigma_iid": [float(v) for v in f.se_iid],
            "n_eff": float(f.n_eff),
            "n": int(f.n),
        },
        "report": d.report(),
    }
    for path in [out / "sea_sky.json"] + ([args.json] if args.json else []):
        if write_json_output(path, doc) is not None:  # --json -: standard output
            print(f"wrote {path}")
    from boresight.reporting.plots import want_figures

    if not want_figures(not args.no_plots):  # matplotlib missing: the one note (reporting.plots.MISSING)
        return 0
    png = out / "sea_sky_fit.png"
    _plot(scan, d, g, png)
    print(f"wrote {png}")
    return 0


def _plot(scan, diag, grid, path: Path) -> None:
    import numpy as np

    from boresight.pointing.sea_sky import elevation_error_deg
    from boresight.reporting.plots import figure

    f = diag.fit
    fig = figure(figsize=(8, 6))
    ax, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    out = np.isin(scan.frame, diag.outlier_frames)
    ax.plot(scan.azimuth_deg[~out], scan.h_meas_deg[~out], "b*", ms=5, label="measured h'")
    ax.plot(scan.azimuth_deg[out], scan.h_meas_deg[out], "o", mfc="none", mec="k", label="flagged outlier")
    ax.plot(scan.azimuth_deg, f.fitted_deg, "r.", label=f"LS fit a={f.alpha_deg:.3f}, b={f.beta_deg:.3f} deg")
    q = np.linspace(0, 360, 721)
    ax.plot(q, elevation_error_deg(q, grid.alpha_deg, grid.beta_deg), "g-", lw=0.8, label="grid estimate, level hull")
    ax.set_ylabel("h' (deg)")
    ax.legend(fontsize=8)
    ax.set_title("USV sea-sky: measured vs fitted elevation error")
    ax2.plot(scan.azimuth_deg, f.residuals_deg, "k.")
    ax2.axhline(0, color="grey", lw=0.5)
    ax2.set_xlabel("azimuth q (deg)")
    ax2.set_ylabel("measured − fitted h' (deg)")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
