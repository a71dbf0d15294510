"""The pushbroom side of ``boresight simulate``, ``estimate``, ``diagnose``, ``check``, ``montecarlo``, ``sensitivity``
and ``plan``: a scenario TOML with ``kind = "pushbroom"`` (``orbits.strip.load_strip_scenario``;
``scenarios/pushbroom-strip.toml``, ``pushbroom-campaign.toml``) is simulated (``--seed``; ``estimate``: seed 1,
``simulate``'s default), or a pushbroom observation file (``boresight.observations.strip_file``: what ``simulate`` and
``ingest --line-detections`` write) is read, and

* ``simulate`` writes each strip as a pushbroom observation file (``DIR/<name>.strip<k>.ecsv``: GCP, chip, line,
  pixel, the GCP's position; the samples, sensor and datation and the truth in the metadata) and prints the strips' geometry;
* ``estimate`` fits θ and the ``[estimate]`` unknowns (the scenario's or the file's) through ``boresight.estimate``
  (the registry row ``line_scan``: the GLS on rows with the tracker's errors on the attitude-sample table) and prints
  each with its σ (and the truth of a simulation);
* ``diagnose`` runs ``boresight.studies.discrepancy.line_scan.diagnose_line_scan`` on each strip and writes
  ``DIR/diagnosis.md`` (the printed report) and ``DIR/diagnosis.json`` (each strip's candidates and names; with
  several strips also the campaign's, all strips diagnosed together: ``campaign``);
* ``check`` runs the convention doctor on a file's lines (each an image of one detection);
* ``montecarlo`` runs ``boresight.studies.montecarlo.line_scan`` on a scenario and prints σ / scatter and the 3σ rate
  (``montecarlo FILE`` on a pushbroom file goes through ``cli/montecarlo.py``'s file study, whose line-scan branch
  resimulates the strip about its fit);
* ``sensitivity`` splits σθ between the pixel noise and the tracker (``studies.sensitivity.line_scan_sensitivities``);
* ``plan`` scores every subset of the scenario's strips (``boresight.studies.planning.line_scan``).

Not a command (no ``register``): the commands call it when their input is a pushbroom scenario or file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

ARCSEC = np.pi / 180.0 / 3600.0


def is_pushbroom(path: Any) -> bool:
    """True when ``path`` (a file or a shipped scenario's name) is a pushbroom scenario TOML or a pushbroom observation
    file (``boresight.observations.strip_file``)."""
    from boresight.observations.strip_file import is_strip_file
    from orbits.strip import is_strip_scenario

    return bool(is_strip_file(path)) or bool(is_strip_scenario(path))


def _is_file(path: Any) -> bool:
    from boresight.observations.strip_file import is_strip_file

    return bool(is_strip_file(path))


def _sigma_options(args: Any) -> tuple[float | None, float | None]:
    """--sigma-pixel-px and --sigma-star-tracker-arcsec (one value, or three equal: the lines' model is isotropic)."""
    st = getattr(args, "sigma_star_tracker_arcsec", None)
    if st is not None:
        if len(set(st)) != 1:
            raise ValueError(
                f"--sigma-star-tracker-arcsec {' '.join(map(str, st))}: a pushbroom file's tracker σ is one value for the three axes"
            )
        st = float(st[0])
    for opt in ("sigma_pixel_m", "sigma_gnss_m", "sigma_catalogue_m", "scenario"):
        if getattr(args, opt, None) is not None:
            raise ValueError(
                f"--{opt.replace('_', '-')} does not apply to a pushbroom file: its noise model is --sigma-pixel-px (line and "
                "column) and --sigma-star-tracker-arcsec (white per tracker sample)"
            )
    return getattr(args, "sigma_pixel_px", None), st


def _file_lines(sf: Any, model: Any) -> list[str]:
    """The header a pushbroom file's commands print: the file, its sensor, its strip and its noise model."""
    o, ls = sf.obs, sf.obs.line_scan
    sensor, tr = ls.sensor, ls.trajectory
    rate = (tr.tracker_t_s.size - 1) / (tr.tracker_t_s[-1] - tr.tracker_t_s[0])
    out = [f"file          {sf.path}"]
    out.append(
        f"sensor        {sensor.n_chips} chips, {sensor.n_pixels} pixels, F = {sensor.focal_length_m:g} m, pitch "
        f"{(sensor.pixel_pitch_m or 0) * 1e6:g} µm"
    )
    out.append(
        f"strip         {o.epoch_utc} UTC; {o.n_observations} detections of {o.n_targets} GCPs, lines "
        f"{np.min(ls.line):.1f} … {np.max(ls.line):.1f}, {o.n_samples} tracker samples at {rate:.4g} Hz"
    )
    out.append(
        f"noise         {model.sigma_pixel_m / sensor.pixel_pitch_m:g} px on line and column; star tracker "
        f"{model.sigma_star_tracker_rad[0] / ARCSEC:g}″ white per sample"
    )
    return out


def read_file(path: Any, args: Any) -> tuple[Any, Any, Any]:
    """(``StripFile``, noise model, unknowns) of a pushbroom observation file with the command line's σ options; the
    convention doctor runs on its lines first (unless ``args.no_check``: a slip is a ``ConventionError``, exit 4), then
    the set's behind-the-camera test (as ``observations.flight.culprit.read_checked_naming_inputs`` for a frame file)."""
    from dataclasses import replace

    from boresight.observations.strip import line_unknowns
    from boresight.observations.strip_file import read_strip_file, strip_file_model

    px, st = _sigma_options(args)
    sf = read_strip_file(path, geometry_checks=False)
    if not getattr(args, "no_check", False):
        check_file(sf, None)
    sf.obs = replace(sf.obs, check_geometry=True)
    model = strip_file_model(sf, px, st)
    unknowns = line_unknowns(sf.estimate, sf.obs.line_scan.sensor.n_chips, f"{sf.path}: meta 'estimate'")
    return sf, model, unknowns


def _scenario(path: Any, seed: int) -> tuple[Any, list[Any]]:
    from boresight.observations.strip import simulate_strip_scenario
    from orbits.strip import load_strip_scenario

    sc = load_strip_scenario(path)
    return sc, simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(seed)))


