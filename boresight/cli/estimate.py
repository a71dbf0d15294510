"""``boresight estimate FILE.ecsv [--algorithm NAME] [--weighting unit|diagonal|gls] [--out DIR] [...]``.

Reads an observation file (``docs/data-format.md``), runs the convention doctor
(``boresight.observations.doctor``; ``--no-check`` skips it), estimates θ (Kiev 2012 eq 24 sign) with
``boresight.estimate`` and prints an honest summary: θ ± σ and what σ includes, converged or not,
χ²/dof with its expected range, the largest normalised residuals (``Estimate.largest_residuals_text``), and the truth with the error
in σ when the file carries one. With several runs, one line per run.

Noise model, in order of precedence: the ``--sigma-*`` options (each overrides one source), a
``--scenario`` TOML, the file's own noise model (format 1.1 ``noise`` block). With a noise model the
default weighting is ``gls``; with none the weighting is ``unit`` and σ is the residual scatter only
— blind to per-image star-tracker and GNSS errors — which the output says, with a warning naming
the options to pass.

``--out DIR`` writes ``estimate.ecsv`` (θ, σ and the covariance), ``residuals.ecsv`` (per
observation: measured − predicted on the focal plane, m, and normalised), ``estimate.json`` and,
with matplotlib, ``residuals_image_plane.png`` and ``residuals_time.png``.

Exit codes: 0 estimate converged; 1 unreadable input / user error; 2 command-line usage;
3 the estimate did not converge (everything is still printed and written); 4 the convention doctor
found a slip (nothing estimated).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from boresight.cli.exit_codes import EXIT_NOT_CONVERGED, EXIT_OK
from boresight.cli.noise_options import add_noise_model_args, model_from_args
from boresight.cli.options import (
    add_command,
    add_join_argument,
    add_loss_argument,
    add_strip_argument,
    effect_list,
    joined_files,
    read_merged,
)
from boresight.core import registry
from boresight.errors import InputValueError
from boresight.files import write_json, write_table
from orbits.rotations import ARCSEC

EPILOG = """examples:
  boresight estimate out/kiev2012-kalman20.ecsv                       # noise model from the file
  boresight estimate flight.ecsv --sigma-pixel-m 3e-6 --sigma-star-tracker-arcsec 4 --sigma-gnss-m 15
  boresight estimate flight.ecsv --algorithm kalman --out results/    # ECSV, JSON and PNG residual plots
  boresight estimate strip0.ecsv --strip strip1.ecsv                  # pushbroom files (ingest --line-detections): a campaign
  boresight estimate pass.ecsv --join stars.ecsv                      # frame files of one campaign, merged as diagnose A B

