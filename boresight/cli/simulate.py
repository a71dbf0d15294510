"""``boresight simulate SCENARIO.toml [--seed N] [--runs R] [--out DIR] [--image-columns xy|uv]``.

Simulates the scenario, writes ``DIR/<scenario name>.ecsv`` (format 1.1, ``docs/data-format.md``:
with the GNSS velocity and the scenario's noise model; ``--image-columns uv`` writes detector
pixels, which needs a calibrated ``[camera]``) and prints a short summary of the geometry and the
error model.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from boresight.cli.options import SEED
from orbits.errors import InputValueError
from orbits.rotations import ARCSEC


def register(sub):
    p = sub.add_parser("simulate", help="simulate a scenario and write an ECSV observation file")
    p.add_argument("scenario", type=Path, help="scenario TOML file (see scenarios/)")
    p.add_argument("--seed", type=SEED, default=1, help="random seed (default 1)")
    p.add_argument("--runs", type=int, default=1, help="number of Monte Carlo runs to write (default 1)")
    p.add_argument("--out", type=Path, default=Path("out"), help="output folder (default out/)")
    p.add_argument(
        "--image-columns",
        choices=("xy", "uv"),
        default="xy",
        help="image points as focal-plane metres x y (default) or detector pixels u v (needs principal_point_px, "
        "pixel_pitch_m, u_axis, v_axis in [camera])",
    )
    p.set_defaults(func=run)


def summary(scenario, obs) -> str:
    """A short human-readable summary of a simulated ObservationSet (on its rows)."""
    lines = [f"scenario      {scenario.name}: {scenario.description}"]
    o = scenario.orbit
    lines.append(
        f"orbit         circular, altitude {o.altitude_km:g} km, inclination {o.inclination_deg:g} deg; Earth model {scenario.earth_model}"
    )
    cam = scenario.camera
    lines.append(
        f"camera        F = {cam.focal_length_m:g} m, field {cam.fov_deg:g} deg (half-width {cam.half_width_m * 1e3:.2f} mm on the focal plane)"
    )
    cal = cam.calibration()
    if cal is not None:
        dist = ", ".join(f"{k} {getattr(cal, k):g}" for k in ("k1", "k2", "k3", "p1", "p2") if getattr(cal, k)) or "none"
        lines.append(
            f"detector      f = {cal.focal_length_px[0]:g} px, principal point {list(cal.principal_point_px)} px, "
            f"u along {cal.u_axis}, v along {cal.v_axis}; distortion {dist}"
        )
    for k, p in enumerate(scenario.passes):
        sel = obs.pass_index == k
        lines.append(
            f"pass {k}        site {p.site_lat_deg:.4f} N {p.site_lon_deg:.4f} E, {p.direction}, {p.attitude}, "
            + (
                f"{int(sel.sum())} images t = {span[0]:g}..{span[1]:g} s"  # ObservationSet.pass_time_span_s
                if (span := obs.pass_time_span_s(k)) is not None
                else "no image sees a landmark"
            )
        )
    lm = obs.landmark_rows(obs.target_index)
    span = obs.landmark_range_span_m()  # the library's (ObservationSet.landmark_range_span_m), run 0
    if span is not None:
        lines.append(
            f"landmarks     {int(np.sum(obs.target_kind == 'landmark'))} in catalogue, {int(lm.sum())} observations per run "
            f"(range {span[0] / 1e3:.1f}..{span[1] / 1e3:.1f} km)"
        )
    if not lm.all():
        lines.append(
            f"stars         {len(obs.stars)} stars ({obs.stars.source}), {int((~lm).sum())} observations per run "
            f"in {np.unique(obs.image_index[~lm]).size} star frames"
        )
    off = obs.field_angle_span_deg()  # the library's (ObservationSet.field_angle_span_deg), run 0
    if off is not None:
        lines.append(f"field angles  {off[0]:.3f}..{off[1]:.3f} deg off the boresight")
    own = obs.sigma_xy_span_m()  # star centroids by magnitude ([stars] centroid_sigma_reference_m): each row's own σ
    pixel = f"pixel {scenario.sigma_pixel_m * 1e6:g} um"
    if own is not None:
        pixel += f" (star centroids by magnitude: {own[0] * 1e6:.3g}..{own[1] * 1e6:.3g} um, each row its own)"
    lines.append(
        f"errors        {pixel}; star tracker {list(scenario.sigma_star_tracker_arcsec)} arcsec "
        f"({scenario.star_tracker_error_mode}); GNSS {scenario.sigma_gnss_m:g} m ({scenario.gnss_error_mode}); catalogue {scenario.sigma_catalogue_m:g} m"
    )
    th = obs.truth["theta_rad"] / ARCSEC
    if scenario.theta_true_arcsec is not None:
        lines.append(f"true theta    {np.array2string(th[0], precision=2)} arcsec (fixed)")
    else:
        lines.append(
            f"true theta    drawn per run from N(0, ({scenario.theta_sigma0_arcsec:g} arcsec)^2); run 0: {np.array2string(th[0], precision=2)} arcsec"
        )
    return "\n".join(lines)


def run(args) -> int:
    import orbits
    from boresight.cli import pushbroom_inputs as pb
    from boresight.observations.simulate import simulate

    if pb.is_pushbroom(args.scenario):  # a pushbroom scenario: its strips' detections (run_pushbroom below)
        return run_pushbroom(args)
    scenario = orbits.load_scenario(args.scenario)

    from boresight.cli.noise_options import warn_scenario_unit_slips

    warn_scenario_unit_slips(scenario, "simulate")
    if args.runs < 1:
        raise InputValueError(f"--runs must be ≥ 1, got {args.runs}")
    rng = np.random.default_rng(np.random.SeedSequence(args.seed))
    obs = simulate(scenario, rng, runs=args.runs)
    if args.image_columns == "uv" and obs.camera is None:
        from boresight.errors import BoresightError

        raise BoresightError(
            f"--image-columns uv needs a calibrated detector: {args.scenario} [camera] has no principal_point_px "
            "(with pixel_pitch_m, u_axis, v_axis)"
        )
    empty = obs.rows_per_image == 0
    t_empty = obs.t_s[empty]
    if empty.any():  # an image that sees no landmark has no row in the file
        obs = obs.images(~empty)
    from boresight.reporting.outputs import writing_outputs

    with writing_outputs():  # Ctrl-C/SIGTERM: the old file or the complete new one
        path = obs.write(Path(args.out) / f"{scenario.name}.ecsv", overwrite=True, image_columns=args.image_columns)
    print(summary(scenario, obs))
    print(f"runs          {obs.runs} (seed {args.seed})")
    if empty.any():
        print(
            f"not written   {int(empty.sum())} image(s) that saw no landmark in the field (t = {np.array2string(t_empty, precision=3)} s)"
        )
    print(f"wrote         {path}")
    return 0


# ---- a pushbroom scenario or file (cli/pushbroom_inputs.py: what the pushbroom branches share)


def run_pushbroom(args: Any) -> int:
    """``boresight simulate PUSHBROOM.toml``: every strip as a pushbroom observation file, and a summary."""
    from boresight.cli import pushbroom_inputs as pb
    from boresight.observations.strip_file import write_strip_file
    from boresight.reporting.outputs import writing_outputs

    sc, strips = pb.scenario(args.scenario, args.seed)
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
            if sc.tracker.sigma_correlated_arcsec > 0:  # the tracker's Gauss–Markov part (strip_file's noise keys)
                noise.update(
                    star_tracker_correlated_arcsec=sc.tracker.sigma_correlated_arcsec,
                    correlation_time_s=sc.tracker.correlation_time_s,
                )
            paths.append(write_strip_file(o, out / f"{sc.name}.strip{k}.ecsv", noise, sc.estimate, extra))
    print("\n".join(pb.geometry_lines(sc, strips)))
    print(f"seed          {args.seed}")
    for p in paths:
        print(f"wrote         {p}")
    return 0
