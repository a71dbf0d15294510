"""What the pushbroom side of the commands shares (not a command: no ``register``, no ``run``): recognising a
pushbroom input (a scenario TOML with ``kind = "pushbroom"``, ``orbits.strip.load_strip_scenario``, or a pushbroom
observation file, ``boresight.observations.strip_file``), reading a file with the command line's σ options and the
convention doctor (as ``cli/options.read_merged`` reads frame files), simulating a scenario at a seed, and the lines
that describe the input and print an unknown (its name without the SI suffix, its value in the printed unit).

The commands' pushbroom branches live in the commands themselves (``run_pushbroom`` in ``cli/simulate.py``,
``estimate.py``, ``check.py``, ``diagnose.py``, ``montecarlo.py``, ``sensitivity.py``, ``plan.py``); they print the
library's results (``boresight.estimate`` on lines, ``studies.montecarlo.line_scan``, ``studies.discrepancy.line_scan``,
``studies.sensitivity.line_scan_sensitivities``, ``studies.planning.line_scan``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from orbits.errors import InputValueError
from orbits.rotations import ARCSEC


def is_pushbroom(path: Any) -> bool:
    """True when ``path`` (a file or a shipped scenario's name) is a pushbroom scenario TOML or a pushbroom observation
    file (``boresight.observations.strip_file``)."""
    from boresight.observations.strip_file import is_strip_file
    from orbits.strip import is_strip_scenario

    return bool(is_strip_file(path)) or bool(is_strip_scenario(path))


def is_file(path: Any) -> bool:
    from boresight.observations.strip_file import is_strip_file

    return bool(is_strip_file(path))


def _sigma_options(args: Any) -> tuple[float | None, float | None]:
    """--sigma-pixel-px and --sigma-star-tracker-arcsec (one value, or three equal: the lines' model is isotropic)."""
    st = getattr(args, "sigma_star_tracker_arcsec", None)
    if st is not None:
        if len(set(st)) != 1:
            raise InputValueError(
                f"--sigma-star-tracker-arcsec {' '.join(map(str, st))}: a pushbroom file's tracker σ is one value for the three axes"
            )
        st = float(st[0])
    for opt in ("sigma_pixel_m", "sigma_gnss_m", "sigma_catalogue_m", "scenario"):
        if getattr(args, opt, None) is not None:
            raise InputValueError(
                f"--{opt.replace('_', '-')} does not apply to a pushbroom file: its noise model is --sigma-pixel-px (line and "
                "column) and --sigma-star-tracker-arcsec (white per tracker sample)"
            )
    return getattr(args, "sigma_pixel_px", None), st


def file_lines(sf: Any, model: Any) -> list[str]:
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
        f"{o.line_span()[0]:.1f} … {o.line_span()[1]:.1f}, {o.n_samples} tracker samples at {rate:.4g} Hz"
    )
    out.append(
        f"noise         {model.sigma_pixel_m / sensor.pixel_pitch_m:g} px on line and column; star tracker "
        f"{model.sigma_star_tracker_rad[0] / ARCSEC:g}″ white per sample"
        + _gauss_markov_text(model.sigma_star_tracker_correlated_rad[0] / ARCSEC, model.star_tracker_correlation_time_s)
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


def campaign_files(args: Any) -> tuple[list[Any], Any, Any]:
    """(``StripFile`` s, noise model, unknowns) of ``estimate`` / ``montecarlo`` / ``sensitivity FILE [--strip FILE …]``: the strips of one campaign, each
    checked by the doctor; θ and the first file's ``estimate`` unknowns common; one noise model (the files' must agree)."""
    sf, model, unknowns = read_file(args.file, args)
    sfs = [sf]
    for f in getattr(args, "strip", None) or []:
        if not is_file(f):
            raise InputValueError(
                f"--strip {f}: not a pushbroom observation file (docs/data-format.md, 'The pushbroom observation file')"
            )
        other, m, _ = read_file(f, args)
        if (m.sigma_pixel_m, m.sigma_star_tracker_rad) != (model.sigma_pixel_m, model.sigma_star_tracker_rad):
            raise InputValueError(
                f"--strip {f}: its noise model ({other.noise}) differs from {args.file}'s ({sf.noise}); a campaign is fitted "
                "with one: give --sigma-pixel-px and --sigma-star-tracker-arcsec"
            )
        sfs.append(other)
    return sfs, model, unknowns


def check_file(sf: Any, model: Any) -> None:
    """The convention doctor on a pushbroom file's lines (``boresight check``): a slip is a ``ConventionError``."""
    from boresight.observations.doctor import convention_error, diagnose_conventions

    dg = diagnose_conventions(sf.obs)
    if not dg.passed:
        raise convention_error(dg, str(sf.path), hint="boresight check FILE shows the table; --no-check skips this test")


def scenario(path: Any, seed: int) -> tuple[Any, list[Any]]:
    from boresight.observations.strip import simulate_strip_scenario
    from orbits.strip import load_strip_scenario

    sc = load_strip_scenario(path)
    return sc, simulate_strip_scenario(sc, np.random.default_rng(np.random.SeedSequence(seed)))


def geometry_lines(sc: Any, strips: list[Any]) -> list[str]:
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
        + _gauss_markov_text(sc.tracker.sigma_correlated_arcsec, sc.tracker.correlation_time_s)
    )
    out.append(
        f"truth         θ = {np.array2string(np.degrees(sc.theta_rad) * 3600, precision=3)}″; effects {sc.effects or 'none'}"
    )
    return out


#: the unit an unknown is printed in, by its SI unit (``core.line_scan.quantity_and_unit``), and the SI value of one
#: printed unit: angles in arcsec, times in ms, a dimensionless unknown as it is
_PRINTED_UNITS = {"rad": ("arcsec", ARCSEC), "s": ("ms", 1e-3), "": ("", 1.0)}


def label(name: str) -> str:
    """The printed name of an unknown (``LineScanUnknowns.names``): its quantity without the SI suffix, as the frame
    summary prints θ (``theta_x … arcsec``) and its effects: the name says what, the unit after the value in what
    (``chip1_along … arcsec``, never ``chip1_along_rad … arcsec``)."""
    from boresight.core.line_scan import quantity_and_unit

    return quantity_and_unit(name)[0]


def labels(names: list[str]) -> list[str]:
    return [label(n) for n in names]


def value_text(name: str, value: float, sigma: float) -> str:
    from boresight.core.line_scan import quantity_and_unit

    unit, per = _PRINTED_UNITS[quantity_and_unit(name)[1]]
    if unit:
        return f"{value / per:12.4f} ± {sigma / per:.4f} {unit}"
    return f"{value:12.4e} ± {sigma:.2e}"


def sigma_text(name: str, sigma: float) -> str:
    return value_text(name, 0.0, sigma).split("± ")[1]


def _gauss_markov_text(sigma_arcsec: float, tau_s: float) -> str:
    """The header's words for the tracker's Gauss–Markov error ("" when there is none)."""
    return f" + {sigma_arcsec:g}″ Gauss–Markov, τ {tau_s:g} s" if sigma_arcsec > 0 else ""