exit codes: 0 converged, 1 bad input, 2 usage, 3 not converged, 4 convention slip found (see boresight check)"""


def register(sub):
    p = add_command(sub, "estimate", "estimate the misalignment θ from an ECSV observation file", EPILOG)
    p.add_argument("file", type=Path, help="ECSV observation file (see docs/data-format.md)")
    add_strip_argument(p)
    add_join_argument(p)
    p.add_argument(
        "--algorithm",
        default="image_plane",
        help=f"estimator (default image_plane): {registry.names_text()} (aliases in brackets), "
        "or a name registered with boresight.core.registry.register_algorithm",
    )
    p.add_argument(
        "--weighting",
        default=None,
        choices=("unit", "diagonal", "gls"),
        help="weighting (default: gls when a noise model is known, else unit; diagonal and gls need one)",
    )
    p.add_argument(
        "--max-iterations",
        type=int,
        default=None,
        help="Gauss-Newton iterations at most (default: until converged, ≤ 20); 1 = no iteration",
    )
    p.add_argument(
        "--sigma-prior-arcsec",
        dest="prior_sigma_arcsec",  # estimate(prior_sigma_arcsec=)
        metavar="SIGMA_PRIOR_ARCSEC",
        type=float,
        default=None,
        help="σθ0: prior θ ~ N(0, σθ0²) per axis",
    )
    add_noise_model_args(p, scenario_help="scenario TOML (name or path) whose disturbance model weights the residuals")
    p.add_argument(
        "--gate-probability",
        type=float,
        default=None,
        help="Kalman filter only: χ² gating — reject an image whose normalised innovation exceeds the chi2 quantile at this probability (e.g. 0.999); the rejected images are listed",
    )
    add_loss_argument(p, "robust loss (iteratively reweighted; docs/estimators.md): cauchy or tukey for gross outliers")
    p.add_argument(
        "--effects",
        dest="effects",
        type=effect_list,
        default=None,
        metavar="NAMES",
        help="effects fitted jointly with θ, comma-separated (e.g. focal_scale,time_tag; docs/effects.md); none: no effect (default: none, but gnss_bias on a file of star and landmark rows, docs/stars.md)",
    )
    p.add_argument(
        "--variance-components",
        action="store_true",
        help="estimate each noise source's scale from the residuals (REML; docs/discrepancy.md) and weight with them",
    )
    p.add_argument("--no-check", action="store_true", help="skip the convention doctor (boresight check)")
    p.add_argument(
        "--out", type=Path, default=None, help="write estimate.ecsv, residuals.ecsv, estimate.json and PNG plots to this folder"
    )
    p.add_argument("--no-plots", action="store_true", help="with --out: skip the PNG plots")
    p.add_argument("--json", type=Path, default=None, help="also write the estimate as JSON to this path")
    p.set_defaults(func=run)


def _registry_row(name):
    """The algorithm table's row for ``name`` (None for an algorithm registered at run time)."""
    from boresight.core import registry

    try:
        return registry.lookup(name)
    except ValueError:
        return None


def sigma_text(est, model) -> str:
    """What σ includes, as the library says it (``Estimate.sigma_includes``); an estimator that does
    not say (the Kalman filter, Algorithm 1) gets the library's wording for its model."""
    from boresight.core.result import sigma_includes

    return est.sigma_includes or sigma_includes(model, est.weighting, False, 0, None)


def all_warnings(est) -> list[str]:
    """The estimate's warnings (Algorithm 1's planar-model error among them), each once."""
    return list(dict.fromkeys(getattr(est, "warnings", ()) or ()))


def field(label: str, text: str, width: int = 100) -> str:
    """``label`` in a 14-column gutter, ``text`` wrapped to ``width`` columns under it; a label
    longer than the gutter (an effect's name, ``radial_distortion``) is still followed by a space.

    >>> field("radial_distortion", "+0.1615 ± 0.02")
    'radial_distortion +0.1615 ± 0.02'
    """
    import textwrap

    return "\n".join(
        textwrap.wrap(text, width=width, initial_indent=f"{label:<13} ", subsequent_indent=" " * 14, break_on_hyphens=False)
    )


def summary_lines(obs, est, model, source, run: int = 0) -> list[str]:
    """The summary of one run."""
    from astropy import units as u  # astropy on first use (start-up)

    th = np.atleast_2d(est.theta.to_value(u.arcsec))[run]
    sg = np.atleast_2d(est.sigma.to_value(u.arcsec))[run]
    conv = bool(np.atleast_1d(est.converged)[run])
    lines = [
        f"algorithm     {est.algorithm} ({est.weighting} weighting), {est.iterations} iteration(s), "
        + ("converged" if conv else "NOT CONVERGED (last correction above 1e-6 arcsec)")
    ]
    for k, name in enumerate(("theta_x", "theta_y", "theta_z")):
        lines.append(f"{name:<13} {th[k]:+.4f} ± {sg[k]:.4f} arcsec")
    noise_free = bool(getattr(est, "noise_free", False))  # σ is round-off
    lines.append(field("sigma", sigma_text(est, model) + (f"; from {source}" if source and not noise_free else "")))
    lines.append(field("chi2 / dof", est.chi2_text(run)))  # the library's χ² test, its band and its verdict
    lines.append(f"condition     {float(np.atleast_1d(est.condition_number)[run]):.3g}")
    if run == 0 and (est.largest_residuals or noise_free):  # the library's statistic (Estimate.largest_residuals_text)
        lines.append(field("largest z", est.largest_residuals_text()))
    te = est.truth_error(run)  # the library's: θ̂ − truth in arcsec and in σ (None: σ not meaningful)
    if te is not None:
        tt, err, ns = te
        in_sigma = (
            " arcsec (σ not meaningful: noise-free input)"
            if ns is None
            else " arcsec = " + "  ".join(f"{v:+.2f}" for v in ns) + " σ"
        )
        lines.append(
            "truth         "
            + "  ".join(f"{t:+.4f}" for t in tt)
            + " arcsec; error "
            + "  ".join(f"{e:+.4f}" for e in err)
            + in_sigma
        )
    return lines


