"""Which strips of a pushbroom campaign separate θ from the line's own unknowns: every non-empty subset of a
pushbroom scenario's strips (``[[strips]]``: days, sites, roll angles) scored by the covariance the GLS on rows gives
its ``[estimate]`` unknowns (``boresight.core.line_scan.estimate_line_scan`` on a noise-free draw of the strips, so
the fit sits at the truth and the covariance is the noise model's: Fisher information, no Monte Carlo).

The table answers the issue's planning question for line scanners: how many strips, at which roll angles, before the
line-time offset stops trading with the pitch (corr(θy, δt) → 1 on one strip, ``docs/effects.md``) and the chips'
look angles are told from θ. A subset's score is its largest σ of θ (arcsec); the best subset of each size is marked.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.core.line_scan import estimate_line_scan
from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns

__all__ = ["StripSubset", "plan_strips"]

_ARCSEC = np.pi / 180.0 / 3600.0


@dataclass
class StripSubset:
    """One subset of the scenario's strips (``strips``, indices), its rolls, the unknowns' ``names`` and ``sigma`` (SI),
    the correlation of θy with the line-time offset (NaN when δt is not estimated), and ``best`` for its size."""

    strips: tuple[int, ...]
    rolls_deg: tuple[float, ...]
    names: list[str]
    sigma: np.ndarray
    corr_pitch_time: float
    best: bool = False

    @property
    def worst_theta_arcsec(self) -> float:
        return float(np.max(self.sigma[:3]) / _ARCSEC)


def plan_strips(sc: Any, seed: int = 1) -> list[StripSubset]:
    """Every non-empty subset of ``sc``'s strips, scored (module docstring); in order of size, then score."""
    from orbits.strip import TrackerNoise, simulate_campaign

    geos = sc.geometries()
    sims = simulate_campaign(geos, [sc.truth()] * len(geos), np.random.default_rng(seed), sc.layout, TrackerNoise(), 0.0)
    strips = [strip_observations(s) for s in sims]
    model, unknowns = strip_noise_model(sc), strip_unknowns(sc)
    names = unknowns.names
    out: list[StripSubset] = []
    for size in range(1, len(strips) + 1):
        group = []
        for sub in itertools.combinations(range(len(strips)), size):
            fit = estimate_line_scan([strips[k] for k in sub], unknowns, model)
            c = fit.covariance
            corr = float(c[1, 3] / np.sqrt(c[1, 1] * c[3, 3])) if "line_time_offset_s" in names else float("nan")
            group.append(StripSubset(sub, tuple(sc.strips[k].roll_deg for k in sub), names, fit.sigma, corr))
        group.sort(key=lambda g: g.worst_theta_arcsec)
        group[0].best = True
        out += group
    return out
