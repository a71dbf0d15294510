"""Sensor error models (Kiev 2012, "system of perturbations").

* Camera: x' = x'' + ξ, y' = y'' + ξ, ξ ~ N(0, σK²) (metres on the focal plane), per observation.
* Star tracker: C_δ = E + Φ(δ) (exactly ``exp(Φ(δ))``), δ ~ N(0, σβj²) per axis j of the star
  tracker; drawn per image, once per pass (a bias), or both (sum of the two).
* GNSS: X = X̄ + ξ per inertial axis, ξ ~ N(0, σR²); per image, per pass or both.

All samplers take the caller's ``numpy.random.Generator`` and return arrays with a leading run
axis. Draw order is fixed (documented in ``docs/assumptions.md``) so a seed reproduces a run.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InputValueError

__all__ = ["ErrorMode", "StarTrackerErrors", "GnssErrors", "PixelNoise", "ERROR_MODES"]

ERROR_MODES = ("per_image", "per_pass", "both")
ErrorMode = str


def _check_mode(owner: str, mode: str) -> None:
    if mode not in ERROR_MODES:
        raise InputValueError(f"{owner}.mode must be one of {ERROR_MODES}, got {mode!r}")


def _check_sigma(name: str, value: Any) -> None:
    finite = np.isscalar(value) and np.isfinite(value)
    if not (finite and value >= 0):
        raise InputValueError(f"{name} must be a finite number ≥ 0, got {value!r}")


def _draw(rng: Any, runs: int, n_images: int, sigma: Any, mode: str) -> np.ndarray:
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (3,))
    out = np.zeros((runs, n_images, 3))
    if mode in ("per_image", "both"):
        out += rng.normal(size=(runs, n_images, 3)) * sigma
    if mode in ("per_pass", "both"):
        out += rng.normal(size=(runs, 1, 3)) * sigma
    return out


@dataclass(frozen=True)
class StarTrackerErrors:
    """Per-axis σβ (rad) of the star-tracker attitude error δ and how it varies in a pass."""

    sigma_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mode: ErrorMode = "per_image"

    def __post_init__(self) -> None:
        _check_mode("StarTrackerErrors", self.mode)
        sig = np.asarray(self.sigma_rad, dtype=float)
        if sig.shape != (3,) or not np.all(np.isfinite(sig) & (sig >= 0)):
            raise InputValueError(
                f"StarTrackerErrors.sigma_rad must be three finite numbers ≥ 0 (one per star-tracker axis), got {self.sigma_rad!r}"
            )

    def sample(self, rng: np.random.Generator, runs: int, n_images: int) -> np.ndarray:
        """δ (rad), shape (runs, n_images, 3), in star-tracker axes."""
        return _draw(rng, runs, n_images, self.sigma_rad, self.mode)


@dataclass(frozen=True)
class GnssErrors:
    """σR (m) per inertial axis of the GNSS position error and how it varies in a pass."""

    sigma_m: float = 0.0
    mode: ErrorMode = "per_image"

    def __post_init__(self) -> None:
        _check_mode("GnssErrors", self.mode)
        _check_sigma("GnssErrors.sigma_m", self.sigma_m)

    def sample(self, rng: np.random.Generator, runs: int, n_images: int) -> np.ndarray:
        """ξ (m), shape (runs, n_images, 3), in inertial axes."""
        return _draw(rng, runs, n_images, self.sigma_m, self.mode)


@dataclass(frozen=True)
class PixelNoise:
    """σK (m on the focal plane) of independent image-coordinate noise."""

    sigma_m: float = 0.0

    def __post_init__(self) -> None:
        _check_sigma("PixelNoise.sigma_m", self.sigma_m)

    def sample(self, rng: np.random.Generator, runs: int, n_images: int, n_landmarks: int) -> np.ndarray:
        """ξ (m), shape (runs, n_images, n_landmarks, 2)."""
        return rng.normal(size=(runs, n_images, n_landmarks, 2)) * self.sigma_m


#: Typical 1σ of each disturbance, in its display unit (the scenario file's): a value more than
#: ``SLIP_FACTOR`` outside the range is most likely a unit slip, and is warned about (not refused:
#: an unusual sensor is allowed). Sources: star trackers 0.5–60″ per axis (cross-boresight, from
#: nano-satellite to high-end units; the seminar's 4″); focal-plane pixel noise 0.1–100 µm (a
#: fraction of a pixel of 1–20 µm pitch); GNSS position 5 cm–100 m (precise orbit to coarse
#: single-frequency); landmark catalogue 1 cm–30 m (surveyed points to map-derived landmarks).
TYPICAL_SIGMA = {
    "pixel": (1e-7, 1e-4, "m"),
    "star_tracker": (0.5, 60.0, "arcsec"),
    "gnss": (0.05, 100.0, "m"),
    "catalogue": (0.01, 30.0, "m"),
}
SLIP_FACTOR = 100.0
#: the unit slips tried, per display unit: (name, factor to the display unit)
_SLIPS = {
    "arcsec": (("degrees", 3600.0), ("radians", 206264.80624709636), ("milliarcseconds", 1e-3)),
    "m": (("millimetres", 1e-3), ("micrometres", 1e-6), ("kilometres", 1e3)),
}


def unit_slip(noise_key: str, value: float) -> str | None:
    """None, or why ``value`` (display unit) looks like a unit slip and which unit would fit.

    >>> unit_slip("star_tracker", 0.0011)
    '0.0011 arcsec is 455× below the typical 0.5–60 arcsec; if it was in degrees, 0.0011 degrees = 3.96 arcsec'
    >>> unit_slip("star_tracker", 4.0) is None
    True
    """
    lo, hi, unit = TYPICAL_SIGMA[noise_key]
    if not value or not (value < lo / SLIP_FACTOR or value > hi * SLIP_FACTOR):
        return None
    where = f"{lo / value:.0f}× below" if value < lo else f"{value / hi:.0f}× above"
    msg = f"{value:.4g} {unit} is {where} the typical {lo:g}–{hi:g} {unit}"
    for name, factor in _SLIPS[unit]:
        if lo <= value * factor <= hi:
            return msg + f"; if it was in {name}, {value:.4g} {name} = {value * factor:.3g} {unit}"
    return msg