def _write_outputs(out: Path, obs, est, model, source, res, z, json_path=None, plots=True, vc=None) -> list[Path]:
    written = []
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        written += _tables(out, obs, est, model, source, res, z)
    doc = _json_doc(obs, est, model, source)
    if vc is not None:
        doc["variance_components"] = vc.as_json()
    if json_path is not None and str(json_path) == "-":  # --json -: standard output (reporting.outputs)
        from boresight.reporting.outputs import write_json_output

        write_json_output("-", doc)
        json_path = None
    targets = ([out / "estimate.json"] if out is not None else []) + ([json_path] if json_path else [])
    seen: set[Path] = set()
    for p in targets:
        if Path(p).resolve() in seen:  # --json into --out: one file, written once
            continue
        seen.add(Path(p).resolve())
        p.parent.mkdir(parents=True, exist_ok=True)
        write_json(p, doc)
        written.append(p)
    if out is not None and plots:
        written += _plots(out, obs, res, z)
    return written


def _tables(out, obs, est, model, source, res, z):
    """estimate.ecsv (one row per run) and residuals.ecsv (one row per run and observation); ``res``
    and ``z`` (R, K, 2) per observation."""
    from astropy import units as u  # astropy on first use (start-up)
    from astropy.table import Table

    written = []
    th = np.atleast_2d(est.theta.to_value(u.arcsec))
    cov = est.covariance.to_value(u.arcsec**2).reshape(-1, 3, 3)
    t = Table()
    t["run"] = np.arange(th.shape[0])
    for k, a in enumerate("xyz"):
        t[f"theta_{a}"] = th[:, k] * u.arcsec
        t[f"sigma_{a}"] = np.sqrt(cov[:, k, k]) * u.arcsec
    for i in range(3):
        for j in range(i, 3):
            t[f"cov_{'xyz'[i]}{'xyz'[j]}"] = cov[:, i, j] * u.arcsec**2
    t["chi2"] = np.atleast_1d(est.chi2)
    t["dof"] = np.atleast_1d(est.dof)
    t["converged"] = np.atleast_1d(est.converged)
    t.meta.update(
        algorithm=est.algorithm,
        weighting=est.weighting,
        sigma_includes=sigma_text(est, model),
        noise_model_source=source or "none",
        theta_convention="C_SK,true = exp(-Phi(theta)) C_SK,nominal (Kiev 2012 eq 24)",
    )
    p = out / "estimate.ecsv"
    write_table(t, p)
    written.append(p)

    R, K = res.shape[:2]
    rr, kk = np.repeat(np.arange(R), K), np.tile(np.arange(K), R)
    nn, mm = obs.image_index[kk], obs.target_index[kk]
    r = Table()
    r["run"], r["image"], r["landmark"] = rr, nn, obs.landmark_ids[mm]
    r["t"] = obs.t_s[nn] * u.s
    r["x"], r["y"] = obs.xy_m[rr, kk, 0] * u.m, obs.xy_m[rr, kk, 1] * u.m
    r["res_x"], r["res_y"] = res[rr, kk, 0] * u.m, res[rr, kk, 1] * u.m
    if z is not None:
        r["z_x"], r["z_y"] = z[rr, kk, 0], z[rr, kk, 1]
    r.meta.update(
        residual="measured - predicted on the focal plane at the estimated theta and floated effects (m); "
        "z = residual / its model sigma"
    )
    p = out / "residuals.ecsv"
    write_table(r, p)
    written.append(p)
    return written


