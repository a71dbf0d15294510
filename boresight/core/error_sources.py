"""The one table of disturbance (error) sources, and their one naming.

The seminar names its sources by symbol (Kiev 2012 eq 28: K pixel, R GNSS, P catalogue, β1-β3
star tracker); the scenario file, the disturbance model, the simulator's drawn-errors dict and
the noise mapping of an observation file each need a name too. This table is the only place
that says which is which:

============  ===============  ===========================  =========================  ====================  ======
symbol        noise key        scenario (TOML / attribute)  ``DisturbanceModel``       drawn-errors key      axis
============  ===============  ===========================  =========================  ====================  ======
``K``         ``pixel``        ``[pixel] sigma_m``          ``sigma_pixel_m``          ``pixel_noise_m``
``R``         ``gnss``         ``[gnss] sigma_m``           ``sigma_gnss_m``           ``gnss_error_m``
``P``         ``catalogue``    ``[catalogue] sigma_m``      ``sigma_catalogue_m``      ``catalogue_error_m``
``beta1..3``  ``star_tracker`` ``[star_tracker]             ``sigma_star_tracker_rad`` ``delta_rad``           0, 1, 2
                               sigma_arcsec``
============  ===============  ===========================  =========================  ====================  ======

Naming (binding, ``docs/conventions.md``): quantity_source_unit — ``sigma_pixel_m``,
``sigma_gnss_m``, ``sigma_catalogue_m``, ``sigma_star_tracker_arcsec`` / ``_rad``. ``Scenario``
attributes follow it (the earlier attribute names ``pixel_sigma_m``… were removed in 0.1.0).

>>> SOURCES
('K', 'R', 'P', 'beta1', 'beta2', 'beta3')
>>> ERROR_SOURCES["beta2"].errors_key, ERROR_SOURCES["beta2"].axis, ERROR_SOURCES["K"].model_field
('delta_rad', 1, 'sigma_pixel_m')
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.errors import UnknownErrorSourceError
from orbits.errors import unknown_keys_message
from orbits.sensors import ERROR_MODES as _ERROR_MODES

__all__ = [
    "ErrorSource",
    "ERROR_SOURCES",
    "SOURCES",
    "NOISE_KEYS",
    "NOISE_SCHEMA",
    "normalize_noise",
    "UnknownErrorSourceError",
    "source",
    "by_noise_key",
]


@dataclass(frozen=True)
class ErrorSource:
    """One disturbance source (one axis of the star tracker's three) under all its names."""

    symbol: str  # the seminar's (eq 28): K, R, P, beta1, beta2, beta3
    noise_key: str  # pixel | gnss | catalogue | star_tracker: scenario table, noise mapping, DisturbanceModel.scaled
    scenario_key: str  # "table.key" in a scenario TOML file
    scenario_field: str  # the orbits.Scenario attribute (σ in display units)
    model_field: str  # the boresight.DisturbanceModel attribute (σ in SI)
    errors_key: str  # the simulator's drawn-errors dict (orbits.draw_errors / observe)
    axis: int | None  # the star-tracker axis (β1-β3), None for the others
    sigma_unit: str  # display unit of σ (scenario): "m" or "arcsec"
    sensitivity_unit: str  # unit of ∂σθ/∂σ in the eq 28 table
    label: str  # for tables and plots


_ROWS = (
    ErrorSource(
        "K", "pixel", "pixel.sigma_m", "sigma_pixel_m", "sigma_pixel_m", "pixel_noise_m", None, "m", "arcsec/m", "σK (pixel)"
    ),
    ErrorSource("R", "gnss", "gnss.sigma_m", "sigma_gnss_m", "sigma_gnss_m", "gnss_error_m", None, "m", "arcsec/m", "σR (GNSS)"),
    ErrorSource(
        "P",
        "catalogue",
        "catalogue.sigma_m",
        "sigma_catalogue_m",
        "sigma_catalogue_m",
        "catalogue_error_m",
        None,
        "m",
        "arcsec/m",
        "σP (catalogue)",
    ),
) + tuple(
    ErrorSource(
        f"beta{i + 1}",
        "star_tracker",
        "star_tracker.sigma_arcsec",
        "sigma_star_tracker_arcsec",
        "sigma_star_tracker_rad",
        "delta_rad",
        i,
        "arcsec",
        "arcsec/arcsec",
        f"σβ{i + 1} (star tracker)",
    )
    for i in range(3)
)

#: symbol → ErrorSource, in the seminar's order
ERROR_SOURCES = {s.symbol: s for s in _ROWS}
#: the seminar's sources (eq 28), in its order
SOURCES = tuple(ERROR_SOURCES)
#: the noise mapping (an observation file's ``noise`` metadata, a scenario's tables): table → key → kind
NOISE_SCHEMA = {
    "pixel": {"sigma_m": "sigma"},
    "star_tracker": {"sigma_arcsec": "sigma3", "error_mode": "mode"},
    "gnss": {"sigma_m": "sigma", "error_mode": "mode"},
    "catalogue": {"sigma_m": "sigma"},
}
#: the noise keys (scenario tables, noise mapping, ``DisturbanceModel.scaled``)
NOISE_KEYS = tuple(NOISE_SCHEMA)


def source(symbol: str) -> ErrorSource:
    """The table row of a seminar symbol (``K``, ``R``, ``P``, ``beta1``…)."""
    try:
        return ERROR_SOURCES[symbol]
    except (KeyError, TypeError):
        raise UnknownErrorSourceError(f"unknown disturbance source {symbol!r}; expected one of {list(SOURCES)}") from None


def by_noise_key(key: str) -> tuple[ErrorSource, ...]:
    """The rows of a noise key (``star_tracker`` has three)."""
    rows = tuple(s for s in _ROWS if s.noise_key == key)
    if not rows:
        raise UnknownErrorSourceError(f"unknown disturbance source {key!r}; expected one of {sorted(NOISE_KEYS)}")
    return rows


def normalize_noise(mapping: Any, where: str, error: Any = ValueError) -> dict[str, dict[str, Any]]:
    """Validate a noise mapping and return it complete (absent tables/keys → 0 / ``per_image``);
    refusals are ``error`` (the caller's type: ``ObservationError``, ``ObservationFileError``) naming ``where``.

    Keys are the scenario file's: ``pixel.sigma_m``, ``star_tracker.sigma_arcsec`` (one number or
    three, per star-tracker axis), ``star_tracker.error_mode``, ``gnss.sigma_m``,
    ``gnss.error_mode``, ``catalogue.sigma_m``. Booleans and strings are not numbers.
    """
    if not isinstance(mapping, dict):
        raise error(f"{where} must be a mapping of tables {sorted(NOISE_SCHEMA)}, got {mapping!r}")
    unknown = set(mapping) - set(NOISE_SCHEMA)
    if unknown:
        raise error(f"{where}: unknown table(s) {sorted(map(str, unknown))}; expected some of {sorted(NOISE_SCHEMA)}")
    out = {}
    for table, keys in NOISE_SCHEMA.items():
        given = mapping.get(table, {})
        if given is None:
            given = {}
        if not isinstance(given, dict):
            raise error(f"{where}.{table} must be a mapping with keys {sorted(keys)}, got {given!r}")
        bad = set(given) - set(keys)
        if bad:
            raise error(unknown_keys_message(f"{where}.{table}", bad, keys))
        row: dict[str, Any] = {}
        for key, kind in keys.items():
            v = given.get(key)
            name = f"{where}.{table}.{key}"
            if kind == "mode":
                v = "per_image" if v is None else v
                if v not in _ERROR_MODES:
                    raise error(f"{name} must be one of {list(_ERROR_MODES)}, got {v!r}")
                row[key] = str(v)
                continue
            v = 0.0 if v is None else v
            vals = v if (kind == "sigma3" and isinstance(v, (list, tuple))) else [v]
            if kind == "sigma3" and len(vals) not in (1, 3):
                raise error(f"{name} must be one number or three (per star-tracker axis), got {v!r}")
            for x in vals:
                if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) or not np.isfinite(x) or x < 0:
                    raise error(f"{name} must be a finite number ≥ 0, got {v!r}")
            vals = [float(x) for x in vals]
            row[key] = (vals * 3 if len(vals) == 1 else vals) if kind == "sigma3" else vals[0]
        out[table] = row
    return out