def _geometry_lines(sc: Any, strips: list[Any]) -> list[str]:
    out = [f"scenario      {sc.name}: {sc.description}"]
    sensor = sc.strips[0].sensor
    out.append(
        f"sensor        {sensor.n_chips} chips, {sensor.n_pixels} pixels, F = {sensor.focal_length_m:g} m, pitch "
        f"{(sensor.pixel_pitch_m or 0) * 1e6:g} µm"
    )
    for k, (c, o) in enumerate(zip(sc.strips, strips)):
        out.append(
            f"strip {k}       {c.epoch} UTC, site {c.site_lat_deg:g} N {c.site_lon_deg:g} E, roll {c.roll_deg:g}°, "
            f"{c.n_lines} lines × {c.line_period_s:g} s; {o.n_observations} detections of {o.n_targets} GCPs, "
            f"{o.n_samples} tracker samples at {c.tracker_rate_hz:g} Hz"
        )
    out.append(
        f"noise         {sc.sigma_pixel_px:g} px on line and column; star tracker {sc.tracker.sigma_white_arcsec:g}″ white per sample"
    )
    out.append(
        f"truth         θ = {np.array2string(np.degrees(sc.theta_rad) * 3600, precision=3)}″; effects {sc.effects or 'none'}"
    )
    return out


def run_simulate(args: Any) -> int:
    """``boresight simulate PUSHBROOM.toml``: every strip as a pushbroom observation file, and a summary."""
    from boresight.observations.strip_file import write_strip_file
    from boresight.reporting.outputs import writing_outputs

    sc, strips = _scenario(args.scenario, args.seed)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    with writing_outputs():
        for k, o in enumerate(strips):
            extra = dict(
                scenario=sc.name,
                strip=k,
                seed=int(args.seed),
                epoch_utc=sc.strips[k].epoch,
                theta_arcsec=(np.degrees(sc.theta_rad) * 3600).tolist(),
                effects=sc.effects,
            )
            noise = dict(sigma_pixel_px=sc.sigma_pixel_px, sigma_star_tracker_arcsec=sc.tracker.sigma_white_arcsec)
            paths.append(write_strip_file(o, out / f"{sc.name}.strip{k}.ecsv", noise, sc.estimate, extra))
    print("\n".join(_geometry_lines(sc, strips)))
    print(f"seed          {args.seed}")
    for p in paths:
        print(f"wrote         {p}")
    return 0


