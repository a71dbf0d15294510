"""The seminar's scenarios and their variants (study choices, not estimation).

``SCENARIOS`` is the shipped scenarios' folder (``orbits.scenario.SCENARIO_DIR``: the repository's
``scenarios/`` in a checkout, package data in an installed wheel). ``kalman_scenario`` builds the eq 32 table's scenario and
``sensitivity_case`` the eq 28 case's variants (number of images, error modes) used by the
reproduction report.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

__all__ = ["SCENARIOS", "kalman_scenario", "sensitivity_case"]

from orbits.scenario import SCENARIO_DIR as SCENARIOS  # noqa: E402  (one lookup rule: orbits.scenario.scenario_path)


def kalman_scenario(
    sigma0_arcsec: float = 10.0, t_s=None, star_tracker_mode: str | None = None, gnss_mode: str | None = None, path=None
):
    """The eq 32 table's scenario: ``scenarios/kiev2012-sensitivity.toml`` with 20 images.

    CHOICES (the seminar gives none for its Kalman table): the sensitivity case's orbit, camera,
    sensors and landmarks; images every 5 s from the nadir passage, t = 0, 5, ..., 95 s
    (``t_s``: any list of times); true θ ~ N(0, ``sigma0_arcsec``²) per axis (10″ as the seminar's
    table states); error modes as in the file (per image) unless overridden.

    >>> sc = kalman_scenario()
    >>> len(sc.passes[0].t_s), sc.theta_sigma0_arcsec
    (20, 10.0)
    """
    from orbits import scenario_from_dict

    path = Path(path) if path is not None else SCENARIOS / "kiev2012-sensitivity.toml"
    with open(path, "rb") as fh:
        d = tomllib.load(fh)
    d["name"] = d["name"] + "-kalman20"
    d["passes"][0]["t_s"] = {"start": 0.0, "stop": 95.0, "step": 5.0} if t_s is None else list(t_s)
    d.setdefault("misalignment", {})
    d["misalignment"].pop("true_arcsec", None)
    d["misalignment"]["sigma0_arcsec"] = float(sigma0_arcsec)
    if star_tracker_mode is not None:
        d.setdefault("star_tracker", {})["error_mode"] = star_tracker_mode
    if gnss_mode is not None:
        d.setdefault("gnss", {})["error_mode"] = gnss_mode
    return scenario_from_dict(d, source=f"{path} (kalman_scenario)")


def sensitivity_case(n_images: int = 1, mode: str = "per_image"):
    """The eq 28 scenario with ``n_images`` images every 5 s from the passage and the star-tracker
    and GNSS errors ``mode`` (per_image | per_pass).

    >>> sc = sensitivity_case(10, "per_pass")
    >>> len(sc.passes[0].t_s), sc.star_tracker_error_mode, sc.name
    (10, 'per_pass', 'kiev2012-sensitivity-10img-per_pass')
    """
    import orbits

    with open(SCENARIOS / "kiev2012-sensitivity.toml", "rb") as fh:
        d = tomllib.load(fh)
    d["passes"][0]["t_s"] = [5.0 * k for k in range(n_images)]
    d["star_tracker"]["error_mode"] = mode
    d["gnss"]["error_mode"] = mode
    d["name"] = f"{d['name']}-{n_images}img-{mode}"
    return orbits.scenario_from_dict(d, source=f"kiev2012-sensitivity.toml ({n_images} images, {mode})")
