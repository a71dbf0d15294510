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
* **Noise models** (never a σ the data do not support). Each input declares its own noise
  model (``ObservationSet.noise``: ``pixel``, ``star_tracker``, ``gnss``, ``catalogue``); the merged set
  carries one, built term by term so that no file's rows are weighted by another file's σ:

  - *pixel σ*: where the inputs' pixel σ differ, every row without its own σ gets its file's pixel σ
    in the per-row σ column (``sigma_xy_m``; rows that carry their own keep it), so the one GLS on the
    merged rows weights each file's rows by the noise that file declares, Σ_kk = σ_k² (``docs/architecture.md``,
    "The error structure and the one GLS on rows"); the merged model's pixel σ is input 0's and then
    acts on no row of a file whose σ differs.
  - *the other terms* (star tracker σ and error mode, GNSS σ and error mode, catalogue σ): equal in every
    input → kept. A term that cannot act on an input's rows is not that input's to declare: the GNSS and
    catalogue terms act on landmark rows only (``docs/effects.md``, "Effects on star rows": a star has no
    position or landmark stage), so a file of star rows only (``ingest --star-centroids`` writes GNSS 0,
    catalogue 0) yields to the files with landmark rows. What is left differing is a real conflict —
    refused by name (the inputs, the term, both values, what to do), never resolved by input order.
  - an input without a noise model declares nothing and takes the merged one (the CLI's ``--sigma-*``
    options then set it for every file); no input with one → no model.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable, Sequence

import numpy as np

from boresight.errors import ObservationError
from boresight.observations.model import ObservationSet
from boresight.observations.stars import join_observations

__all__ = ["merge_observations"]


def merge_observations(sets: Iterable[ObservationSet], names: Sequence[str] | None = None) -> ObservationSet:
    """One ``ObservationSet`` from several (files of one campaign).

    Parameters
    ----------
    sets : iterable of ObservationSet
        one run each, the same camera (focal length and C_SK,nominal).
    names : sequence of str, optional
        what to call each input in a refusal (the file names); default ``input 0``, ``input 1``, …

    Returns
    -------
    ObservationSet
        the images of every input in order (times on the first input's epoch, pass indices made
        distinct per input), targets united by id, rows in canonical order; no truth; one noise
        model and each file's pixel σ on its rows where the files' differ (module docstring, "Noise
        models"). A single input is returned as it is.

    Raises
    ------
    ObservationError
        no input; an input with more than one run; a different camera from input 0; a target id
        whose kind or position differs between inputs (``join_observations``); a noise term that
        two inputs set differently where it acts on both inputs' rows (module docstring).
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

    label = [f"input {k}" for k in range(len(sets))] if names is None else [str(n) for n in names]
    if len(label) != len(sets):
        raise ObservationError(f"merge_observations: {len(label)} names for {len(sets)} observation sets")
    noise, own_pixel_m = _merged_noise(sets, label)
    t0 = Time(first.epoch_utc, scale="utc")
    drop_velocity = any(o.v_sc_i_m_s is None for o in sets)
    aligned = []
    for o, pixel_m in zip(sets, own_pixel_m):
        shift_s = 0.0 if o.epoch_utc == first.epoch_utc else float((Time(o.epoch_utc, scale="utc") - t0).sec)
        aligned.append(
            dataclasses.replace(
                o,
                epoch_utc=first.epoch_utc,
                t_s=np.asarray(o.t_s, float) + shift_s,
                v_sc_i_m_s=None if drop_velocity else o.v_sc_i_m_s,
                truth=None,
                noise=noise,
                sigma_xy_m=o.sigma_xy_m if pixel_m is None else _own_sigma(o, pixel_m),
            )
        )
    return functools.reduce(join_observations, aligned)


#: the noise terms that act on landmark rows only (``docs/effects.md``, "Effects on star rows"): a file of
#: star rows only cannot declare them
_LANDMARK_ONLY = ("gnss", "catalogue")


def _merged_noise(sets: list[ObservationSet], label: list[str]) -> tuple[dict | None, list[float | None]]:
    """The merged noise model and, per input, the pixel σ (m) to write on its rows without their own
    (None: the merged model's applies); module docstring, "Noise models"."""
    declared = [(k, o.noise) for k, o in enumerate(sets) if o.noise is not None]
    if not declared:
        return None, [None] * len(sets)
    k0, base = declared[0]
    merged = {table: dict(row) for table, row in base.items()}
    has_landmarks = [bool(np.any(o.target_kinds()[o.target_index] == "landmark")) for o in sets]
    for table, row in base.items():
        if table == "pixel":
            continue
        acting = [(k, n) for k, n in declared if table not in _LANDMARK_ONLY or has_landmarks[k]]
        for key in row:
            # DECISION: a value that cannot act on its file's rows is no voice (a star file's GNSS 0 does not outvote a
            # pass's 15 m); differing values that act are refused, never settled by the order of the files. A term
            # acting on no input's rows weights nothing: the first model's is kept.
            voices = acting if acting else declared[:1]
            kv, value = voices[0][0], voices[0][1][table][key]
            for k, n in voices[1:]:
                if n[table][key] != value:
                    raise ObservationError(
                        f"merge_observations: {label[kv]} and {label[k]} declare different noise {table}.{key} "
                        f"({value!r} and {n[table][key]!r}) and it acts on both files' rows; one campaign has one "
                        f"{table} noise — write one file again with the other's value (boresight ingest --sigma-* "
                        "options, or the file's noise metadata)"
                    )
            merged[table][key] = value
    pixel_m = float(base["pixel"]["sigma_m"])
    own = [
        None if o.noise is None or float(o.noise["pixel"]["sigma_m"]) == pixel_m else float(o.noise["pixel"]["sigma_m"])
        for o in sets
    ]
    for k, v in enumerate(own):
        if v is not None and (pixel_m == 0.0 or v == 0.0):
            raise ObservationError(
                f"merge_observations: {label[k0]} declares pixel σ {pixel_m!r} m and {label[k]} {v!r} m; a pixel σ of 0 "
                "(noise-free) cannot weight rows beside another file's — write the noise-free file with its real pixel σ "
                "(boresight ingest --sigma-pixel-px)"
            )
    return merged, own


def _own_sigma(o: ObservationSet, pixel_m: float) -> np.ndarray:
    """``o``'s per-row σ (K, 2) m with ``pixel_m`` (its file's pixel σ) on every row without its own."""
    own = np.full((o.n_observations, 2), np.nan) if o.sigma_xy_m is None else np.asarray(o.sigma_xy_m, float)
    return np.where(np.isnan(own), pixel_m, own)
