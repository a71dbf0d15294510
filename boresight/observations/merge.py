"""One campaign from several observation sets: ``merge_observations`` (``boresight diagnose A.ecsv B.ecsv``).

The files of one campaign — one per pass, per day, per downlink — are one problem: one image table
(the images of every input in order), one target table (targets united by id) and one row table in
canonical (image, target) order (``docs/architecture.md``, "The row model"). It is built on rows, by
the one joining function of the data model, ``observations.stars.join_observations`` (images of the
second set after those of the first, its passes renumbered after the first's, targets united — a
target id in both must be of the same kind, a landmark's position must agree to 1 µm —, rows in
canonical order), applied input after input. What merging adds to joining:

* **Epochs.** Each input's image times are referred to the first input's epoch (campaign time: the
  alignment drift, the whiteness order), t'_n = t_n + (epoch_k − epoch_0) in seconds (astropy ``Time``, UTC).
* **Flight data only.** Every input must have one run; the truth of a simulation is dropped (a merged
  set is data, not a simulated campaign).
* **Velocities.** Kept when every input has them, dropped (None) when one has none: the velocity is
  optional in the file format, and an effect that needs it says so.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable

import numpy as np

from boresight.observations.model import ObservationError, ObservationSet
from boresight.observations.stars import join_observations

__all__ = ["merge_observations"]


def merge_observations(sets: Iterable[ObservationSet]) -> ObservationSet:
    """One ``ObservationSet`` from several (files of one campaign).

    Parameters
    ----------
    sets : iterable of ObservationSet
        one run each, the same camera (focal length and C_SK,nominal).

    Returns
    -------
    ObservationSet
        the images of every input in order (times on the first input's epoch, pass indices made
        distinct per input), targets united by id, rows in canonical order; no truth. A single
        input is returned as it is.

    Raises
    ------
    ObservationError
        no input; an input with more than one run; a different camera from input 0; a target id
        whose kind or position differs between inputs (``join_observations``).
    """
    sets = list(sets)
    if not sets:
        raise ObservationError("merge_observations: no observation set given")
    if len(sets) == 1:
        return sets[0]
    first = sets[0]
    for k, o in enumerate(sets):
        if o.runs != 1:
            raise ObservationError(f"merge_observations: input {k} has {o.runs} runs; give one run per file")
        if not np.isclose(o.focal_length_m, first.focal_length_m) or not np.allclose(o.C_SK_nominal, first.C_SK_nominal):
            raise ObservationError(
                f"merge_observations: input {k} has a different camera (focal length or C_SK,nominal) than input 0"
            )
    from astropy.time import Time

    t0 = Time(first.epoch_utc, scale="utc")
    drop_velocity = any(o.v_sc_i_m_s is None for o in sets)
    aligned = []
    for o in sets:
        shift_s = 0.0 if o.epoch_utc == first.epoch_utc else float((Time(o.epoch_utc, scale="utc") - t0).sec)
        aligned.append(
            dataclasses.replace(
                o,
                epoch_utc=first.epoch_utc,
                t_s=np.asarray(o.t_s, float) + shift_s,
                v_sc_i_m_s=None if drop_velocity else o.v_sc_i_m_s,
                truth=None,
            )
        )
    return functools.reduce(join_observations, aligned)