def _json_doc(obs, est, model, source):
    from astropy import units as u  # on first use (start-up)

    doc = {
        "algorithm": est.algorithm,
        "weighting": est.weighting,
        "sigma_includes": sigma_text(est, model),
        "noise_model_source": source,
        "theta_arcsec": est.theta.to_value(u.arcsec).tolist(),
        "covariance_arcsec2": est.covariance.to_value(u.arcsec**2).tolist(),
        "chi2": np.asarray(est.chi2).tolist(),
        "dof": np.asarray(est.dof).tolist(),
        "condition_number": np.asarray(est.condition_number).tolist(),
        "iterations": est.iterations,
        "converged": np.asarray(est.converged).tolist(),
        "warnings": all_warnings(est),
        "largest_residuals": est.largest_residuals_json(),  # the library's, as the 'largest z' line prints it (first run)
        # the library's χ² test, as the 'chi2 / dof' line prints it: per run (one dict for one run, as 'chi2')
        "chi2_test": est.chi2_test_json() if obs.runs == 1 else [est.chi2_test_json(r) for r in range(obs.runs)],
        "downweighted": est.downweighted_json(),  # the library's, as the 'robust' line prints it (first run; null: no loss)
    }
    if obs.truth and "theta_rad" in obs.truth:
        doc["truth_theta_arcsec"] = (np.asarray(obs.truth["theta_rad"]) / ARCSEC).tolist()
    return doc


def _plots(out, obs, res, z):
    """The residual figures of run 0 (``reporting.plots``); ``res`` and ``z`` (R, K, 2) per observation."""
    from boresight.reporting.plots import plot_residual_map, plot_residuals_time, want_figures

    if not want_figures():  # matplotlib missing: the one note (reporting.plots.MISSING)
        return []
    return [
        plot_residual_map(
            obs.xy_m[0],
            res[0],
            obs.target_index,
            obs.n_images,
            out / "residuals_image_plane.png",
            obs.pass_index[obs.image_index],
        ),
        plot_residuals_time(
            obs.t_s[obs.image_index], res[0], None if z is None else z[0], obs.epoch_utc, out / "residuals_time.png"
        ),
    ]


def _cli_words(warning: str) -> str:
    """A library warning in the command line's words: its advice names options, not Python calls."""
    if "noise model that was NOT used" in warning:
        return (
            "the file carries a noise model that was NOT used (--weighting unit, or no pixel σ to weight with): σ is the "
            "residual scatter only and does not include star-tracker or GNSS errors; drop --weighting for GLS under it"
        )
    return warning


def _gate_option(args) -> dict:
    """``--gate-probability`` as the Kalman filter's ``gate_probability`` option (checked)."""
    p = getattr(args, "gate_probability", None)
    if p is None:
        return {}
    from boresight.core import registry
    from boresight.errors import BoresightError

    if registry.lookup(args.algorithm).name not in ("kalman",):
        raise BoresightError(f"--gate-probability applies to the Kalman filter (--algorithm kalman), not to {args.algorithm!r}")
    if not (0.0 < p < 1.0):
        raise BoresightError(f"--gate-probability must be in (0, 1), e.g. 0.999, got {p}")
    return {"gate_probability": float(p)}


def _print_gated(est, options):
    if not options:
        return
    rej = np.atleast_2d(np.asarray(est.rejected if est.rejected is not None else np.zeros((1, 0), bool)))
    for r, row in enumerate(rej):
        idx = np.flatnonzero(row)
        who = f"run {r}: " if rej.shape[0] > 1 else ""
        print(
            f"gating        {who}{idx.size} image(s) rejected by the χ² gate at P = {options['gate_probability']:g}"
            + (f": image(s) {', '.join(str(int(i)) for i in idx)}" if idx.size else "")
        )


