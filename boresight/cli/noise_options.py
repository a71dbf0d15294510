"""The noise-model options shared by ``estimate``, ``diagnose``, ``ingest``, ``montecarlo`` (a
study on a file), ``sensitivity`` and ``simulate``: their arguments, the ``DisturbanceModel`` they
give (options > ``--scenario`` > the file's own noise model) and the unit-slip warnings.

A command module imports these from here, never from another command (``tests/project/test_layering.py``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from orbits.errors import InputValueError
from orbits.rotations import ARCSEC

__all__ = [
    "add_noise_model_args",
    "model_from_args",
    "warn_unit_slips",
    "warn_scenario_unit_slips",
    "NOISE_OPTIONS",
    "OVERRIDE_OPTIONS",
]


def add_noise_model_args(
    p, scenario_help: str | None = None, *, title: str | None = None, gnss_help: str = "GNSS position error σR (m)"
) -> None:
    """The noise-model options shared by ``estimate``, ``diagnose`` and ``ingest`` (read by
    ``model_from_args``): ``--scenario`` (when ``scenario_help`` is given) and the
    ``--sigma-…``/``--…-mode`` overrides of the file's own noise model; in an argument group
    ``title`` when given."""
    g = p.add_argument_group(title) if title else p
    if scenario_help is not None:
        g.add_argument("--scenario", type=Path, default=None, help=scenario_help)
    g.add_argument("--sigma-pixel-m", type=float, default=None, help="image-coordinate noise σK (m on the focal plane)")
    g.add_argument(
        "--sigma-pixel-px",
        type=float,
        default=None,
        help="centroiding noise in pixels, converted to σK on the focal plane with the camera calibration (pitch and distortion)",
    )
    g.add_argument(
        "--sigma-star-tracker-arcsec", type=float, nargs="+", default=None, help="star-tracker error σβ (1 or 3 values, arcsec)"
    )
    g.add_argument("--star-tracker-mode", choices=("per_image", "per_pass", "both"), default=None)
    g.add_argument("--sigma-gnss-m", type=float, default=None, help=gnss_help)
    g.add_argument("--gnss-mode", choices=("per_image", "per_pass", "both"), default=None)
    g.add_argument("--sigma-catalogue-m", type=float, default=None, help="catalogue landmark error σP (m)")


def _override_options() -> dict[str, str]:
    scratch = argparse.ArgumentParser(add_help=False)
    add_noise_model_args(scratch)
    return {dest: "--" + dest.replace("_", "-") for dest in vars(scratch.parse_args([]))}


#: the noise-model overrides ``add_noise_model_args`` adds (``--scenario`` aside), argparse destination →
#: the option as written: read off the function itself, so a command that takes them for an observation file
#: only (``montecarlo`` with a scenario refuses them) names every one
OVERRIDE_OPTIONS = _override_options()


def _file_model(obs):
    """The file's own noise model as a DisturbanceModel, or None (format 1.1 ``noise`` block)."""
    from boresight.core.disturbances import DisturbanceModel

    if hasattr(DisturbanceModel, "from_observations"):
        return DisturbanceModel.from_observations(obs)
    return None


def _base_model(args, obs):
    """(DisturbanceModel fields, where they came from) before the options: the scenario over the
    file's noise model, or ({}, None)."""
    from boresight.core.disturbances import DisturbanceModel
    from boresight.errors import NoiseModelError

    kw, source = {}, None
    try:
        base = _file_model(obs) if obs is not None else None
    except NoiseModelError as exc:
        where = getattr(args, "file", None)
        if where is None:
            raise
        raise NoiseModelError(f"{where}: {exc}") from None
    if base is not None:
        kw, source = dict(base.__dict__), "the file's noise model"
    if args.scenario is not None:
        import orbits

        kw, source = (
            dict(DisturbanceModel.from_scenario(orbits.load_scenario(args.scenario)).__dict__),
            f"scenario {args.scenario}",
        )
    return kw, source


def _pixel_sigma_from_px(args, obs):
    """``--sigma-pixel-px`` converted to metres on the focal plane through the file's camera block."""
    if args.sigma_pixel_m is not None:
        raise InputValueError("give --sigma-pixel-px or --sigma-pixel-m, not both")
    if obs is None or getattr(obs, "camera", None) is None:
        raise InputValueError(
            "--sigma-pixel-px needs a file with a camera block (the calibration that converts pixels to metres); "
            "give --sigma-pixel-m instead"
        )
    # the detections' pixels: the measured points mapped back through the calibration
    uv = obs.camera.focal_plane_to_pixels(obs.xy_m[0])  # (K, 2): one per row
    sigma_m, _ = obs.camera.focal_plane_sigma_m(args.sigma_pixel_px, uv)
    return sigma_m


def _option_overrides(args, obs):
    """The DisturbanceModel fields the command-line options set, by field name."""
    opts = {}
    if getattr(args, "sigma_pixel_px", None) is not None:
        opts["sigma_pixel_m"] = _pixel_sigma_from_px(args, obs)
    if args.sigma_pixel_m is not None:
        opts["sigma_pixel_m"] = args.sigma_pixel_m
    if args.sigma_star_tracker_arcsec is not None:
        v = args.sigma_star_tracker_arcsec
        if len(v) not in (1, 3):
            raise InputValueError(f"--sigma-star-tracker-arcsec takes 1 or 3 values, got {len(v)}")
        opts["sigma_star_tracker_rad"] = tuple(np.broadcast_to(np.asarray(v, float), (3,)) * ARCSEC)
    for opt in ("star_tracker_mode", "sigma_gnss_m", "gnss_mode", "sigma_catalogue_m"):
        if getattr(args, opt) is not None:
            opts[opt] = getattr(args, opt)
    return opts


