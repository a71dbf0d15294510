"""The weighting policy of ``estimate``: which weighting and which noise model a fit uses when the
caller leaves them to it ("the noise model travels in the file and is used by default"), and how many
Gauss–Newton steps ``iterate`` allows (``iteration_limit``, for every estimator that takes it).

* ``"unit"`` — W = E (the slides' eqs 18, 22, 31). Covariance: the sandwich
  A (Gᵀ Σ G) A, A = (GᵀG)⁻¹, under ``model`` if given; else A·χ²/dof.
* ``"diagonal"`` — W = 1/diag(Σ): each residual weighted by its total variance under
  ``model`` (required); covariance by the sandwich with the full Σ.
* ``"gls"`` — generalised least squares under ``model`` (required), block-sparse
  (``boresight.core.gls.campaign``).

Each row's pixel σ is its own where the observations carry one (``ObservationSet.sigma_xy_m``: a
centroid's σ from its brightness), the model's σK elsewhere (``gls.structure.row_pixel_sigma``), in
every weighting and in every σ the fit reports.

And the default of ``effects`` (``default_effects``): on a set holding both star and landmark rows the
landmark chain's nuisance that star rows make separable, ``gnss_bias``, is floated unless the caller says
otherwise (``effects=[]`` or ``"none"`` fixes it at 0; ``docs/stars.md``, "Fusion: the default").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.structure import has_pixel_noise
from boresight.errors import InputValueError

__all__ = ["WEIGHTINGS", "default_weighting", "iteration_limit", "default_effects", "SEPARABLE_BY_STARS"]

WEIGHTINGS = ("unit", "diagonal", "gls")

# DECISION: the Kalman filter is only meaningful with its full per-image noise model, so its
# default weighting is always "gls"; the least-squares algorithms default to "gls" when a noise
# model is known and to "unit" otherwise (``default_weighting``). The line model (``line_scan``) is a GLS only, as
# the filter is.
_DEFAULT_WEIGHTING = {"kalman": "gls", "line_scan": "gls"}


def _can_weight(observations: Any, spec: Any, model: DisturbanceModel | None) -> bool:
    """A known noise model with a pixel σ > 0 on every row (the model's σK, or the rows' own
    ``sigma_xy_m``: ``gls.structure.has_pixel_noise``) and a linearizer with a residual map: GLS by default."""
    return bool(spec.kind == "linearizer" and spec.residual_map is not None and has_pixel_noise(observations, model))


def default_weighting(
    observations: Any, name: str, spec: Any, weighting: str | None, model: DisturbanceModel | None
) -> tuple[str, DisturbanceModel | None]:
    """(weighting, model) ``estimate`` uses when the caller leaves them to it.

    ``model=None`` with ``weighting`` None, ``"diagonal"`` or ``"gls"`` takes the observations' own
    noise model (``DisturbanceModel.from_observations``, the file's ``noise`` block), if any.
    ``weighting=None`` is then ``"gls"`` whenever a noise model is known (given or the file's) with
    σ_pixel > 0 and the algorithm can weight (a ``residual_map``; the Kalman filter always), else
    ``"unit"`` — the rule ``boresight estimate`` applies. An explicit ``weighting="unit"`` keeps
    ``model`` as given: the seminar's plain least squares, σ from the scatter unless ``model=``.
    """
    # DECISION: the file's model is taken for the weighted forms only; "unit" stays the slides'
    # eqs 18/22/31 exactly, with the warning that a carried noise model was not used. Algorithm 1
    # (and estimators registered at run time) take no model they were not given.
    weighted = spec.kind == "linearizer" or name in _DEFAULT_WEIGHTING
    if model is None and weighting != "unit" and weighted and getattr(observations, "noise", None) is not None:
        carried = DisturbanceModel.from_observations(observations)
        if carried is not None and (
            weighting is not None or name in _DEFAULT_WEIGHTING or (spec.residual_map is not None and carried.sigma_pixel_m > 0)
        ):
            model = carried
    if weighting is None:
        if name in _DEFAULT_WEIGHTING:
            weighting = _DEFAULT_WEIGHTING[name]
        else:
            weighting = "gls" if _can_weight(observations, spec, model) else "unit"
    return weighting, model


def iteration_limit(iterate: Any) -> int | None:
    """``estimate``'s ``iterate`` as a limit on the Gauss–Newton steps: True → None (the estimator's own default:
    ``MAX_ITERATIONS``, ``MAX_ROBUST_ITERATIONS`` with a loss, the line scanner's), False or None → 1 (one
    linearisation), a positive integer → itself; anything else is refused (``InputValueError``)."""
    if iterate is True:
        return None
    if iterate is False or iterate is None:
        return 1
    if isinstance(iterate, (int, np.integer)) and iterate >= 1:
        return int(iterate)
    raise InputValueError(f"estimate: iterate must be True, False or a positive integer, got {iterate!r}")


#: the effects ``estimate`` floats by default on a set of star and landmark rows (``default_effects``)
SEPARABLE_BY_STARS = ("gnss_bias",)


def default_effects(observations: Any, spec: Any, effects: list[str] | None) -> tuple[list[str] | None, tuple[str, ...]]:
    """(effects to float, those among them floated by default) when ``estimate`` is given ``effects``.

    ``effects`` None (left to ``estimate``) on a set whose rows include both star and landmark targets,
    fitted by a least-squares algorithm (a linearizer: the only ones that float effects): the effects of
    ``SEPARABLE_BY_STARS``. Otherwise ``effects`` as given (``[]``: none).

    DECISION (``docs/stars.md``, "Fusion: the default"): a GNSS position bias is a rotation under nadir
    landmark passes (50 m at 600 km is 17″ of θ) and does not reach a star row (its direction has no position
    stage), so on a fused campaign the star rows separate it from θ. A user who fuses stars with landmarks
    does so to be safe from such a bias: left fixed at 0, a bias the orbit carries is absorbed into θ and the
    joint fit is confidently wrong (on ``stars-and-landmarks`` with 50 m hidden: θ_y 20σ off, the χ² warning
    the only sign). Floated, the joint θ stays within 3σ, and its σθ is still no larger than that of stars
    alone or landmarks alone on any axis there (measured: (0.5246, 0.5246, 0.4597)″ against stars only
    (0.5253, 0.5253, 0.6732)″ and landmarks only (0.5623, 0.5623, 0.6293)″). What it costs: the landmark rows
    no longer pin the axes the bias aliases with (joint σθ x, y 0.384″ with the bias fixed). By information
    additivity the floated joint σθ never exceeds the stars-only σθ; with few star frames it can exceed the
    landmarks-only σθ of a fit that trusts the orbit, which is the price of not trusting it.
    """
    if effects is not None or spec.kind != "linearizer":
        return effects, ()
    kind = getattr(observations, "target_kind", None)
    index = getattr(observations, "target_index", None)
    if kind is None or index is None or len(index) == 0:
        return effects, ()
    seen = set(str(k) for k in np.unique(np.asarray(kind)[np.asarray(index)]))
    if {"star", "landmark"} <= seen:
        return list(SEPARABLE_BY_STARS), SEPARABLE_BY_STARS
    return effects, ()