def _check_run_options(args):
    """The refusals that need no file: a missing file, ``--max-iterations``, ``--sigma-prior-arcsec``."""
    if not args.file.exists():
        raise FileNotFoundError(f"no such observation file: {args.file}")
    if args.max_iterations is not None and args.max_iterations < 1:
        raise InputValueError(f"--max-iterations must be ≥ 1, got {args.max_iterations}")
    if args.prior_sigma_arcsec is not None:
        from boresight.core.estimation import PRIOR_SIGMA_MIN_ARCSEC
        from boresight.errors import BoresightError

        if not (np.isfinite(args.prior_sigma_arcsec) and args.prior_sigma_arcsec >= PRIOR_SIGMA_MIN_ARCSEC):
            v = args.prior_sigma_arcsec
            raise BoresightError(
                f"--sigma-prior-arcsec {int(v) if v.is_integer() else v!r}: must be a finite number ≥ {PRIOR_SIGMA_MIN_ARCSEC:g} arcsec "
                "(σθ0 of the prior θ ~ N(0, σθ0²))"
            )


def _least_squares_options(args) -> dict:
    """``--loss`` and ``--effects`` as the least-squares options (the Kalman gate stays apart)."""
    lsq = {}
    given = []
    if getattr(args, "loss", None):
        lsq["loss"] = args.loss
        given.append(f"--loss {args.loss}")
    if getattr(args, "effects", None) is not None:  # [] (--effects none): the default effects off
        lsq["effects"] = args.effects
        if args.effects:
            given.append(f"--effects {','.join(args.effects)}")
    if given:
        from boresight.core import registry
        from boresight.errors import BoresightError

        if registry.lookup(args.algorithm).kind != "linearizer":
            fits = ", ".join(registry.names("linearizer"))
            raise BoresightError(
                f"{' and '.join(given)} apply to the least-squares algorithms ({fits}), not to --algorithm {args.algorithm}"
            )
    return lsq


def _with_variance_components(args, obs, est, model, weighting, options, lsq):
    """``--variance-components``: each source's scale estimated from the residuals at the GLS θ
    (``boresight.core.variance_components``, REML) and θ re-estimated under the estimated model;
    prints the scales beside the declared ones. Returns (estimate, model, components)."""
    from boresight import estimate
    from boresight.core.variance_components import variance_components_at
    from boresight.errors import BoresightError

    if weighting != "gls" or model is None or lsq.get("effects") or obs.runs != 1:
        raise BoresightError(
            "--variance-components needs GLS weighting under a noise model (the file's or --sigma-…), one run, and no --effects"
        )
    vc = variance_components_at(obs, est.theta.to_value("rad")[0], model)
    for line in vc.lines():
        print(field("noise", line))
    if not vc.converged:
        print(field("warning", f"the variance components did not converge in {vc.iterations} iterations"))
    est = estimate(
        vc.scaled_rows(obs),  # the rows' own pixel σ (if any) scaled as the model's σK
        algorithm=args.algorithm,
        weighting=weighting,
        iterate=True if args.max_iterations is None else args.max_iterations,
        model=vc.model,
        prior_sigma_arcsec=args.prior_sigma_arcsec,
        **options,
        **lsq,
    )
    return est, vc.model, vc


def _model_and_weighting(args, model, source, obs):
    """(model, source, weighting, whether the file's model was ignored) for the chosen algorithm: GLS by default
    when every row of ``obs`` has a pixel σ > 0, the model's σK or its own (``gls.structure.has_pixel_noise``)."""
    from boresight.core.gls.structure import has_pixel_noise

    weighting = args.weighting
    row = _registry_row(args.algorithm)
    ignored_file_model = False
    if row is not None and row.kind == "estimator" and row.name != "kalman" and source == "the file's noise model":
        # DECISION: Algorithm 1 (homography) takes no disturbance model; a model that only came with
        # the file is not forced on it (its σ is its own, and the output says so). Options still are.
        print(
            field(
                "note", f"{row.name} does not use a noise model: the file's is ignored; σ is the algorithm's own (scatter only)"
            )
        )
        model, source = None, None
        ignored_file_model = True
    if weighting is None and has_pixel_noise(obs, model) and (row is None or row.kind == "linearizer"):
        weighting = "gls"
    return model, source, weighting, ignored_file_model