#: the unit an unknown is printed in, by its SI unit (``core.line_scan.quantity_and_unit``), and the SI value of one
#: printed unit: angles in arcsec, times in ms, a dimensionless unknown as it is
_PRINTED_UNITS = {"rad": ("arcsec", ARCSEC), "s": ("ms", 1e-3), "": ("", 1.0)}


def _label(name: str) -> str:
    """The printed name of an unknown (``LineScanUnknowns.names``): its quantity without the SI suffix, as the frame
    summary prints θ (``theta_x … arcsec``) and its effects: the name says what, the unit after the value in what
    (``chip1_along … arcsec``, never ``chip1_along_rad … arcsec``)."""
    from boresight.core.line_scan import quantity_and_unit

    return quantity_and_unit(name)[0]


def _labels(names: list[str]) -> list[str]:
    return [_label(n) for n in names]


def _value_text(name: str, value: float, sigma: float) -> str:
    from boresight.core.line_scan import quantity_and_unit

    unit, per = _PRINTED_UNITS[quantity_and_unit(name)[1]]
    if unit:
        return f"{value / per:12.4f} ± {sigma / per:.4f} {unit}"
    return f"{value:12.4e} ± {sigma:.2e}"


def run_estimate(args: Any) -> int:
    """``boresight estimate PUSHBROOM.toml`` or ``PUSHBROOM.ecsv``: θ and the ``[estimate]`` unknowns (the scenario's,
    or the file's ``estimate``), with σ (and the truth of a scenario or a simulated file)."""
    from boresight import estimate
    from boresight.files import write_json

    if getattr(args, "effects", None):
        raise ValueError(
            f"--effects {','.join(args.effects)}: a pushbroom fit floats the line's own unknowns, set by the scenario's "
            "[estimate] table or the file's estimate (docs/pushbroom.md), not the frame camera's effects"
        )
    # the registry's line_scan row (core.line_scan.estimate_lines); a frame algorithm named by --algorithm is refused there
    kw = dict(algorithm=getattr(args, "algorithm", "image_plane"), loss=getattr(args, "loss", None))
    if _is_file(args.file):
        sfs, model, unknowns = campaign_files(args)
        head = [ln for sf in sfs for ln in _file_lines(sf, model)]
        est = estimate([sf.obs for sf in sfs], model=model, unknowns=unknowns, **kw)
        fit = est.algorithm_result
        truth = _file_truth(sfs[0], fit.names)
        seed, name = None, str(sfs[0].path)
    else:
        from boresight.observations.strip import strip_noise_model, strip_unknowns
        from boresight.studies.montecarlo.line_scan import truth_vector

        if getattr(args, "strip", None):
            raise ValueError("--strip adds pushbroom observation files to a file; a scenario holds its own strips")
        seed = 1
        sc, strips = _scenario(args.file, seed)
        model = strip_noise_model(sc)
        unknowns = strip_unknowns(sc)
        est = estimate(strips, model=model, unknowns=unknowns, **kw)
        fit = est.algorithm_result
        truth = truth_vector(sc, fit.names)
        head = _geometry_lines(sc, strips) + [
            f"seed          {seed} (the scenario simulated as `boresight simulate` does by default)"
        ]
        name = sc.name
    print("\n".join(head))
    print(
        f"method        GLS on rows: pixel noise, the star tracker's errors per sample (interpolated to each line); {fit.iterations} Gauss–Newton steps"
    )
    for nm, v, s_, t in zip(fit.names, fit.x, fit.sigma, truth):
        line = f"  {_label(nm):<22} {_value_text(nm, v, s_)}"
        if np.isfinite(t):
            line += f"   truth {_value_text(nm, t, 0).split(' ±')[0].strip()}   ({(v - t) / s_:+.2f} σ)"
        print(line)
    print(f"chi2 / dof    {est.chi2_text()}")  # the library's χ² test, its band and verdict (as the frame estimate prints)
    if fit.loss is not None and fit.weights is not None:
        from boresight.core.robust import CHI2_INLIER_Z

        print(
            f"loss          {fit.loss} (iteratively reweighted; σ the M-estimator sandwich): {int(np.sum(fit.weights < 0.5))} of "
            f"{fit.weights.size} detections weighted below 0.5, χ² over the {est.chi2_kept_observations} kept (pixel-level "
            f"z ≤ {CHI2_INLIER_Z:.2f})"
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
            ),
        )
    if not fit.converged:
        from boresight.cli.exit_codes import EXIT_NOT_CONVERGED

        return EXIT_NOT_CONVERGED
    return 0


