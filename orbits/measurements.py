"""Simulate measurements of a campaign (one or more passes) for a batch of runs.

``draw_errors`` is the only random step: every run gets its own misalignment θ and sensor errors
along a leading run axis. ``observe`` is deterministic array code that turns the true geometry
(computed once, ``orbits.scenario.campaign_arrays``) and those errors into what the sensors
report, so one pass and 45 000 runs go through the same code (``orbits.scenario.simulate`` is
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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import effects as fx
from .camera import Camera, project, render_image_points
from .landmarks import catalogue_errors
from .rotations import misalignment_dcm, quat_from_dcm, rotvec_dcm, star_tracker_error_dcm
from .sensors import GnssErrors, PixelNoise, StarTrackerErrors

__all__ = ["Measurements", "draw_errors", "observe"]


@dataclass(frozen=True)
class Measurements:
    """What the sensors report (the estimator's input) plus the truth behind it.

    Shapes: R runs, N images, M landmarks. Measured: ``q_is`` (R, N, 4) star-tracker attitude
    quaternion inertial → star tracker, scalar last; ``r_sc_i_m`` (R, N, 3) GNSS position in I;
    ``landmark_g_m`` (R, M, 3) catalogue coordinates in G; ``xy_m`` (R, N, M, 2) image points
    (0 where ``mask`` is False); ``mask`` (N, M). Known: ``t_s`` (N,), ``pass_index`` (N,),
    ``C_GI`` (N, 3, 3), ``C_SK_nominal`` (3, 3), ``camera``, ``epoch_utc``. Truth: ``truth`` dict
    with ``theta_rad`` (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3),
    ``catalogue_error_m`` (R, M, 3), ``xy_true_m`` (R, N, M, 2), ``C_IS`` (N, 3, 3), ``r_sc_i_m`` (N, 3),
    ``landmark_g_m`` (M, 3). ``v_sc_i_m_s`` (R, N, 3) is the GNSS velocity in I (the true
    velocity: a GNSS receiver's velocity error, ~0.05 m/s, is negligible here) or None.
    With effects, ``truth["effects"]`` maps each hidden effect's name to its parameters (k,) or
    (R, k) in the effect's units; ``truth["unmodelled"]`` lists out-of-catalogue perturbations.
    """

    # DECISION (transitional): the simulator still reports an images × landmarks grid
    # with a mask; ``boresight.observations.from_measurements`` turns it into rows. Its port to
    # rows (``orbits.records.ImageRecords``) is the next step of the row model.
    t_s: np.ndarray
    pass_index: np.ndarray
    q_is: np.ndarray
    r_sc_i_m: np.ndarray
    C_GI: np.ndarray
    landmark_ids: np.ndarray
    landmark_g_m: np.ndarray
    xy_m: np.ndarray
    mask: np.ndarray
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

    @property
    def runs(self) -> int:
        return int(self.xy_m.shape[0])


def draw_errors(
    rng: np.random.Generator,
    runs: int,
    pass_index: Any,
    n_landmarks: int,
    *,
    theta_true_rad: Any = None,
    theta_sigma_rad: float = 0.0,
    star_tracker: StarTrackerErrors = StarTrackerErrors(),
    gnss: GnssErrors = GnssErrors(),
    pixel: PixelNoise = PixelNoise(),
    catalogue_sigma_m: float = 0.0,
) -> dict[str, Any]:
    """Draw every run's θ and sensor errors (the only random step), leading run axis.

    Draw order (fixed, so a seed reproduces a run): θ (if random), star tracker (per image, then
    per pass, pass by pass), GNSS (same), catalogue, pixel noise.

    Returns ``theta_rad`` (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3),
    ``catalogue_error_m`` (R, M, 3), ``pixel_noise_m`` (R, N, M, 2).
    """
    pass_index = np.asarray(pass_index, int)
    n = pass_index.size
    if theta_true_rad is not None:
        theta = np.broadcast_to(np.asarray(theta_true_rad, float), (runs, 3)).copy()
    else:
        theta = rng.normal(size=(runs, 3)) * theta_sigma_rad
    passes = np.unique(pass_index)
    return {
        "theta_rad": theta,
        "delta_rad": _per_pass(rng, star_tracker.sample, runs, pass_index, passes),
        "gnss_error_m": _per_pass(rng, gnss.sample, runs, pass_index, passes),
        "catalogue_error_m": catalogue_errors(rng, runs, n_landmarks, catalogue_sigma_m),
        "pixel_noise_m": pixel.sample(rng, runs, n, n_landmarks),
    }


def observe(
    errors: dict[str, Any],
    *,
    t_s: Any,
    pass_index: Any,
    r_sc_i_m: Any,
    C_GI: Any,
    C_IE: Any,
    landmarks_g_m: Any,
    landmark_pass: Any,
    landmark_ids: Any,
    camera: Camera,
    C_ES: Any,
    epoch_utc: str = "2012-01-31T00:00:00",
    visibility_margin: float = 1.0,
    frames: dict[str, Any] | None = None,
    v_sc_i_m_s: Any = None,
    effects: Any = None,
    attitude_rate_e_rad_s: Any = None,
    time_tag_rotation_e_rad: Any = None,
    time_tag_rotation_dt_s: Any = None,
    unmodelled: Any = (),
) -> Measurements:
    """What the sensors report for given errors (deterministic; broadcasts over the run axis).

    ``effects``: mapping effect name → parameters (k,) or (R, k) in the effect's units
    (``orbits.effects``); velocity-dependent effects need ``v_sc_i_m_s`` (N, 3); ``time_tag``
    needs ``time_tag_rotation_e_rad`` (N, 3), the rotation vector of the attitude law from t to
    t + dt in body axes, log(C_IE(t + dt) C_IE(t)ᵀ), for ``time_tag_rotation_dt_s`` = dt (the exact
    shift; ``orbits.scenario.campaign_arrays`` provides both), or ``attitude_rate_e_rad_s``
    (N, 3), the body rate of the law at t + dt (first order, ε = −ω dt; any per-run dt). ``unmodelled``: ``orbits.effects.Unmodelled``
    perturbations outside the catalogue (tests of "unexplained structure").
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

    lm_i = np.einsum("nij,mj->nmi", C_GI, lm_g)  # (N, M, 3)
    rel = lm_i - r_sc[:, None, :]
    s_nom = np.einsum("nij,nmj->nmi", C_IE, rel)  # body ≡ nominal camera
    own = np.asarray(landmark_pass)[None, :] == pass_index[:, None]
    half = np.degrees(np.arctan(np.tan(np.radians(camera.fov_deg) / 2) * visibility_margin))
    mask = own & Camera(camera.focal_length_m, 2 * half).visible(s_nom)

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
    s_true = np.einsum("rnij,nmj->rnmi", C_IK, rel)
    m4 = mask[None, :, :, None]
    xy_true = project(np.where(m4, s_true, -1.0), F)
    if names:
        xy_true = fx.apply_image_chain(xy_true, names, p_si, F)
    for hook in unmodelled:
        xy_true = hook.image(xy_true, F)
        lm_rep = hook.catalogue(lm_rep)
    xy_true = np.where(m4, xy_true, 0.0)
    xy = np.where(m4, render_image_points(camera, xy_true, pix), 0.0)  # xy_true + pix without a detector calibration

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
        xy_m=xy,
        mask=mask,
        C_SK_nominal=C_SK_nom,
        camera=camera,
        epoch_utc=epoch_utc,
        truth=truth,
        **({"frames": frames} if frames else {}),
        v_sc_i_m_s=v,
    )


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


def _per_pass(rng: Any, sampler: Any, runs: int, pass_index: Any, passes: Any) -> Any:
    """Run a per-image/per-pass sampler pass by pass so per-pass errors are one per pass."""
    if passes.size == 1:
        return sampler(rng, runs, pass_index.size)
    out = np.empty((runs, pass_index.size, 3))
    for p in passes:  # a handful of passes, not runs: the run axis stays vectorised
        sel = pass_index == p
        out[:, sel] = sampler(rng, runs, int(sel.sum()))
    return out
