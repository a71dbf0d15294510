"""Star rows: an ``ObservationSet`` whose targets are catalogue stars (``docs/stars.md``).

A star is a target at infinity (``docs/architecture.md``, "Thinking ahead: stars and pushbroom
lines"): kind ``"star"``, no position (``landmark_g_m`` NaN), its astrometry in the set's ``stars``
(``orbits.star_catalogue.StarCatalogue``: ICRS direction at the catalogue epoch, proper motion,
parallax, magnitude, HIP id), its id ``"HIP <n>"``. The direction the camera sees at each row is
computed from the row's image (time, position, velocity) by the one apparent-place function,
``orbits.star_apparent.apparent_directions`` (``ObservationSet.row_star_directions_i``).

``star_observations`` builds such a set from identified detections — (image, HIP id, measured
point) triples and the image table — as the simulator's star frames and ``ingest`` of centroid
lists both produce them; ``join_observations`` puts star frames and landmark passes of one
campaign into one set (one image table, one target table, one GLS).
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from boresight.errors import ObservationError
from boresight.observations.model import ObservationSet, canonical_order

__all__ = ["star_observations", "join_observations", "star_target_id", "of_kind", "targets_text"]


def targets_text(obs: ObservationSet) -> str:
    """``"12 landmark(s)"``, ``"80 star(s)"`` or ``"12 landmark(s) + 80 star(s)"``: the target table in words."""
    kinds = obs.target_kinds()
    n_star = int(np.sum(kinds == "star"))
    parts = [f"{kinds.size - n_star} landmark(s)"] if n_star < kinds.size else []
    return " + ".join(parts + ([f"{n_star} star(s)"] if n_star else []))


def of_kind(obs: ObservationSet, kind: str) -> ObservationSet:
    """The rows of one target kind (``"star"`` or ``"landmark"``) with their images (images left
    without a row are dropped): the stars-only or landmarks-only part of a joint campaign."""
    if kind not in ("star", "landmark"):
        raise ObservationError(f"of_kind: kind must be 'star' or 'landmark', got {kind!r}")
    sub = obs.targets(obs.target_kinds() == kind)
    if sub.n_observations == 0:
        raise ObservationError(f"of_kind: the set has no {kind} rows")
    return sub.images(sub.rows_per_image > 0)


def star_target_id(hip: Any) -> np.ndarray:
    """The target id of a star: ``"HIP <n>"`` (``(...,) -> (...,)`` str)."""
    return np.char.add("HIP ", np.asarray(hip, np.int64).astype(str))


def star_observations(
    catalogue: Any,
    image_index: Any,
    hip: Any,
    xy_m: Any,
    *,
    t_s: Any,
    q_is: Any,
    r_sc_i_m: Any,
    v_sc_i_m_s: Any,
    focal_length_m: float,
    epoch_utc: str,
    pass_index: Any = None,
    C_GI: Any = None,
    truth: dict[str, Any] | None = None,
    sigma_xy_m: Any = None,
    **fields_: Any,
) -> ObservationSet:
    """An ObservationSet of star rows from identified detections.

    ``image_index`` (K,) and ``hip`` (K,) (each detection's image and HIP id, any order),
    ``xy_m`` (R, K, 2) measured focal-plane points; the image table ``t_s`` (N,) s from
    ``epoch_utc``, ``q_is`` (R, N, 4) scalar last, ``r_sc_i_m`` and ``v_sc_i_m_s`` (R, N, 3) in GCRS;
    ``C_GI`` (N, 3, 3) defaults to astropy's ITRS → GCRS at each image (``orbits.earth``). Every
    other keyword is an ``ObservationSet`` field (``C_SK_nominal``, ``fov_deg``, ``noise``, …).
    Rows with a row-shaped truth (``xy_true_m``, ``pixel_noise_m`` (R, K, 2)) are reordered with the rows,
    and so is ``sigma_xy_m`` (K, 2), each detection's own centroid σ (NaN: the noise model's), or None.
    A HIP id missing from ``catalogue`` is refused naming it.
    """
    ii = np.asarray(image_index, np.int64).reshape(-1)
    hh = np.asarray(hip, np.int64).reshape(-1)
    xy = np.asarray(xy_m, float)
    if hh.shape != ii.shape or xy.ndim != 3 or xy.shape[1:] != (ii.size, 2):
        raise ObservationError(
            f"star_observations: image_index {ii.shape}, hip {hh.shape} and xy_m (R, K, 2) {xy.shape} must agree on K"
        )
    ids = np.unique(hh)
    where = catalogue.index_of(ids)
    if np.any(where < 0):
        raise ObservationError(f"star_observations: HIP {int(ids[np.argmax(where < 0)])} is not in the star catalogue")
    tgt = np.searchsorted(ids, hh)
    order = canonical_order(ii, tgt)
    t = np.asarray(t_s, float)
    if C_GI is None:
        from astropy import units as u
        from astropy.time import Time

        from orbits.earth import itrs_to_gcrs_dcm

        C_GI = itrs_to_gcrs_dcm(Time(epoch_utc, scale="utc") + t * u.s)
    runs = xy.shape[0]
    if truth is not None:
        truth = {k: (np.asarray(v)[:, order] if k in ("xy_true_m", "pixel_noise_m") else v) for k, v in truth.items()}
    return ObservationSet(
        t_s=t,
        pass_index=np.zeros(t.size, np.int64) if pass_index is None else np.asarray(pass_index, np.int64),
        q_is=q_is,
        r_sc_i_m=r_sc_i_m,
        C_GI=C_GI,
        landmark_ids=star_target_id(ids),
        landmark_g_m=np.full((runs, ids.size, 3), np.nan),
        target_kind=np.full(ids.size, "star"),
        stars=catalogue.subset(where),
        image_index=ii[order],
        target_index=tgt[order],
        xy_m=xy[:, order],
        focal_length_m=focal_length_m,
        epoch_utc=epoch_utc,
        v_sc_i_m_s=v_sc_i_m_s,
        truth=truth,
        sigma_xy_m=None if sigma_xy_m is None else np.asarray(sigma_xy_m, float)[order],
        **fields_,
    )


#: truth entries joined along the image axis (R, N, ...) and along the rows (R, K, ...)
_IMAGE_TRUTH = ("delta_rad", "gnss_error_m")
_ROW_TRUTH = ("xy_true_m", "pixel_noise_m")


def join_observations(first: ObservationSet, second: ObservationSet) -> ObservationSet:
    """One campaign from two sets with the same camera, epoch and runs: images of ``second`` after
    those of ``first`` (its passes renumbered after ``first``'s), targets united (a target id in both
    must be of the same kind; a landmark's position must agree), rows in canonical order.
    Truth: ``theta_rad`` must agree; per-image and per-row truth is joined, the rest of the
    truth is ``first``'s. Star frames and landmark passes of one campaign become one set: one
    image table, so one star-tracker nuisance per image, and one GLS."""
    if first.runs != second.runs:
        raise ObservationError(f"join_observations: {first.runs} runs and {second.runs} runs")
    if not np.isclose(first.focal_length_m, second.focal_length_m) or not np.allclose(first.C_SK_nominal, second.C_SK_nominal):
        raise ObservationError("join_observations: the two sets have different cameras (focal length or C_SK,nominal)")
    if first.epoch_utc != second.epoch_utc:
        raise ObservationError(f"join_observations: epochs differ ({first.epoch_utc!r}, {second.epoch_utc!r})")
    if (first.v_sc_i_m_s is None) != (second.v_sc_i_m_s is None):
        raise ObservationError("join_observations: one set has a velocity and the other none")
    sights = {o.landmark_sight for o in (first, second) if o.landmark_rows(o.target_index).any()}
    if len(sights) > 1:
        raise ObservationError(
            f"join_observations: the two sets' landmark rows carry different sights ({' and '.join(sorted(sights))}; "
            "ObservationSet.landmark_sight): simulate or ingest both the same way"
        )
    kinds_a, kinds_b = first.target_kinds(), second.target_kinds()
    pos = {str(k): j for j, k in enumerate(first.landmark_ids.tolist())}
    new_b = np.empty(second.n_targets, np.int64)
    extra: list[int] = []
    for j, lid in enumerate(second.landmark_ids.tolist()):
        k = pos.get(str(lid))
        if k is None:
            new_b[j] = first.n_targets + len(extra)
            extra.append(j)
            continue
        if kinds_a[k] != kinds_b[j] or (
            kinds_a[k] == "landmark" and not np.allclose(first.landmark_g_m[:, k], second.landmark_g_m[:, j], atol=1e-6)
        ):
            raise ObservationError(f"join_observations: target {lid!r} differs between the two sets (kind or position)")
        new_b[j] = k
    extra_idx = np.asarray(extra, np.int64)
    kinds = np.concatenate([kinds_a, kinds_b[extra_idx]])
    stars = _joined_stars(first, second, extra_idx)
    img = np.concatenate([first.image_index, second.image_index + first.n_images])
    tgt = np.concatenate([first.target_index, new_b[second.target_index]])
    order = canonical_order(img, tgt)
    offset = int(first.pass_index.max()) + 1
    truth = _joined_truth(first, second, extra_idx, order)
    kw = {f.name: getattr(first, f.name) for f in fields(first)}
    kw.update(
        t_s=np.concatenate([first.t_s, second.t_s]),
        pass_index=np.concatenate([first.pass_index, second.pass_index + offset]),
        q_is=np.concatenate([first.q_is, second.q_is], axis=1),
        r_sc_i_m=np.concatenate([first.r_sc_i_m, second.r_sc_i_m], axis=1),
        v_sc_i_m_s=None if first.v_sc_i_m_s is None else np.concatenate([first.v_sc_i_m_s, second.v_sc_i_m_s], axis=1),
        C_GI=np.concatenate([first.C_GI, second.C_GI]),
        landmark_ids=np.concatenate([first.landmark_ids.astype(str), second.landmark_ids.astype(str)[extra_idx]]),
        landmark_g_m=np.concatenate([first.landmark_g_m, second.landmark_g_m[:, extra_idx]], axis=1),
        target_kind=kinds,
        stars=stars,
        image_index=img[order],
        target_index=tgt[order],
        xy_m=np.concatenate([first.xy_m, second.xy_m], axis=1)[:, order],
        truth=truth,
        sigma_xy_m=_joined_sigma(first, second, order),
        landmark_sight=sights.pop() if sights else first.landmark_sight,
    )
    return ObservationSet(**kw)


def _joined_sigma(first: ObservationSet, second: ObservationSet, order: np.ndarray) -> np.ndarray | None:
    """The rows' own pixel σ of ``join_observations``: NaN (the noise model's) on the rows of a set without one."""
    if first.sigma_xy_m is None and second.sigma_xy_m is None:
        return None
    parts = [np.full((o.n_observations, 2), np.nan) if o.sigma_xy_m is None else o.sigma_xy_m for o in (first, second)]
    out: np.ndarray = np.concatenate(parts)[order]
    return out


def _joined_truth(first: ObservationSet, second: ObservationSet, extra_idx: np.ndarray, order: np.ndarray) -> dict | None:
    """The truth of ``join_observations``: per-image and per-row entries joined, per-target ones united."""
    if first.truth is None or second.truth is None:
        return None
    ta, tb = first.truth, second.truth
    if "theta_rad" in ta and "theta_rad" in tb and not np.allclose(ta["theta_rad"], tb["theta_rad"], rtol=0, atol=1e-15):
        raise ObservationError("join_observations: the two sets have different true θ")
    truth = dict(ta)
    for key in _IMAGE_TRUTH:
        if key in ta and key in tb:
            truth[key] = np.concatenate([ta[key], tb[key]], axis=1)
    for key in _ROW_TRUTH:
        if key in ta and key in tb:
            truth[key] = np.concatenate([ta[key], tb[key]], axis=1)[:, order]
    for key in ("C_IS", "r_sc_i_m"):  # per image, no run axis
        if key in ta and key in tb:
            truth[key] = np.concatenate([ta[key], tb[key]])
    for key in set(_IMAGE_TRUTH + _ROW_TRUTH + ("C_IS", "r_sc_i_m")) & (set(ta) ^ set(tb)):
        truth.pop(key, None)
    if "landmark_g_m" in ta:  # true landmark positions (T, 3): none for a star (NaN)
        lb = np.asarray(tb.get("landmark_g_m", np.full((second.n_targets, 3), np.nan)))
        truth["landmark_g_m"] = np.concatenate([np.asarray(ta["landmark_g_m"]), lb[extra_idx]])
    if "catalogue_error_m" in ta or "catalogue_error_m" in tb:  # per target; a star has none (zeros)
        ca = ta.get("catalogue_error_m", np.zeros((first.runs, first.n_targets, 3)))
        cb = tb.get("catalogue_error_m", np.zeros((second.runs, second.n_targets, 3)))
        truth["catalogue_error_m"] = np.concatenate([ca, np.asarray(cb)[:, extra_idx]], axis=1)
    return truth


def _joined_stars(first: ObservationSet, second: ObservationSet, extra_idx: np.ndarray) -> Any:
    """The star astrometry of the joined target table: ``first``'s, then ``second``'s new star targets."""
    rank_b = second.star_rank()[extra_idx]
    new_b = rank_b[rank_b >= 0]
    if new_b.size == 0 or second.stars is None:
        return first.stars
    if first.stars is None:
        return second.stars.subset(new_b)
    from orbits.star_catalogue import StarCatalogue

    a, b = first.stars, second.stars.subset(new_b)
    if a.epoch_jd_tt != b.epoch_jd_tt:
        raise ObservationError("join_observations: the star catalogues have different epochs")
    names = [f.name for f in fields(StarCatalogue) if f.name not in ("epoch_jd_tt", "source")]
    return StarCatalogue(
        **{n: np.concatenate([getattr(a, n), getattr(b, n)]) for n in names}, epoch_jd_tt=a.epoch_jd_tt, source=a.source
    )