def campaign_files(args: Any) -> tuple[list[Any], Any, Any]:
    """(``StripFile`` s, noise model, unknowns) of ``estimate`` / ``montecarlo`` / ``sensitivity FILE [--strip FILE …]``: the strips of one campaign, each
    checked by the doctor; θ and the first file's ``estimate`` unknowns common; one noise model (the files' must agree)."""
    sf, model, unknowns = read_file(args.file, args)
    sfs = [sf]
    for f in getattr(args, "strip", None) or []:
        if not _is_file(f):
            raise ValueError(
                f"--strip {f}: not a pushbroom observation file (docs/data-format.md, 'The pushbroom observation file')"
            )
        other, m, _ = read_file(f, args)
        if (m.sigma_pixel_m, m.sigma_star_tracker_rad) != (model.sigma_pixel_m, model.sigma_star_tracker_rad):
            raise ValueError(
                f"--strip {f}: its noise model ({other.noise}) differs from {args.file}'s ({sf.noise}); a campaign is fitted "
                "with one: give --sigma-pixel-px and --sigma-star-tracker-arcsec"
            )
        sfs.append(other)
    return sfs, model, unknowns


def _file_truth(sf: Any, names: list[str]) -> np.ndarray:
    """The truth of a simulated file (its ``theta_arcsec`` and ``effects``), NaN for a flight file's unknowns."""
    if "theta_arcsec" not in sf.meta:
        return np.full(len(names), np.nan)
    from boresight.studies.montecarlo.line_scan import parameters_truth
    from orbits.effects import line_scan_truth

    truth = line_scan_truth(
        np.radians(np.asarray(sf.meta["theta_arcsec"], float) / 3600.0),
        sf.meta.get("effects") or {},
        sf.obs.line_scan.sensor.n_chips,
        f"{sf.path}: meta 'effects'",
    )
    return parameters_truth(truth, names)


def check_file(sf: Any, model: Any) -> None:
    """The convention doctor on a pushbroom file's lines (``boresight check``): a slip is a ``ConventionError``."""
    from boresight.observations.doctor import convention_error, diagnose_conventions

    dg = diagnose_conventions(sf.obs)
    if not dg.passed:
        raise convention_error(dg, str(sf.path), hint="boresight check FILE shows the table; --no-check skips this test")


def run_check(args: Any) -> int:
    """``boresight check PUSHBROOM.ecsv``: the convention doctor on the file's lines (each line an image of one row:
    its attitude the tracker's SLERP, its point F · tan ψ of its pixel); exit as ``check`` does."""
    from boresight.observations.doctor import convention_error, diagnose_conventions
    from boresight.observations.strip_file import read_strip_file

    sf = read_strip_file(args.file, geometry_checks=False)  # a slip is the doctor's to name, not "behind the camera"
    dg = diagnose_conventions(sf.obs, max_images=args.max_images, max_rotation_deg=args.max_rotation_deg)
    print(f"file          {args.file} (pushbroom: {sf.obs.n_observations} lines with a detection)")
    print(dg.table())
    if getattr(args, "json", None) is not None:
        from boresight.reporting.outputs import write_json_output

        write_json_output(
            args.json,
            {
                "file": str(args.file),
                "verdict": dg.verdict or ("inconclusive" if dg.disagreeing is not None else "conventions_fit"),
                "message": dg.message,
                "rms_residual_m": {k: float(v) for k, v in dg.rms_m.items()},
                "rotation_deg": {k: float(v) for k, v in dg.rotation_deg.items()},
            },
        )
    if dg.passed:
        print(f"result        {dg.message}")
        return 0
    from boresight.observations.doctor import ConventionError
    from boresight.observations.flight.culprit import file_input_slip

    slip = file_input_slip(sf.obs, dg, str(args.file))  # the landmarks' or the orbit's own slip, named as check does
    if slip is not None:
        raise ConventionError(f"{args.file}: {slip.message}", slip=slip.name, report=slip.report)
    raise convention_error(dg, str(args.file), hint="the table above compares the hypotheses")


