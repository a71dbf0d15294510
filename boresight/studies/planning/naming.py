"""The planner's naming scores: will ``boresight.diagnose`` *name* each required effect of a candidate
campaign?

The model — the naming probability P_name and the nameable size η of an effect given its information
with θ and the nuisances eliminated — is the diagnosis' own (``boresight.studies.discrepancy.naming_power``,
derived there), shared with ``diagnose``'s ``min_nameable``: one model, below both. What is the
planner's is only the route to its inputs: a campaign's Fisher information I of [θ, effects] (every
nuisance marginalised) and R (only the per-image errors), both sums of per-pass blocks
(``fisher.score_candidates``); the effects' information given θ is the Schur complement of I over θ
(``naming_power.theta_schur``).
"""

from __future__ import annotations

import numpy as np

from boresight.studies.discrepancy.naming_power import (
    LOWER_BOUND_SLACK,
    NamingRule,
    NcxSf,
    canonical_fractions,
    detection_only_size,
    nameable_sizes,
    theta_schur,
)

__all__ = [
    "NamingRule",
    "NcxSf",
    "canonical_fractions",
    "theta_schur",
    "naming_scores",
    "detection_only_size",
    "LOWER_BOUND_SLACK",
]

#: the first three parameters of a planner's information are θ
_NB = 3


def naming_scores(
    info, raw, n_rows, effect_slices, required, lam_joint, rival_slices, rule: NamingRule, iterations: int = 20, scan_sizes=None
):
    """Nameability of each required effect in C campaigns: ``naming_power.nameable_sizes`` on the
    effects' information given θ (``theta_schur`` of ``info``) and ``raw``'s effect block.

    ``info`` (C, P, P) information [θ, required effects, look-alikes] (nuisances marginalised);
    ``raw`` (C, P, P) the same with only the per-image errors marginalised; ``n_rows`` (C,)
    whitened data rows; ``effect_slices``/``required`` the required effects (slices into ``info``)
    and their sizes; ``lam_joint`` (C, E) the detection non-centrality of each at its required size
    with the required effects floated; ``rival_slices`` every effect's slice (required and look-alikes);
    ``scan_sizes`` a scanned rival's number of boundaries (``naming_power.nameable_sizes``).

    Returns (η (C, E) nameable size / required size — inf when not separable; P_name (C, E)
    at the required size; ρ (C, E) the largest canonical correlation of each required effect
    with the base model; the binding rival (C, E) index into ``rival_slices`` or −1).
    """

    def shift(sl):
        return slice(sl.start - _NB, sl.stop - _NB)

    return nameable_sizes(
        theta_schur(info),
        np.asarray(raw)[..., _NB:, _NB:],
        n_rows,
        [shift(sl) for sl in effect_slices],
        required,
        lam_joint,
        [shift(sl) for sl in rival_slices],
        rule,
        iterations,
        scan_sizes,
    )