def _named_option_error(exc, args, opts):
    """The model's refusal re-worded to name the option as the user wrote it, or None when the
    field did not come from an option."""
    from boresight.errors import NoiseModelError

    option = NOISE_OPTIONS.get(getattr(exc, "field", None))
    if option is None or exc.field not in opts:
        return None
    if option == "--sigma-pixel-m" and args.sigma_pixel_m is None:  # it came from --sigma-pixel-px
        err = NoiseModelError(
            f"--sigma-pixel-px {args.sigma_pixel_px:g} (= {opts['sigma_pixel_m']:.3g} m on the focal plane): {exc.reason}"
        )
    else:
        value = getattr(args, option[2:].replace("-", "_"))
        value = (
            " ".join(f"{v:g}" for v in value)
            if isinstance(value, list)
            else (f"{value:g}" if isinstance(value, float) else value)
        )
        err = NoiseModelError(f"{option} {value}: {exc.reason}")
    err.field, err.reason = exc.field, exc.reason
    return err


def model_from_args(args, obs=None):
    """(DisturbanceModel or None, where it came from): options > scenario > the file's noise model.
    An invalid value is refused naming the option (``--sigma-pixel-m 5: must be ≤ 1 m …``) or the
    file's key (``FILE: metadata 'noise'.pixel.sigma_m = 5.0: …``) as the user wrote it."""
    from boresight.core.disturbances import DisturbanceModel
    from boresight.errors import NoiseModelError

    kw, source = _base_model(args, obs)
    opts = _option_overrides(args, obs)
    if opts:
        kw.update(opts)
        source = "command-line options" + (f" over {source}" if source else "")
    if not kw:
        return None, None
    try:
        model = DisturbanceModel(**kw)
    except NoiseModelError as exc:  # name the option as the user wrote it, not the model's field
        err = _named_option_error(exc, args, opts)
        if err is None:
            raise
        raise err from None
    warn_unit_slips(model, opts, source, getattr(args, "command", None))
    return model, source


#: per noise source: (DisturbanceModel field, Scenario attribute, noise key, factor from SI to the display
#: unit, the key as a file's noise metadata writes it, the key as a scenario TOML writes it)
_SLIP_FIELDS = (
    ("sigma_pixel_m", "sigma_pixel_m", "pixel", 1.0, "pixel.sigma_m", "[pixel] sigma_m"),
    (
        "sigma_star_tracker_rad",
        "sigma_star_tracker_arcsec",
        "star_tracker",
        1 / ARCSEC,
        "star_tracker.sigma_arcsec",
        "[star_tracker] sigma_arcsec",
    ),
    ("sigma_gnss_m", "sigma_gnss_m", "gnss", 1.0, "gnss.sigma_m", "[gnss] sigma_m"),
    ("sigma_catalogue_m", "sigma_catalogue_m", "catalogue", 1.0, "catalogue.sigma_m", "[catalogue] sigma_m"),
)


def _warn_slips(command, named_values) -> None:
    """One warning line per (noise key, values in display unit, name as written) more than 100×
    outside its typical range (``orbits.sensors.unit_slip``)."""
    from orbits.sensors import unit_slip

    for key, values, named in named_values:
        for v in np.unique(np.atleast_1d(values)):
            why = unit_slip(key, float(v))
            if why:
                _warn(command, f"{named}: {why}")


def warn_unit_slips(model, opts, source, command=None):
    """One warning line on stderr per noise σ more than 100× outside its typical range
    (``orbits.sensors.TYPICAL_SIGMA``), naming the option or key it came from and the unit that
    would fit (``--sigma-star-tracker-arcsec 0.0011: … if it was in degrees, … = 3.96 arcsec``).
    A warning, not a refusal: an unusual sensor is allowed."""
    _warn_slips(
        command,
        [
            (key, np.asarray(getattr(model, fld)) * factor, NOISE_OPTIONS[fld] if fld in opts else f"{source}: {file_key}")
            for fld, _, key, factor, file_key, _ in _SLIP_FIELDS
        ],
    )


def warn_scenario_unit_slips(scenario, command=None):
    """``warn_unit_slips`` for a scenario's σ, named by its file and table key as written."""
    where = getattr(scenario, "source", None) or scenario.name
    _warn_slips(command, [(key, getattr(scenario, attr, 0.0), f"{where}: {table}") for _, attr, key, _, _, table in _SLIP_FIELDS])


def _warn(command, text):
    print(f"boresight {command}: warning: {text}" if command else f"boresight: warning: {text}", file=sys.stderr)


#: the DisturbanceModel field each noise-model option sets (for messages naming the option)
NOISE_OPTIONS = {
    "sigma_pixel_m": "--sigma-pixel-m",
    "sigma_star_tracker_rad": "--sigma-star-tracker-arcsec",
    "star_tracker_mode": "--star-tracker-mode",
    "sigma_gnss_m": "--sigma-gnss-m",
    "gnss_mode": "--gnss-mode",
    "sigma_catalogue_m": "--sigma-catalogue-m",
}
