"""``boresight estimate FILE.ecsv [--algorithm NAME] [--weighting unit|diagonal|gls] [...]``.

Reads an observation file (``docs/data-format.md``), estimates θ (Kiev 2012 eq 24 sign) with
``boresight.estimate`` and prints θ ± σ, χ²/dof, the condition number and the iterations; with
several runs in the file, one line per run (``--json`` writes everything machine-readable).

The disturbance model for weighted forms comes from ``--scenario TOML`` (the model the file was
simulated with) or from ``--sigma-*`` options (those override the scenario's values).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from astropy import units as u

from orbits.rotations import ARCSEC

_ALGORITHMS = ("image_plane", "alg3", "ground_plane", "alg2", "unit_vector", "alg1", "homography", "kalman")


def register(sub):
    p = sub.add_parser("estimate", help="estimate the misalignment θ from an ECSV observation file")
    p.add_argument("file", type=Path, help="ECSV observation file (see docs/data-format.md)")
    p.add_argument("--algorithm", default="image_plane", help=f"estimator (default image_plane); one of {', '.join(_ALGORITHMS)} or a registered name")
    p.add_argument("--weighting", default=None, choices=("unit", "diagonal", "gls"), help="weighting (default: gls for kalman, unit otherwise; diagonal and gls need a disturbance model)")
    p.add_argument("--max-iterations", type=int, default=None, help="Gauss-Newton iterations at most (default: until converged, ≤ 20); 1 = no iteration")
    p.add_argument("--prior-sigma-arcsec", type=float, default=None, help="σθ0: prior θ ~ N(0, σθ0²) per axis")
    p.add_argument("--scenario", type=Path, default=None, help="scenario TOML whose disturbance model weights the residuals")
    p.add_argument("--sigma-pixel-m", type=float, default=None, help="image-coordinate noise σK (m)")
    p.add_argument("--sigma-star-tracker-arcsec", type=float, nargs="+", default=None, help="star-tracker error σβ (1 or 3 values, arcsec)")
    p.add_argument("--star-tracker-mode", choices=("per_image", "per_pass", "both"), default=None)
    p.add_argument("--sigma-gnss-m", type=float, default=None, help="GNSS position error σR (m)")
    p.add_argument("--gnss-mode", choices=("per_image", "per_pass", "both"), default=None)
    p.add_argument("--sigma-catalogue-m", type=float, default=None, help="catalogue landmark error σP (m)")
    p.add_argument("--json", type=Path, default=None, help="also write the estimate as JSON to this path")
    p.set_defaults(func=run)


def model_from_args(args):
    """The ``DisturbanceModel`` the options describe, or None if none was given."""
    from boresight.disturbances import DisturbanceModel

    kw = {}
    if args.scenario is not None:
        import orbits

        kw = dict(DisturbanceModel.from_scenario(orbits.load_scenario(args.scenario)).__dict__)
    if args.sigma_pixel_m is not None:
        kw["sigma_pixel_m"] = args.sigma_pixel_m
    if args.sigma_star_tracker_arcsec is not None:
        v = args.sigma_star_tracker_arcsec
        if len(v) not in (1, 3):
            raise ValueError(f"--sigma-star-tracker-arcsec takes 1 or 3 values, got {len(v)}")
        kw["sigma_star_tracker_rad"] = tuple(np.broadcast_to(np.asarray(v, float), (3,)) * ARCSEC)
    for opt, name in (("star_tracker_mode", "star_tracker_mode"), ("sigma_gnss_m", "sigma_gnss_m"), ("gnss_mode", "gnss_mode"), ("sigma_catalogue_m", "sigma_catalogue_m")):
        if getattr(args, opt) is not None:
            kw[name] = getattr(args, opt)
    return DisturbanceModel(**kw) if kw else None


def run(args) -> int:
    from boresight import ObservationSet, estimate

    if not args.file.exists():
        raise FileNotFoundError(f"no such observation file: {args.file}")
    if args.max_iterations is not None and args.max_iterations < 1:
        raise ValueError(f"--max-iterations must be ≥ 1, got {args.max_iterations}")
    obs = ObservationSet.read(args.file)
    model = model_from_args(args)
    est = estimate(
        obs,
        algorithm=args.algorithm,
        weighting=args.weighting,
        iterate=True if args.max_iterations is None else args.max_iterations,
        model=model,
        prior_sigma_arcsec=args.prior_sigma_arcsec,
    )
    print(f"file          {args.file} ({obs.runs} run(s), {obs.n_images} image(s), {obs.n_landmarks} landmark(s), {obs.n_observations} observations per run)")
    if obs.runs == 1:
        print(est.summary())
    else:
        th = est.theta.to_value(u.arcsec)
        sg = est.sigma.to_value(u.arcsec)
        print(f"algorithm     {est.algorithm} ({est.weighting} weighting), {est.iterations} iteration(s)")
        print("run   theta_x     theta_y     theta_z     (arcsec)   sigma_x  sigma_y  sigma_z   chi2/dof")
        for r in range(obs.runs):
            print(f"{r:<5} {th[r, 0]:+10.4f} {th[r, 1]:+10.4f} {th[r, 2]:+10.4f}              {sg[r, 0]:7.4f}  {sg[r, 1]:7.4f}  {sg[r, 2]:7.4f}   {est.chi2[r]:.4g}/{int(est.dof[r])}")
    if args.json is not None:
        out = {
            "algorithm": est.algorithm,
            "weighting": est.weighting,
            "theta_arcsec": est.theta.to_value(u.arcsec).tolist(),
            "covariance_arcsec2": est.covariance.to_value(u.arcsec**2).tolist(),
            "chi2": np.asarray(est.chi2).tolist(),
            "dof": np.asarray(est.dof).tolist(),
            "condition_number": np.asarray(est.condition_number).tolist(),
            "iterations": est.iterations,
            "converged": np.asarray(est.converged).tolist(),
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=2))
        print(f"wrote         {args.json}")
    return 0