def _print_runs(args, obs, est, model, source):
    """The file line and θ, σ, χ² of every run (one run: the full summary)."""
    from astropy import units as u

    from boresight.observations.stars import targets_text

    print(
        f"file          {', '.join(str(f) for f in joined_files(args))} ({obs.runs} run(s), {obs.n_images} image(s), {targets_text(obs)}, {obs.n_observations} observations per run)"
    )
    if obs.runs == 1:
        print("\n".join(summary_lines(obs, est, model, source)))
        return
    th = est.theta.to_value(u.arcsec)
    sg = est.sigma.to_value(u.arcsec)
    print(f"algorithm     {est.algorithm} ({est.weighting} weighting), {est.iterations} iteration(s)")
    print(field("sigma", sigma_text(est, model)))
    tests = [est.chi2_test(r) for r in range(obs.runs)]  # the library's χ² test per run (Estimate.chi2_test)
    what = "chi2/dof (the noise model's test, expected range)" if tests[0] is not None else "chi2/dof"
    print(f"run   theta_x     theta_y     theta_z   (arcsec)  sigma_x  sigma_y  sigma_z   converged  {what}")
    for r in range(obs.runs):
        t = tests[r]
        chi2 = (
            est.chi2_text(r).split(" (no ")[0] + " (no range)"
            if t is None
            else f"{t[0] / t[1]:.3f} ({t[2]:.3f}..{t[3]:.3f})" + ("  OUTSIDE" if t[4] else "")
        )
        print(
            f"{r:<5} {th[r, 0]:+10.4f} {th[r, 1]:+10.4f} {th[r, 2]:+10.4f}            {sg[r, 0]:7.4f}  {sg[r, 1]:7.4f}  {sg[r, 2]:7.4f}"
            f"   {str(bool(est.converged[r])):<9}  {chi2}"
        )


def _print_effects_and_warnings(args, est, model, ignored_file_model):
    """Floated effects, robust down-weighting and the warnings, in the command line's words."""
    for name, (val, sig) in (getattr(est, "effects", {}) or {}).items():
        v, e = np.ravel(np.atleast_2d(val.value)[0]), np.ravel(np.atleast_2d(sig.value)[0])
        how = (
            "floated by default: the file holds star and landmark rows, and the star rows separate it from θ; "
            "--effects none fixes it at 0"
            if name in getattr(est, "effects_by_default", ())
            else "floated jointly with θ"
        )
        unit = f" {val.unit}" if str(val.unit) else ""  # a dimensionless effect (focal_scale): no unit, no gap
        print(field(name, ", ".join(f"{a:+.4g} ± {b:.2g}" for a, b in zip(v, e)) + f"{unit} ({how})"))
    dw = est.downweighted_json()  # the library's, as --json writes it
    if dw is not None and dw["observations"]:
        print(
            field(
                "robust",
                f"{len(dw['observations'])} observation(s) down-weighted ({dw['loss']}); largest pixel-level z "
                "(|residual| over the pixel σ alone, not the full noise model): "
                + "; ".join(
                    f"image {o['image']} {o['landmark']} z={o['z']:.1f} w={o['weight']:.2f}" for o in dw["observations"][:3]
                ),
            )
        )
    for w in all_warnings(est):
        if not (model is None and w.startswith("no noise model")):  # said below, with the options to pass
            print(field("warning", _cli_words(w)))
    if model is None and ignored_file_model:  # the note above said why; do not contradict it
        print(
            field("warning", f"σ is {est.algorithm}'s own residual scatter: it cannot see per-image star-tracker and GNSS errors")
        )
    elif model is None:
        print(
            field(
                "warning",
                "no noise model in the file or on the command line: σ is the residual scatter only and cannot see per-image "
                "star-tracker and GNSS errors; pass --sigma-pixel-m, --sigma-star-tracker-arcsec, --sigma-gnss-m (and --sigma-catalogue-m) "
                "or --scenario for an honest σ",
            )
        )