def run_diagnose(args: Any) -> int:
    """``boresight diagnose PUSHBROOM.toml`` or ``PUSHBROOM.ecsv …``: the line-scanner effects named on each strip, and on the strips
    together when there are several (one campaign)."""
    from boresight.files import atomic_write_text, write_json
    from boresight.reporting.outputs import output_folder, writing_outputs
    from boresight.studies.discrepancy.line_scan import diagnose_line_scan

    if _is_file(args.files[0]):
        jobs, head = [], []
        for f in args.files:
            if not _is_file(f):
                raise ValueError(f"diagnose: {f} is not a pushbroom observation file (give pushbroom files only)")
            sf, model, _ = read_file(f, args)  # checked by the doctor (read_file)
            head += _file_lines(sf, model)
            jobs.append((sf.obs, model))
        label: dict[str, Any] = dict(files=[str(f) for f in args.files])
    else:
        from boresight.observations.strip import strip_noise_model

        sc, strips = _scenario(args.files[0], args.seed)
        model = strip_noise_model(sc)
        head = _geometry_lines(sc, strips) + [f"seed          {args.seed}"]
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


def run_montecarlo(args: Any) -> int:
    """``boresight montecarlo PUSHBROOM.toml --runs N --seed S``: the reported σ against the scatter, and the runs within
    3σ (``boresight.studies.montecarlo.line_scan``)."""
    from boresight.studies.montecarlo.line_scan import line_scan_montecarlo
    from orbits.strip import load_strip_scenario

    sc = load_strip_scenario(args.scenario)
    mc = line_scan_montecarlo(sc, args.runs, args.seed)
    print(f"scenario      {sc.name}: {sc.description}")
    print(f"runs          {args.runs} (seed {args.seed}; run k draws from default_rng([seed, k]))")
    ratio, count, rate, interval = mc.sigma_over_scatter, mc.count_within_3_sigma, mc.within_3_sigma, mc.within_3_sigma_interval()
    for j, nm in enumerate(mc.names):
        print(
            f"  {_label(nm):<22} σ / scatter {ratio[j]:.3f}   within 3σ {count[j]}/{mc.runs} "
            f"({100 * rate[j]:.2f} %, 95 % interval {100 * interval[j, 0]:.2f}-{100 * interval[j, 1]:.2f} %)"
        )
    return 0


def run_plan(args: Any) -> int:
    """``boresight plan PUSHBROOM.toml``: every subset of the scenario's strips scored by its σ; with ``--target-arcsec``
    the search over roll angles for the fewest strips meeting it (``studies.planning.line_scan``)."""
    from orbits.strip import load_strip_scenario

    if args.target_arcsec is not None:
        return _run_roll_plan(args)
    from boresight.studies.planning.line_scan import plan_strips

    sc = load_strip_scenario(args.plan)
    subsets = plan_strips(sc, args.seed)
    names = subsets[0].names
    print(f"scenario      {sc.name}: {sc.description}")
    print(f"unknowns      {', '.join(_labels(names))} (σ from the GLS on rows at a noise-free draw, seed {args.seed})")
    print(
        "strips (rolls)                     worst σθ″  "
        + "  ".join(f"{n[:18]:>18}" for n in _labels(names[3:]))
        + "  corr(θy, δt)"
    )
    for g in subsets:
        rolls = ", ".join(f"{r:+g}°" for r in g.rolls_deg)
        cells = "  ".join(f"{_sigma_text(n, s):>18}" for n, s in zip(names[3:], g.sigma[3:]))
        mark = " *" if g.best else "  "
        print(
            f"{str(list(g.strips)) + ' (' + rolls + ')':<34}{mark}{g.worst_theta_arcsec:8.3f}  {cells}  {g.corr_pitch_time:11.6f}"
        )
    print("* the best subset of its size (smallest worst σ of θ)")
    print("search        give --target-arcsec (and --target-chip-arcsec) to search the roll angles for the fewest strips")
    return 0


def _sigma_text(name: str, sigma: float) -> str:
    return _value_text(name, 0.0, sigma).split("± ")[1]


def _roll_lines(plan: Any, sc: Any) -> list[str]:
    """The printed (and summary.md) lines of a roll search."""
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
        f"unknowns      {', '.join(_labels(plan.names))} (information from the GLS on rows, summed over strips)",
        f"requirement   {plan.requirement_text()}; campaigns of 1 to {plan.max_strips} strips, a roll may be flown on several "
        f"days ({n_scored} scored)",
        "best of each size (rolls)       worst σθ″  "
        + "  ".join(f"{n[:18]:>18}" for n in _labels(plan.names))
        + "  corr(θy, δt)  meets",
    ]
    for b in plan.best:
        cells = "  ".join(f"{_sigma_text(n, s):>18}" for n, s in zip(plan.names, b.sigma))
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
        out.append(f"  {_label(n):<22} σ {_sigma_text(n, s)}")
    return out


