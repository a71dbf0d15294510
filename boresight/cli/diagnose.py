"""``boresight diagnose FILE.ecsv [MORE.ecsv …] [--sigma-… overrides] --out DIR``.

Finds where the data and the model disagree, names the missing effect(s) from the effects
catalogue when the data single them out, and writes ``DIR/diagnosis.md``, ``DIR/diagnosis.json``
(format ``boresight-diagnosis`` 1.0, ``docs/discrepancy.md``) and PNG plots of the residuals
before and after each step. The noise model is the file's (format 1.1 metadata ``noise``);
``--sigma-…`` options override it (or supply it for a 1.0 file).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from boresight.cli.options import SEED, effect_list, probability, whole
from orbits.errors import InputValueError


def register(sub):
    from boresight.cli.noise_options import add_noise_model_args

    p = sub.add_parser("diagnose", help="find, name and add the effect the model misses (docs/discrepancy.md)")
    p.add_argument(
        "files",
        type=Path,
        nargs="+",
        help="ECSV observation file(s) of one campaign, or one scenario (TOML path or shipped name) to simulate (with --seed) and diagnose",
    )
    p.add_argument("--seed", type=SEED, default=1, help="random seed when FILE is a scenario TOML (default 1)")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder for diagnosis.md, diagnosis.json and the plots (default out/<first file's name>-diagnosis)",
    )
    p.add_argument(
        "--candidates",
        type=effect_list,
        default=None,
        metavar="NAMES",
        help="comma-separated catalogue effects the diagnosis may name (default: all)",
    )
    p.add_argument(
        "--alpha", type=probability, default=0.01, help="family-wise level of the naming and the residual tests (default 0.01)"
    )
    p.add_argument(
        "--power", type=probability, default=0.8, help="power at which minimum detectable sizes are quoted (default 0.8)"
    )
    p.add_argument("--max-steps", type=whole(0, 1000), default=4, help="name at most this many effects (default 4)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--no-check", action="store_true", help="skip the convention doctor (boresight check) on the files")
    add_noise_model_args(p, scenario_help="scenario TOML whose noise model to use (options override it)")
    p.set_defaults(func=run)


def run(args) -> int:
    import orbits
    from boresight.cli.noise_options import model_from_args
    from boresight.cli.options import read_merged
    from boresight.core.result import noise_model_text
    from boresight.observations.flight.culprit import read_checked_naming_inputs as read_checked  # names input slips
    from boresight.studies.discrepancy.report import write_report
    from boresight.studies.discrepancy.workflow import diagnose

    if args.out is None:
        args.out = Path("out") / f"{Path(str(args.files[0])).stem}-diagnosis"
    from boresight.reporting.outputs import check_output_folder

    check_output_folder(args.out)  # before any work
    for k, f in enumerate(args.files):
        if not f.exists() and f.suffix in ("", ".toml") and f.parent == Path("."):
            if f.stem in orbits.scenario_names():  # a shipped scenario by name (orbits.scenario_path)
                args.files[k] = f = orbits.scenario_path(f)
        if not f.exists():
            raise FileNotFoundError(f"no such observation file: {f}")
    from boresight.cli import pushbroom_inputs as pb

    if pb.is_pushbroom(args.files[0]) and args.files[0].suffix.lower() == ".ecsv":  # pushbroom files (run_pushbroom below)
        return run_pushbroom(args)
    if any(f.suffix == ".toml" for f in args.files):
        if len(args.files) != 1:
            raise InputValueError("diagnose: give one scenario TOML, or observation files — not both")
        if pb.is_pushbroom(args.files[0]):  # pushbroom lines: the line-scanner effects (run_pushbroom below)
            return run_pushbroom(args)
        import numpy as np

        from boresight import simulate

        # one command for the worked example: simulate the scenario (its hidden [effects]) and
        # diagnose it with the scenario's own noise model
        if args.scenario is None:
            args.scenario = args.files[0]
        obs = simulate(orbits.load_scenario(args.files[0]), np.random.default_rng(args.seed))
        print(f"simulated       {args.files[0]} with seed {args.seed}")
    else:
        # the convention doctor first, as `boresight estimate` does: a mirrored axis or a
        # transposed mount is named and stops the diagnosis (exit 4) instead of a 10⁵″ θ
        # (a slip: ConventionError → exit 4 and its message, cli.classify)
        obs = read_merged(args.files, lambda f: read_checked(f, check=not args.no_check))
    model, source = model_from_args(args, obs)
    if model is None:
        raise InputValueError(
            "diagnose: no noise model — the file has none (format 1.0); give --sigma-pixel-m, --sigma-star-tracker-arcsec, "
            "--sigma-gnss-m, --sigma-catalogue-m or --scenario"
        )
    from boresight.cli.heartbeat import Heartbeat

    with Heartbeat("diagnose", every_s=2.0, quiet=getattr(args, "quiet", False)) as beat:
        d = diagnose(
            obs, model, effects=args.candidates, alpha=args.alpha, power=args.power, max_steps=args.max_steps, progress=beat.stage
        )
    print(f"files           {', '.join(str(f) for f in args.files)} ({obs.n_images} images, {obs.n_observations} observations)")
    print(f"noise model     {source}: {noise_model_text(model, obs.sigma_xy_m)}")
    print(d.summary())
    from boresight.reporting.outputs import writing_outputs
    from boresight.reporting.plots import want_figures

    with writing_outputs():  # Ctrl-C/SIGTERM: the old set of files or the complete new one
        paths = write_report(d, args.out, inputs=[str(f) for f in args.files], plots=want_figures(not args.no_plots))
    print(
        f"wrote           {paths['md']}, {paths['json']}" + (f" and {len(paths['figures'])} plot(s)" if paths["figures"] else "")
    )
    return 0


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight diagnose PUSHBROOM.toml`` or ``PUSHBROOM.ecsv …``: the line-scanner effects named on each strip, and on the strips
    together when there are several (one campaign)."""
    from boresight.cli import pushbroom_inputs as pb
    from boresight.files import atomic_write_text, write_json
    from boresight.reporting.outputs import output_folder, writing_outputs
    from boresight.studies.discrepancy.line_scan import diagnose_line_scan

    if pb.is_file(args.files[0]):
        jobs, head = [], []
        for f in args.files:
            if not pb.is_file(f):
                raise InputValueError(f"diagnose: {f} is not a pushbroom observation file (give pushbroom files only)")
            sf, model, _ = pb.read_file(f, args)  # checked by the doctor (read_file)
            head += pb.file_lines(sf, model)
            jobs.append((sf.obs, model))
        label: dict[str, Any] = dict(files=[str(f) for f in args.files])
    else:
        from boresight.observations.strip import strip_noise_model

        sc, strips = pb.scenario(args.files[0], args.seed)
        model = strip_noise_model(sc)
        head = pb.geometry_lines(sc, strips) + [f"seed          {args.seed}"]
        jobs = [(o, model) for o in strips]
        label = dict(scenario=sc.name, seed=int(args.seed))
    print("\n".join(head))
    texts, docs = [], []
    for k, (o, model) in enumerate(jobs):
        d = diagnose_line_scan(o, model)
        texts.append(f"strip {k}:\n  " + d.text().replace("\n", "\n  "))
        print(texts[-1])
        docs.append(
            dict(
                strip=k,
                named=d.named,
                theta_arcsec=d.base.theta_arcsec.tolist(),
                chi2=d.base.chi2,
                dof=d.base.dof,
                candidates=[dict(vars(c)) for c in d.candidates],
            )
        )
    campaign = None
    if len(jobs) > 1:  # the strips together: what several rolls separate (a line-time offset from pitch)
        d = diagnose_line_scan([o for o, _ in jobs], jobs[0][1])
        texts.append(f"campaign (strips 0-{len(jobs) - 1} together):\n  " + d.text().replace("\n", "\n  "))
        print(texts[-1])
        campaign = dict(named=d.named, theta_arcsec=d.base.theta_arcsec.tolist(), chi2=d.base.chi2, dof=d.base.dof)
        campaign["candidates"] = [dict(vars(c)) for c in d.candidates]
    out = output_folder(args.out)
    with writing_outputs():
        atomic_write_text(out / "diagnosis.md", "```\n" + "\n".join(head + texts) + "\n```\n")
        write_json(out / "diagnosis.json", dict(**label, strips=docs, **({"campaign": campaign} if campaign else {})))
    print(f"wrote         {out / 'diagnosis.md'}, {out / 'diagnosis.json'}")
    return 0
