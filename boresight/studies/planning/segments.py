"""Which segments of a campaign with star frames to fly: every non-empty subset of a scenario's segments — its
landmark passes (``[[passes]]``) and star-frame segments (``[[star_frames]]``: inertial holds, slews, night-side
zenith frames) — scored by the covariance the one GLS on rows gives θ (the planner proposing star frames
with their cost).

A subset's covariance is the inverse Fisher information of its rows, I = Xᵀ Σ⁻¹ X, computed by
``boresight.estimate`` (``weighting="gls"``, the scenario's noise model) on the scenario's noise-free nominal
campaign (``boresight.observations.simulate.nominal_observations``: the study engine's rows, star rows included)
restricted to the subset's images: one linearisation at θ = 0, no Monte Carlo. With ``effects`` floated (e.g.
``gnss_bias``) the same fit gives θ's σ with the effects marginalised: under nadir passes a GNSS bias is a rotation
absorbed into θ (σθ of arcseconds), and a few star frames, which no position error reaches, pin θ again
(``docs/stars.md``). A subset whose rows do not determine a floated effect (star frames alone and a position
effect, which does not act on them) has no such σ (``None``) and is scored by its σθ without it.

The cost of a subset is its images: star frames are images the camera does not spend on the ground (its
``[[star_frames]]`` times that see at least one star), a landmark pass's images are its frames over the sites.
A subset's score is its largest σ of θ (arcsec; with ``effects`` floated when given); the best subset of each size is
marked, and ``cheapest(subsets, target)`` is the subset with the fewest images that reaches a target σθ.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["SegmentSubset", "segment_labels", "plan_segments", "cheapest"]

#: subsets are enumerated whole: 2^S − 1 of them (S ≤ 12: 4 095 GLS fits of a few ms each)
MAX_SEGMENTS = 12


@dataclass
class SegmentSubset:
    """One subset of the scenario's segments: their ``labels``, ``images`` (the cost), σθ (3,) arcsec of the GLS on
    their rows, and σθ with the effects floated (None when the rows do not determine them); ``best`` for its size."""

    segments: tuple[int, ...]
    labels: tuple[str, ...]
    images: int
    sigma_theta_arcsec: np.ndarray
    sigma_theta_floated_arcsec: np.ndarray | None
    best: bool = False

    @property
    def score_arcsec(self) -> float:
        """The largest σ of θ, with the effects floated when they were asked for and determined by the rows; else
        without them (star rows alone do not determine a position effect, which does not reach them: their σθ is
        the same with or without it)."""
        s = self.sigma_theta_arcsec if self.sigma_theta_floated_arcsec is None else self.sigma_theta_floated_arcsec
        return float(np.max(s))


def segment_labels(sc: Any) -> list[str]:
    """A label per segment, in the campaign's pass order: landmark passes first, then star-frame segments."""
    out = [f"pass {k} ({p.attitude})" for k, p in enumerate(sc.passes)]
    return out + [f"stars {k} ({fr.attitude}{', night' if fr.night_only else ''})" for k, fr in enumerate(sc.star_frames)]


def plan_segments(sc: Any, effects: tuple[str, ...] = ()) -> list[SegmentSubset]:
    """Every non-empty subset of ``sc``'s segments (an ``orbits.Scenario``) scored (module docstring), sorted by size
    then score. Refused (``StudyError``) above ``MAX_SEGMENTS`` segments."""
    from boresight import estimate
    from boresight.core.disturbances import DisturbanceModel
    from boresight.errors import ObservabilityError, StudyError
    from boresight.observations.simulate import nominal_observations

    nom = nominal_observations(sc)
    labels = segment_labels(sc)
    present = [int(k) for k in np.unique(nom.pass_index)]  # a star segment that sees no star has no images
    if len(present) > MAX_SEGMENTS:
        raise StudyError(f"{sc.source}: {len(present)} segments: at most {MAX_SEGMENTS} are planned by enumeration")
    model = DisturbanceModel.from_scenario(sc)
    out = []
    for size in range(1, len(present) + 1):
        group = []
        for subset in itertools.combinations(present, size):
            sub = nom.images(np.isin(nom.pass_index, subset))
            try:
                sig = estimate(sub, "image_plane", weighting="gls", model=model, iterate=1, effects=[]).sigma.to_value("arcsec")
                sig = sig.reshape(3)
            except ObservabilityError:
                sig = np.full(3, np.inf)
            floated = None
            if effects:
                try:
                    e = estimate(sub, "image_plane", weighting="gls", model=model, iterate=1, effects=",".join(effects))
                    floated = e.sigma.to_value("arcsec").reshape(3)
                except ObservabilityError:
                    floated = None
            group.append(SegmentSubset(subset, tuple(labels[k] for k in subset), sub.n_images, sig, floated))
        min(group, key=lambda g: g.score_arcsec).best = True
        out += sorted(group, key=lambda g: g.score_arcsec)
    return out


def cheapest(subsets: list[SegmentSubset], target_arcsec: float) -> SegmentSubset | None:
    """The subset with the fewest images whose score reaches ``target_arcsec`` (ties: the smaller score), or None."""
    ok = [g for g in subsets if g.score_arcsec <= target_arcsec]
    return min(ok, key=lambda g: (g.images, g.score_arcsec)) if ok else None