def _check_lines(chk: Any) -> list[str]:
    out = [
        f"check         Monte Carlo of chosen.toml: {chk.runs} runs (seed {chk.seed}; run k from default_rng([seed, k])), "
        f"each simulated with the scenario's noise and fitted by estimate_line_scan; the scatter's "
        f"{100 * chk.level:.2f} % interval (Bonferroni over {len(chk.names)} unknowns)"
    ]
    for j, n in enumerate(chk.names):
        out.append(
            f"  {_label(n):<22} predicted σ {_sigma_text(n, chk.predicted[j]):>16}   scatter {_sigma_text(n, chk.scatter[j]):>16} "
            f"(interval {_sigma_text(n, chk.low[j]).split()[0]}-{_sigma_text(n, chk.high[j])})   mean reported σ "
            f"{_sigma_text(n, chk.reported[j])}"
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
        raise ValueError(f"--mc-check must be ≥ 0, got {args.mc_check}")
    if args.mc_check == 1:
        raise ValueError("--mc-check needs at least 2 runs for a scatter, got 1")
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


def run_sensitivity(args: Any) -> int:
    """``boresight sensitivity PUSHBROOM.ecsv`` (or a pushbroom scenario, simulated with seed 1): eq 28's
    sensitivities of σθ to the pixel noise and the tracker's per-sample error, by linear propagation through the GLS
    gain and by finite differences of resimulations (``boresight.studies.sensitivity.line_scan_sensitivities``), and
    the error budget; writes ``DIR/sensitivity.json``."""
    import argparse

    from boresight.errors import StudyError
    from boresight.files import write_json
    from boresight.reporting.outputs import inside, output_folder, writing_outputs
    from boresight.studies.sensitivity import LINE_SOURCES, MIN_REL_STEP, line_scan_sensitivities

    runs = 200 if args.runs is None else args.runs
    if not (np.isfinite(args.rel_step) and MIN_REL_STEP <= args.rel_step <= 10):
        raise StudyError(f"--rel-step must be in [{MIN_REL_STEP:g}, 10] (each σs is scaled by 1 + H), got {args.rel_step}")
    if runs != 0 and runs < 2:
        raise StudyError(f"--runs must be 0 (the linear propagation alone) or ≥ 2, got {runs}")
    if _is_file(args.scenario):
        ns = argparse.Namespace(**{k: v for k, v in vars(args).items() if k != "scenario"}, file=args.scenario)
        sfs, model, unknowns = campaign_files(ns)  # with --strip: a campaign; each checked by the doctor
        strips, head = [sf.obs for sf in sfs], [ln for sf in sfs for ln in _file_lines(sf, model)]
        name = Path(str(args.scenario)).stem
    else:
        from boresight.observations.strip import strip_noise_model, strip_unknowns

        if getattr(args, "strip", None):
            raise ValueError("--strip adds pushbroom observation files to a file; a scenario holds its own strips")
        sc, strips = _scenario(args.scenario, 1)
        model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
        head = _geometry_lines(sc, strips) + ["seed          1 (the scenario simulated as `boresight simulate` does by default)"]
        name = sc.name
    out = output_folder(args.out if args.out is not None else inside(Path("out"), f"{name}-sensitivity"))
    r = line_scan_sensitivities(strips, unknowns, model, runs=runs, seed=args.seed, rel_step=args.rel_step)
    print("\n".join(head))
    print(
        f"fit           θ = {np.array2string(r.theta_arcsec, precision=4)}″ with {', '.join(_labels(r.names[3:])) or 'θ alone'} "
        "(the GLS on rows); the sensitivities about it"
    )
    print(
        f"routes        analytic: the GLS gain's linear propagation; FD: {runs} resimulations about the fit, each σ × "
        f"{1 + args.rel_step:g} with common random numbers (seed {args.seed})"
    )
    print("source                                     a_x        a_y        a_z   unit           route")
    for s, (label, _, unit) in LINE_SOURCES.items():
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
    for s, (label, _, _) in LINE_SOURCES.items():
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
            for s in LINE_SOURCES
        },
        runs=runs,
        seed=int(args.seed),
        rel_step=float(args.rel_step),
    )
    with writing_outputs():
        path = write_json(out / "sensitivity.json", doc)
    print(f"wrote {path}")
    return 0
