"""Simulate measurements of a campaign (one or more passes) for a batch of runs, on rows.

``draw_errors`` is the only random step: every run gets its own misalignment θ and sensor errors
along a leading run axis. ``observe`` is deterministic array code that turns the true geometry
(computed once, ``orbits.scenario.campaign_arrays``) and those errors into what the sensors
report, so one pass and 45 000 runs go through the same code (``orbits.scenario.simulate_passes`` is
the scenario-level front door).

The true camera attitude is ``C_IK = exp(−Φ(θ)) C_SK,nom C_ES C_IE`` (Kiev 2012 eqs 23-24 with a
star-tracker mount C_ES; body E ≡ nominal camera frame so C_SK,nom = C_ESᵀ), each image point is
the collinearity projection (eq 3) plus pixel noise, the star tracker reports
``A = exp(Φ(δ)) C_ES C_IE`` and GNSS reports ``r + ξ``; catalogue coordinates carry N(0, σP²).

Effects of the catalogue (``orbits.effects``; a scenario's ``[effects]`` table) are applied
forward with their one definition: the catalogue, GNSS position and star-tracker attitude are
reported as ``r_L + ξ_L + Δr_L``, ``r + ξ + Δr``, ``exp(Φ(ε)) exp(Φ(δ)) C_IS``; a thermal
misalignment φ adds to θ in ``C_IK``; image-stage effects map the ideal projection to the
measured point before pixel noise. ``unmodelled`` perturbations (test cases outside the
catalogue) perturb the measured image points or the catalogue after that.

Rows (``docs/architecture.md``, "The row model"). The observations are rows — (image, target)
pairs in canonical order, ``orbits.records`` — given (``observe(rows=…)``: single-use ground-control
points, a file's own rows) or found by ``visible_rows``, pass by pass (a scenario's landmarks belong
to their pass) and in pieces of bounded size. Every per-observation array is (R, K, …): the gathers
``C_GI[image_index]``, ``landmark_g_m[target_index]``; nothing has an images × targets axis pair, so
memory is O(R (K + N + T)) (``tests/orbits/test_simulate_rows.py``).

Pixel-noise draw order. ``draw_errors(rows=…, grid_stream=True)`` draws the pixel noise in the order
of the old images × landmarks grid — every cell, run-major, those without a row discarded — in
pieces of O(K) numbers (a Generator's ``normal`` drawn in pieces is the same stream as one draw), so
every seed of a scenario study gives the numbers it gave before the row model. ``grid_stream=False``
draws one pair per row, (R, K, 2). For a complete set (every target in every image) the two are the
same stream, drawn at once. DECISION: the grid order is kept only while the grid holds at most
``GRID_STREAM_MAX_FILL`` cells per row (every shipped scenario: ≤ 12): its cost is R·N·M normals, which
for a campaign whose targets differ from image to image grows as the square of its size; beyond,
the rows are drawn directly and CPU stays linear in observations.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import effects as fx
from .camera import Camera, project, render_image_points
from .errors import InputValueError
from .landmarks import catalogue_errors
from .records import ImageRecords, complete_rows, row_offsets
from .rotations import misalignment_dcm, quat_from_dcm, rotvec_dcm, star_tracker_error_dcm
from .sensors import GnssErrors, PixelNoise, StarTrackerErrors
from .sight import EARTH_SPIN_G_RAD_S, LANDMARK_SIGHTS, SightCorrections, apparent_sight_i

__all__ = [
    "Measurements",
    "draw_errors",
    "observe",
    "visible_rows",
    "pixel_draws_per_run",
    "GRID_STREAM_MAX_FILL",
]

#: the grid draw order of the pixel noise is kept while the images × landmarks grid holds at most
#: this many cells per row (module docstring)
GRID_STREAM_MAX_FILL = 64
#: the smallest piece (normals) of a grid-order draw; pieces are otherwise 4 K pairs (O(K) memory)
_MIN_PIECE = 1 << 16


@dataclass(frozen=True)
class Measurements(ImageRecords):
    """What the sensors report (the estimator's input) plus the truth behind it, on rows.

    The three tables of ``orbits.records.ImageRecords`` (R runs, N images, T targets, K rows):
    ``q_is`` (R, N, 4) star-tracker attitude quaternion inertial → star tracker, scalar last;
    ``r_sc_i_m`` (R, N, 3) GNSS position in I; ``landmark_g_m`` (R, T, 3) catalogue coordinates in
    G; ``image_index``, ``target_index`` (K,) the observations in canonical order; ``xy_m`` (R, K, 2)
    their image points. Known: ``t_s`` (N,), ``pass_index`` (N,), ``C_GI`` (N, 3, 3),
    ``C_SK_nominal`` (3, 3), ``camera``, ``epoch_utc``. Truth: ``truth`` dict with ``theta_rad``
    (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3), ``catalogue_error_m`` (R, T, 3),
    ``pixel_noise_m`` and ``xy_true_m`` (R, K, 2), ``C_IS`` (N, 3, 3), ``r_sc_i_m`` (N, 3),
    ``landmark_g_m`` (T, 3). ``v_sc_i_m_s`` (R, N, 3) is the GNSS velocity in I (the true
    velocity: a GNSS receiver's velocity error, ~0.05 m/s, is negligible here) or None.
    With effects, ``truth["effects"]`` maps each hidden effect's name to its parameters (k,) or
    (R, k) in the effect's units; ``truth["unmodelled"]`` lists out-of-catalogue perturbations.
    """

    C_SK_nominal: np.ndarray
    camera: Camera
    epoch_utc: str
    truth: dict[str, Any] = field(default_factory=dict)
    frames: dict[str, Any] = field(
        default_factory=lambda: {
            "inertial": "spherical-earth inertial (Kiev 2012)",
            "earth_fixed": "spherical-earth fixed (Kiev 2012)",
        }
    )
    v_sc_i_m_s: np.ndarray | None = None
    #: the star targets' astrometry (``orbits.star_catalogue.StarCatalogue``, one entry per target whose
    #: position is NaN, in target order), or None without star rows
    stars: Any = None
    #: (K, 2) each row's own pixel σ (m) that its noise was drawn with (star rows by magnitude), NaN where the
    #: scenario's one pixel σ applies; None: every row that one σ
    sigma_xy_m: Any = None
    #: what the landmark rows' lines of sight were simulated with: ``"geometric"`` or ``"light_time+aberration"``
    #: (``observe``; the estimator's data model models the same, ``ObservationSet.landmark_sight``)
    landmark_sight: str = "geometric"


def draw_errors(
    rng: np.random.Generator,
    runs: int,
    pass_index: Any,
    n_landmarks: int,
    *,
    rows: Any = None,
    grid_stream: bool = True,
    theta_true_rad: Any = None,
    theta_sigma_rad: float = 0.0,
    star_tracker: StarTrackerErrors = StarTrackerErrors(),
    gnss: GnssErrors = GnssErrors(),
    pixel: PixelNoise = PixelNoise(),
    catalogue_sigma_m: float = 0.0,
    pixel_sigma_rows_m: Any = None,
) -> dict[str, Any]:
    """Draw every run's θ and sensor errors (the only random step), leading run axis.

    Draw order (fixed, so a seed reproduces a run): θ (if random), star tracker (per image, then
    per pass, pass by pass), GNSS (same), catalogue, pixel noise. ``rows`` = (image_index,
    target_index) (K,) in canonical order: the observations that get pixel noise (None: every
    landmark in every image, K = N·M). ``grid_stream``: the pixel noise in the grid's draw order
    (module docstring, "Pixel-noise draw order"; the same stream as before the row model) or one
    draw per row. ``pixel_sigma_rows_m`` (K, 2) or None: each row's own σ of x and y (a star's
    centroid σ from its magnitude, ``orbits.star_frames.CentroidNoise``), NaN where ``pixel.sigma_m``
    applies: the same standard normals (the same stream) times each row's σ.

    Returns ``theta_rad`` (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3),
    ``catalogue_error_m`` (R, M, 3), ``pixel_noise_m`` (R, K, 2).
    """
    pass_index = np.asarray(pass_index, int)
    n = pass_index.size
    if theta_true_rad is not None:
        theta = np.broadcast_to(np.asarray(theta_true_rad, float), (runs, 3)).copy()
    else:
        theta = rng.normal(size=(runs, 3)) * theta_sigma_rad
    passes = np.unique(pass_index)
    img, tgt = complete_rows(n, n_landmarks) if rows is None else (np.asarray(a, np.int64) for a in rows)
    return {
        "theta_rad": theta,
        "delta_rad": _per_pass(rng, star_tracker.sample, runs, pass_index, passes),
        "gnss_error_m": _per_pass(rng, gnss.sample, runs, pass_index, passes),
        "catalogue_error_m": catalogue_errors(rng, runs, n_landmarks, catalogue_sigma_m),
        "pixel_noise_m": _pixel_noise(rng, pixel, runs, n, n_landmarks, img, tgt, grid_stream)
        if pixel_sigma_rows_m is None
        else _pixel_noise(rng, PixelNoise(1.0), runs, n, n_landmarks, img, tgt, grid_stream)
        * np.where(np.isnan(pixel_sigma_rows_m), pixel.sigma_m, np.asarray(pixel_sigma_rows_m, float))[None],
    }


def pixel_draws_per_run(n_images: int, n_landmarks: int, n_rows: int, grid_stream: bool = True) -> int:
    """Pixel-noise pairs ``draw_errors`` draws per run for K = ``n_rows`` rows of an N × M campaign:
    N·M in the grid's draw order (module docstring: a complete set, or at most
    ``GRID_STREAM_MAX_FILL`` cells per row), K in the rows' order.

    >>> pixel_draws_per_run(120, 128, 1320), pixel_draws_per_run(1200, 12860, 12860)
    (15360, 12860)
    """
    cells = int(n_images) * int(n_landmarks)
    if cells == n_rows or (grid_stream and cells <= GRID_STREAM_MAX_FILL * max(int(n_rows), 1)):
        return cells
    return int(n_rows)


def _pixel_noise(
    rng: Any, pixel: PixelNoise, runs: int, n_images: int, n_landmarks: int, img: Any, tgt: Any, grid_stream: bool
) -> np.ndarray:
    """Pixel noise (R, K, 2) of the rows (img, tgt), in the grid's or the rows' draw order."""
    k = int(img.size)
    cells = n_images * n_landmarks
    if k == cells or pixel_draws_per_run(n_images, n_landmarks, k, grid_stream) == k:
        # complete (the grid is the rows: the same stream), or one pair per row
        return pixel.sample(rng, runs, 1, k)[:, 0]
    out = np.empty((runs, k, 2))
    piece = max(_MIN_PIECE, 8 * k)  # normals per draw: O(K) memory
    if 2 * cells <= piece:  # whole runs at a time: the stream is run-major
        step = piece // (2 * cells)
        for r0 in range(0, runs, step):
            r1 = min(runs, r0 + step)
            out[r0:r1] = pixel.sample(rng, r1 - r0, n_images, n_landmarks)[:, img, tgt]
        return out
    start = row_offsets(img, n_images)
    per = max(1, piece // (2 * n_landmarks))  # images per draw
    for r in range(runs):
        for n0 in range(0, n_images, per):
            n1 = min(n_images, n0 + per)
            z = pixel.sample(rng, 1, n1 - n0, n_landmarks)[0]
            a, b = start[n0], start[n1]
            out[r, a:b] = z[img[a:b] - n0, tgt[a:b]]
    return out


def visible_rows(
    *,
    pass_index: Any,
    r_sc_i_m: Any,
    C_GI: Any,
    C_IE: Any,
    landmarks_g_m: Any,
    landmark_pass: Any,
    camera: Camera,
    visibility_margin: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The observations of a scenario campaign: (image_index, target_index) (K,) in canonical order.

    Landmark m is observed in image n when it belongs to the image's pass (``landmark_pass`` (M,))
    and lies inside the field (``Camera.visible``, the half-field widened by ``visibility_margin``)
    at the nominal attitude (θ = 0, body ≡ nominal camera). Checked pass by pass, in pieces of at
    most ``_MIN_PIECE`` image × landmark pairs: memory O(K + piece), never the campaign's grid.
    """
    pass_index = np.asarray(pass_index, int)
    r_sc = np.asarray(r_sc_i_m, float)
    C_GI = np.asarray(C_GI, float)
    C_IE = np.asarray(C_IE, float)
    lm_g = np.asarray(landmarks_g_m, float)
    lm_pass = np.asarray(landmark_pass)
    half = np.degrees(np.arctan(np.tan(np.radians(camera.fov_deg) / 2) * visibility_margin))
    field_cam = Camera(camera.focal_length_m, 2 * half)
    imgs, tgts = [], []
    lm_groups = {int(lm_pass[g[0]]): g for g in _groups(lm_pass)}
    for ni in _groups(pass_index):
        mi = lm_groups.get(int(pass_index[ni[0]]))
        if mi is None:
            continue
        per = max(1, _MIN_PIECE // mi.size)
        for a in range(0, ni.size, per):
            n = ni[a : a + per]
            lm_i = np.einsum("nij,mj->nmi", C_GI[n], lm_g[mi])
            s_nom = np.einsum("nij,nmj->nmi", C_IE[n], lm_i - r_sc[n][:, None, :])  # body ≡ nominal camera
            vi, vm = np.nonzero(field_cam.visible(s_nom))
            imgs.append(n[vi])
            tgts.append(mi[vm])
    if not imgs:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    img = np.concatenate(imgs).astype(np.int64)
    tgt = np.concatenate(tgts).astype(np.int64)
    order = np.lexsort((tgt, img))
    return img[order], tgt[order]


def observe(
    errors: dict[str, Any],
    *,
    t_s: Any,
    pass_index: Any,
    r_sc_i_m: Any,
    C_GI: Any,
    C_IE: Any,
    landmarks_g_m: Any,
    landmark_ids: Any,
    camera: Camera,
    C_ES: Any,
    landmark_pass: Any = None,
    rows: Any = None,
    epoch_utc: str = "2012-01-31T00:00:00",
    visibility_margin: float = 1.0,
    frames: dict[str, Any] | None = None,
    v_sc_i_m_s: Any = None,
    effects: Any = None,
    attitude_rate_e_rad_s: Any = None,
    time_tag_rotation_e_rad: Any = None,
    time_tag_rotation_dt_s: Any = None,
    unmodelled: Any = (),
    row_directions_i: Any = None,
    star_catalogue: Any = None,
    pixel_sigma_rows_m: Any = None,
    landmark_sight: str = "geometric",
) -> Measurements:
    """What the sensors report for given errors (deterministic; broadcasts over the run axis).

    ``rows`` = (image_index, target_index) (K,) in canonical order: the observations (a file's own
    rows, single-use ground-control points, ``orbits.scenario.campaign_arrays``' visible rows); without
    them, ``visible_rows`` of ``landmark_pass`` (M,) and the camera's field widened by
    ``visibility_margin``. ``errors["pixel_noise_m"]`` is (R, K, 2) (``draw_errors`` with the same rows).
    ``effects``: mapping effect name → parameters (k,) or (R, k) in the effect's units
    (``orbits.effects``); velocity-dependent effects need ``v_sc_i_m_s`` (N, 3); ``time_tag``
    needs ``time_tag_rotation_e_rad`` (N, 3), the rotation vector of the attitude law from t to
    t + dt in body axes, log(C_IE(t + dt) C_IE(t)ᵀ), for ``time_tag_rotation_dt_s`` = dt (the exact
    shift; ``orbits.scenario.campaign_arrays`` provides both), or ``attitude_rate_e_rad_s``
    (N, 3), the body rate of the law at t + dt (first order, ε = −ω dt; any per-run dt). ``unmodelled``: ``orbits.effects.Unmodelled``
    perturbations outside the catalogue (tests of "unexplained structure"). ``row_directions_i``
    (K, 3): the true inertial direction of each row whose target is at infinity (a star: its
    apparent direction, ``orbits.star_apparent``; ``orbits.star_campaign``), NaN on a landmark row:
    used in place of C_GI r_L − r, so a star goes through the same attitude, misalignment and
    image stages (position and landmark stages do not reach it). ``star_catalogue``: those targets'
    astrometry, carried to ``Measurements.stars`` (the estimator's data model computes each star row's
    direction from it). ``pixel_sigma_rows_m`` (K, 2): each row's own pixel σ, the one ``draw_errors`` drew
    its noise with (NaN: the scenario's), carried to ``Measurements.sigma_xy_m`` (the estimator weights each
    row by it). ``landmark_sight``: ``"geometric"`` (C_GI r_L − r, the seminar's model) or
    ``"light_time+aberration"``: each landmark row's true line of sight is the direction in which the spacecraft
    sees the landmark (``orbits.sight.apparent_sight_i``: light time and aberration from the true position and
    ``v_sc_i_m_s``, the Earth's spin ``EARTH_SPIN_G_RAD_S``), times the geometric range (module docstring).
    """
    t_s = np.asarray(t_s, float)
    pass_index = np.asarray(pass_index, int)
    r_sc = np.asarray(r_sc_i_m, float)
    C_GI = np.asarray(C_GI, float)
    C_IE = np.asarray(C_IE, float)
    lm_g = np.asarray(landmarks_g_m, float)
    C_ES = np.asarray(C_ES, float)
    C_IS = C_ES @ C_IE  # (N, 3, 3)
    C_SK_nom = C_ES.T
    theta = errors["theta_rad"]
    delta = errors["delta_rad"]
    gnss_err = errors["gnss_error_m"]
    cat_err = errors["catalogue_error_m"]
    pix = errors["pixel_noise_m"]

    img, tgt = _observed_rows(rows, landmark_pass, pass_index, r_sc, C_GI, C_IE, lm_g, camera, visibility_margin)
    if np.shape(pix)[1:] != (img.size, 2):
        raise InputValueError(f"observe: pixel_noise_m has shape {np.shape(pix)}, the {img.size} rows need (R, {img.size}, 2)")
    # per row: the landmark in I and its offset from the spacecraft, (K, 3) — gathers, no grid
    rel = _apparent_rows(
        _row_vectors(C_GI, lm_g, r_sc, img, tgt, row_directions_i), landmark_sight, C_GI, lm_g, r_sc, v_sc_i_m_s, img, tgt
    )

    runs = theta.shape[0]
    F = camera.focal_length_m
    names, p_si = _effect_parameters(effects, runs)
    v = None if v_sc_i_m_s is None else np.broadcast_to(np.asarray(v_sc_i_m_s, float), (runs,) + r_sc.shape)
    rate = None
    if attitude_rate_e_rad_s is not None:
        rate = np.broadcast_to(np.einsum("ij,nj->ni", C_ES, np.asarray(attitude_rate_e_rad_s, float)), (runs,) + r_sc.shape)
    lm_rep = lm_g[None] + cat_err
    r_rep = r_sc[None] + gnss_err
    A_rep = star_tracker_error_dcm(delta) @ C_IS[None]
    phi = None
    if names:
        # the effects' one definition, applied forward (orbits.effects): contexts are the reported quantities
        def ctx(**kw: Any) -> Any:
            base = dict(
                focal_length_m=F,
                C_SK=C_SK_nom,
                C_IS=A_rep,
                r_i_m=r_rep,
                landmark_g_m=lm_rep,
                C_GI=C_GI,
                v_i_m_s=v,
                rate_s_rad_s=rate,
                t_s=t_s,
            )
            return fx.EffectContext(**dict(base, **kw))

        try:
            lm_rep = fx.forward_reported(lm_g, lm_rep, names, p_si, lambda y: ctx(landmark_g_m=y), "landmark")
            r_rep = fx.forward_reported(r_sc, r_rep, names, p_si, lambda y: ctx(r_i_m=y), "position")
            if any(fx.EFFECTS[n].stage == "star_tracker" for n in names):
                A0 = A_rep
                st_names, eps0 = names, 0.0
                if "time_tag" in names and time_tag_rotation_e_rad is not None:
                    # the exact shift A_rep(t) = A_true(t + dt): ε = log(A_true(t + dt) A_true(t)ᵀ) from the law
                    dt = np.asarray(effects["time_tag"], float).reshape(-1)
                    if not np.allclose(dt, time_tag_rotation_dt_s, rtol=0, atol=1e-12):
                        raise fx.EffectError(
                            f"observe: time_tag_rotation_e_rad was computed for dt = {time_tag_rotation_dt_s} s, "
                            f"the effect has {dt.tolist()} s"
                        )
                    eps0 = np.einsum("ij,nj->ni", C_ES, np.asarray(time_tag_rotation_e_rad, float))[None]
                    st_names = [n for n in names if n != "time_tag"]
                for _ in range(fx.FORWARD_ITERATIONS):
                    eps = fx.stage_offset(st_names, p_si, ctx(C_IS=A_rep, r_i_m=r_rep), "star_tracker")
                    A_rep = rotvec_dcm(eps0 + (0.0 if eps is None else eps)) @ A0
            phi = fx.stage_offset(names, p_si, ctx(r_i_m=r_rep), "misalignment")
        except fx.MissingContextError as exc:
            raise fx.EffectError(
                f"observe: an effect in {names} {exc} (pass v_sc_i_m_s / time_tag_rotation_e_rad or attitude_rate_e_rad_s)"
            ) from None

    th = theta[:, None] if phi is None else theta[:, None] + phi
    C_IK = misalignment_dcm(th) @ (C_SK_nom @ C_IS)[None]  # (R, N, 3, 3)
    # s = C_IK(image) rel per row, (R, K, 3); the rows' attitudes gathered a few runs at a time
    # (pieces of ~2¹⁸ rows: the (R, K, 3, 3) gather would be the simulator's largest array)
    s_true = np.empty((runs, img.size, 3))
    step = max(1, (1 << 18) // max(img.size, 1))
    for r0 in range(0, runs, step):
        s_true[r0 : r0 + step] = np.einsum("rkij,kj->rki", C_IK[r0 : r0 + step, img], rel)
    xy_true = project(s_true, F)
    if names:
        xy_true = fx.apply_image_chain(xy_true, names, p_si, F)
    for hook in unmodelled:
        xy_true = hook.image(xy_true, F)
        lm_rep = hook.catalogue(lm_rep)
    xy = render_image_points(camera, xy_true, pix)  # xy_true + pix without a detector calibration

    q_is = quat_from_dcm(A_rep)
    truth = dict(errors, xy_true_m=xy_true, C_IS=C_IS, r_sc_i_m=r_sc, landmark_g_m=lm_g)
    if names:
        truth["effects"] = {n: np.array(effects[n], float) for n in names}
    if unmodelled:
        truth["unmodelled"] = [h.description for h in unmodelled]
    return Measurements(
        t_s=t_s,
        pass_index=pass_index,
        q_is=q_is,
        r_sc_i_m=r_rep,
        C_GI=C_GI,
        landmark_ids=np.asarray(landmark_ids),
        landmark_g_m=lm_rep,
        image_index=img,
        target_index=tgt,
        xy_m=xy,
        C_SK_nominal=C_SK_nom,
        camera=camera,
        epoch_utc=epoch_utc,
        truth=truth,
        **({"frames": frames} if frames else {}),
        v_sc_i_m_s=v,
        stars=star_catalogue,
        sigma_xy_m=None if pixel_sigma_rows_m is None else np.asarray(pixel_sigma_rows_m, float),
        landmark_sight=landmark_sight,
    )


def _row_vectors(C_GI: Any, lm_g: Any, r_sc: Any, img: Any, tgt: Any, row_directions_i: Any) -> np.ndarray:
    """Each row's inertial target vector (K, 3): C_GI r_L − r, or a star row's direction (``observe``)."""
    rel: np.ndarray = np.einsum("kij,kj->ki", C_GI[img], lm_g[tgt]) - r_sc[img]
    if row_directions_i is not None:
        u = np.asarray(row_directions_i, float)
        rel = np.where(np.isfinite(u[:, :1]), u, rel)
    return rel


def _apparent_rows(
    rel: np.ndarray, landmark_sight: str, C_GI: Any, lm_g: Any, r_sc: Any, v_sc: Any, img: Any, tgt: Any
) -> np.ndarray:
    """``rel`` with each landmark row's geometric vector replaced by its apparent direction times its range
    (``observe``'s ``landmark_sight``); a star row (NaN landmark position) is kept; ``rel`` itself when geometric."""
    if landmark_sight == "geometric":
        return rel
    if landmark_sight not in LANDMARK_SIGHTS:
        raise InputValueError(f"observe: landmark_sight must be one of {list(LANDMARK_SIGHTS)}, got {landmark_sight!r}")
    if v_sc is None:
        raise InputValueError(f"observe: landmark_sight {landmark_sight!r} needs v_sc_i_m_s (the aberration), got None")
    lm = np.isfinite(np.asarray(lm_g, float)[tgt, 0])
    i, t = img[lm], tgt[lm]
    v = np.asarray(v_sc, float)
    sight = apparent_sight_i(r_sc[i], v[i], C_GI[i], lm_g[t], EARTH_SPIN_G_RAD_S, SightCorrections(True, True))
    out = rel.copy()
    out[lm] = sight.direction_i * np.linalg.norm(rel[lm], axis=-1, keepdims=True)
    return out


def _observed_rows(
    rows: Any, landmark_pass: Any, pass_index: Any, r_sc: Any, C_GI: Any, C_IE: Any, lm_g: Any, camera: Camera, margin: float
) -> Any:
    """``observe``'s rows: the given ones, else ``visible_rows`` of ``landmark_pass``."""
    if rows is None:
        if landmark_pass is None:
            raise InputValueError("observe: pass rows=(image_index, target_index) or landmark_pass to find the visible ones")
        rows = visible_rows(
            pass_index=pass_index,
            r_sc_i_m=r_sc,
            C_GI=C_GI,
            C_IE=C_IE,
            landmarks_g_m=lm_g,
            landmark_pass=landmark_pass,
            camera=camera,
            visibility_margin=margin,
        )
    return tuple(np.asarray(a, np.int64) for a in rows)


def _effect_parameters(effects: Any, runs: int) -> tuple[Any, Any]:
    """Catalogue names (catalogue order) and {name: (R, k) SI parameters} of an effects mapping."""
    if not effects:
        return [], {}
    unknown = [n for n in effects if n not in fx.EFFECTS]
    if unknown:
        raise fx.EffectError(f"observe: unknown effect(s) {unknown}; the catalogue has {sorted(fx.EFFECTS)}")
    names = [n for n in fx.EFFECTS if n in effects]
    p_si = {}
    for n in names:
        e = fx.EFFECTS[n]
        p = np.atleast_1d(np.asarray(effects[n], float))
        if p.shape[-1] != e.n_params or p.ndim > 2:
            raise fx.EffectError(
                f"observe: effect {n} needs (k,) or (R, k) parameters with k = {e.n_params}, got shape {p.shape}"
            )
        p_si[n] = np.broadcast_to(p * e.si, (runs, e.n_params))
    return names, p_si


def _groups(labels: Any) -> list[np.ndarray]:
    """The indices of each distinct label, labels in increasing order, indices in increasing order
    (one stable sort: O(n log n), not a comparison of every label with every element)."""
    labels = np.asarray(labels)
    order = np.argsort(labels, kind="stable")
    cuts = np.flatnonzero(np.diff(labels[order])) + 1
    return np.split(order, cuts) if labels.size else []


def _per_pass(rng: Any, sampler: Any, runs: int, pass_index: Any, passes: Any) -> Any:
    """Run a per-image/per-pass sampler pass by pass so per-pass errors are one per pass."""
    if passes.size == 1:
        return sampler(rng, runs, pass_index.size)
    out = np.empty((runs, pass_index.size, 3))
    for idx in _groups(pass_index):  # passes in increasing order; the run axis stays vectorised
        out[:, idx] = sampler(rng, runs, int(idx.size))
    return out