def run(args) -> int:

    from boresight import estimate
    from boresight.cli import pushbroom_inputs as pb
    from boresight.observations.flight.culprit import read_checked_naming_inputs as read_checked  # names input slips

    if getattr(args, "join", None) and pb.is_pushbroom(args.file):
        raise InputValueError(
            f"--join merges frame-camera observation files; {args.file} is pushbroom: give its strips with --strip"
        )
    if getattr(args, "strip", None) and not pb.is_pushbroom(args.file):
        raise InputValueError(f"--strip applies to a pushbroom observation file; {args.file} is not one")
    if pb.is_pushbroom(args.file):  # a pushbroom scenario TOML: simulated and fitted on rows (run_pushbroom below)
        return run_pushbroom(args)
    _check_run_options(args)
    from boresight.reporting.outputs import check_output_file, check_output_folder

    check_output_folder(args.out)  # before any work: a file there is refused now, not after the result
    check_output_file(args.json, "--json")
    # a slip: ConventionError, exit 4 (cli.classify); --join: the files merged into one campaign (cli/options.read_merged)
    obs = read_merged(joined_files(args), lambda f: read_checked(f, check=not args.no_check))
    model, source = model_from_args(args, obs)
    options = _gate_option(args)
    lsq = _least_squares_options(args)
    model, source, weighting, ignored_file_model = _model_and_weighting(args, model, source, obs)
    est = estimate(
        obs,
        algorithm=args.algorithm,
        weighting=weighting,
        iterate=True if args.max_iterations is None else args.max_iterations,
        model=model,
        prior_sigma_arcsec=args.prior_sigma_arcsec,
        **options,
        **lsq,
    )
    vc = None
    if getattr(args, "variance_components", False):
        est, model, vc = _with_variance_components(args, obs, est, model, weighting, options, lsq)
    _print_gated(est, options)
    res = est.focal_plane_residuals(obs)
    z = est.residual_z(obs, model)  # per coordinate, over its own σ (the library's, printed as it is)
    _print_runs(args, obs, est, model, source)
    _print_effects_and_warnings(args, est, model, ignored_file_model)
    if args.out is not None or args.json is not None:
        from boresight.reporting.outputs import writing_outputs

        with writing_outputs():  # Ctrl-C/SIGTERM: the old set of files or the complete new one
            written = _write_outputs(
                args.out, obs, est, model, source, res, z, args.json, plots=not getattr(args, "no_plots", False), vc=vc
            )
        for p in written:
            print(f"wrote         {p}")
    if not np.all(est.converged):
        print("boresight estimate: the estimate did not converge (exit 3); see 'algorithm' above", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    return EXIT_OK


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight estimate PUSHBROOM.toml`` or ``PUSHBROOM.ecsv``: θ and the ``[estimate]`` unknowns (the scenario's,
    or the file's ``estimate``), with σ (and the truth of a scenario or a simulated file)."""
    from boresight import estimate
    from boresight.cli import pushbroom_inputs as pb
    from boresight.files import write_json
    from boresight.studies.montecarlo.line_scan import errors_in_sigma, strip_file_truth

    if getattr(args, "effects", None):
        raise InputValueError(
            f"--effects {','.join(args.effects)}: a pushbroom fit floats the line's own unknowns, set by the scenario's "
            "[estimate] table or the file's estimate (docs/pushbroom.md), not the frame camera's effects"
        )
    # the registry's line_scan row (core.line_scan.estimate_lines); a frame algorithm named by --algorithm is refused there
    kw = dict(algorithm=getattr(args, "algorithm", "image_plane"), loss=getattr(args, "loss", None))
    if pb.is_file(args.file):
        sfs, model, unknowns = pb.campaign_files(args)
        head = [ln for sf in sfs for ln in pb.file_lines(sf, model)]
        est = estimate([sf.obs for sf in sfs], model=model, unknowns=unknowns, **kw)
        fit = est.algorithm_result
        truth = strip_file_truth(sfs[0], fit.names)
        seed, name = None, str(sfs[0].path)
    else:
        from boresight.observations.strip import strip_noise_model, strip_unknowns
        from boresight.studies.montecarlo.line_scan import truth_vector

        if getattr(args, "strip", None):
            raise InputValueError(
                f"--strip {', '.join(map(str, args.strip))}: --strip adds pushbroom observation files to a file; "
                f"{args.file} is a scenario, which holds its own strips"
            )
        seed = 1
        sc, strips = pb.scenario(args.file, seed)
        model = strip_noise_model(sc)
        unknowns = strip_unknowns(sc)
        est = estimate(strips, model=model, unknowns=unknowns, **kw)
        fit = est.algorithm_result
        truth = truth_vector(sc, fit.names)
        head = pb.geometry_lines(sc, strips) + [
            f"seed          {seed} (the scenario simulated as `boresight simulate` does by default)"
        ]
        name = sc.name
    print("\n".join(head))
    print(
        f"method        GLS on rows: pixel noise, the star tracker's errors per sample (interpolated to each line); {fit.iterations} Gauss–Newton steps"
    )
    in_sigma = errors_in_sigma(fit.x, fit.sigma, truth)  # the library's (studies.montecarlo.line_scan)
    for nm, v, s_, t, e in zip(fit.names, fit.x, fit.sigma, truth, in_sigma):
        line = f"  {pb.label(nm):<22} {pb.value_text(nm, v, s_)}"
        if np.isfinite(t):
            line += f"   truth {pb.value_text(nm, t, 0).split(' ±')[0].strip()}   ({e:+.2f} σ)"
        print(line)
    print(f"chi2 / dof    {est.chi2_text()}")  # the library's χ² test, its band and verdict (as the frame estimate prints)
    if est.largest_residuals or est.noise_free:  # the library's statistic, as the frame estimate prints it
        print(f"largest z     {est.largest_residuals_text()}")  # one line, as the other pushbroom lines (a label is not split)
    dw = est.downweighted_json()  # the library's, as --json writes it
    if dw is not None and est.downweighted_count() is not None:
        from boresight.core.robust import CHI2_INLIER_Z

        print(
            f"loss          {fit.loss} (iteratively reweighted; σ the M-estimator sandwich): {dw['count']} of "
            f"{np.size(est.whitened_residual_norm)} detections down-weighted (pixel-level z > {dw['z_threshold']:g}), χ² over "
            f"the {est.chi2_kept_observations} kept (z ≤ {CHI2_INLIER_Z:.2f})"
        )
    for w in est.warnings:
        print(f"warning       {w}")
    if not fit.converged:
        print(f"result        NOT CONVERGED in {fit.iterations} Gauss–Newton steps (θ and σ are the last step's)")
    if getattr(args, "json", None):
        write_json(
            args.json,
            dict(
                scenario=name,
                seed=seed,
                # θ under the frame estimate.json's keys (one vocabulary for θ); every unknown in SI under its name after
                theta_arcsec=est.theta.to_value("arcsec").tolist(),
                covariance_arcsec2=est.covariance.to_value("arcsec2").tolist(),
                names=fit.names,
                x=fit.x.tolist(),
                sigma=fit.sigma.tolist(),
                covariance=fit.covariance.tolist(),
                truth=[None if not np.isfinite(t) else float(t) for t in truth],
                chi2=fit.chi2,
                dof=fit.dof,
                converged=fit.converged,
                largest_residuals=est.largest_residuals_json(),  # the library's, as the 'largest z' line prints it
                chi2_test=est.chi2_test_json(),  # the library's, as the 'chi2 / dof' line prints it
                downweighted=est.downweighted_json(),  # the library's, as the 'loss' line prints it (null: least squares)
            ),
        )
    if not fit.converged:
        from boresight.cli.exit_codes import EXIT_NOT_CONVERGED

        return EXIT_NOT_CONVERGED
    return 0
