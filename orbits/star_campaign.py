"""Star frames in a scenario: the ``[stars]`` table and ``[[star_frames]]`` segments, simulated as rows.

A scenario may add to (or, without ``[[passes]]``, replace) its landmark passes star-frame
segments: the camera pointed at the sky (``docs/stars.md``). Each ``[[star_frames]]`` entry is one
segment — one "pass" of the campaign, so its star-tracker error in mode ``per_pass``/``both`` is
one draw — with its own times and attitude law:

* ``attitude = "inertial_hold"``: boresight on (``ra_deg``, ``dec_deg``), roll ``roll_deg``
  (``orbits.star_frames.inertial_hold``);
* ``attitude = "slew"``: from that hold to (``ra_end_deg``, ``dec_end_deg``, ``roll_end_deg``) over
  the segment's times (``orbits.star_frames.slew``, scipy's Slerp);
* ``attitude = "zenith"``: the nadir law turned over, the sky scanned at the orbital rate
  (``zenith_pointing``); ``night_only = true`` keeps the frames in the Earth's shadow.

The spacecraft flies the scenario's ``[orbit]`` (a circular orbit, GCRS axes: the apparent
directions are GCRS) at argument of latitude ``u0_deg`` + n·t at the segment's times ``t_s`` (s
from the scenario's ``epoch_utc``). ``[stars]``: ``catalogue = "hipparcos"`` (the optional extra
``stars``) or ``"synthetic"`` (``n`` stars uniform on the sphere, Hp uniform in [1, 8.5], drawn
from ``seed``: tests and machines without the extra), ``mag_limit_hp``, ``detection_probability``.

What each run reports (``simulate_star_rows``): which stars each frame detects is decided once,
noise-free, at the scenario's true θ (the rows are shared by the runs, as a file's are); each run
draws θ (if ``sigma0_arcsec``), the star tracker's δ (``orbits.measurements.draw_errors``, the
scenario's mode), the GNSS error (reported position r + ξ; it moves no star direction by more
than 0.04 mas) and one centroid error per row; ``orbits.measurements.observe``, the simulator's one
forward chain, then reports them with each row's apparent direction as its target, so the
scenario's hidden ``[effects]`` act on star frames by their one definition (position and landmark
stages cannot reach a star: ``docs/effects.md``, "Effects on star rows").

Centroid noise by magnitude. With ``[stars] centroid_sigma_reference_m`` (and optionally
``centroid_reference_mag``, default 6, ``centroid_sigma_floor_m``, default 0.3 µm) each star row's
centroid σ follows ``orbits.star_frames.CentroidNoise``: σ(m) = √(σ_floor² + (σ_ref 10^(0.2 (m − m_ref)))²),
the photon-limited centroid (σ ≈ PSF width / SNR, SNR ∝ √flux ∝ 10^(−0.2 m): Liebe, *Accuracy
performance of star trackers — a tutorial*, IEEE TAES 38(2), 2002) with a floor (detector and PSF
sampling), isotropic, from the star's catalogue magnitude. The rows' σ (``pixel_sigma_rows_m`` (K, 2))
draws each row's noise (``draw_errors``) and travels with the rows (``Measurements.sigma_xy_m`` →
``ObservationSet.sigma_xy_m``, the file's ``sigma_x sigma_y``), so the GLS weights each star by its own σ.
DECISION: σ from the catalogue magnitude, not the measured one: a real centroider estimates its σ from
the star's measured flux, whose noise (≈ 0.1 mag, 5 % in σ) moves a weight, not the estimate's
consistency. Without ``centroid_sigma_reference_m`` every star row has the scenario's ``[pixel] sigma_m``.
The true image point is the one projection of
``C_IK u`` with ``C_IK = exp(−Φ(θ + φ)) C_SK,nom C_ES C_IE`` and u the apparent direction
(``star_apparent``) from the true position and velocity.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .errors import checked_table
from .scenario_schema import ScenarioError

__all__ = [
    "StarSpec",
    "StarFrameSpec",
    "star_tables",
    "star_catalogue_of",
    "star_frame_geometry",
    "star_frame_arrays",
    "simulate_star_rows",
]

_ATTITUDES = ("inertial_hold", "slew", "zenith")


@dataclass(frozen=True)
class StarSpec:
    """``[stars]``: the catalogue and what the camera detects."""

    catalogue: str = "hipparcos"  # hipparcos | synthetic
    mag_limit_hp: float = 7.5
    detection_probability: float = 1.0
    n: int = 60000  # synthetic: number of stars
    seed: int = 0  # synthetic: the sky's seed (part of the scenario, not of a run)
    #: the centroid σ law by magnitude (``orbits.star_frames.CentroidNoise``): σ_ref (m) at ``centroid_reference_mag``
    #: and the floor; None: every star row has the scenario's ``[pixel] sigma_m`` (module docstring)
    centroid_sigma_reference_m: float | None = None
    centroid_reference_mag: float = 6.0
    centroid_sigma_floor_m: float = 0.3e-6

    def centroid(self) -> Any:
        """The ``CentroidNoise`` of the star rows, or None (the scenario's one pixel σ)."""
        if self.centroid_sigma_reference_m is None:
            return None
        from .star_frames import CentroidNoise

        return CentroidNoise(self.centroid_sigma_reference_m, self.centroid_reference_mag, self.centroid_sigma_floor_m)


@dataclass(frozen=True)
class StarFrameSpec:
    """One ``[[star_frames]]`` segment (module docstring)."""

    attitude: str
    t_s: tuple[float, ...]
    u0_deg: float = 0.0
    ra_deg: float = 0.0
    dec_deg: float = 0.0
    roll_deg: float = 0.0
    ra_end_deg: float = 0.0
    dec_end_deg: float = 0.0
    roll_end_deg: float = 0.0
    night_only: bool = False


#: the keys a ``[stars]`` table and a ``[[star_frames]]`` entry may hold: the fields they fill
_STAR_KEYS = tuple(f.name for f in fields(StarSpec))
_FRAME_KEYS = tuple(f.name for f in fields(StarFrameSpec))


def _number(where: str, key: str, v: Any, lo: float = -np.inf, hi: float = np.inf) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or not lo <= v <= hi:
        raise ScenarioError(f"{where}.{key} must be a finite number in [{lo:g}, {hi:g}], got {v!r}")
    return float(v)


def _times(where: str, spec: Any) -> tuple[float, ...]:
    if isinstance(spec, dict):
        try:
            start, stop, step = (_number(where, f"t_s.{k}", spec[k]) for k in ("start", "stop", "step"))
        except KeyError as exc:
            raise ScenarioError(f"{where}.t_s needs start, stop and step, missing {exc}") from None
        if step <= 0 or stop < start or (stop - start) / step > 1e6:
            raise ScenarioError(f"{where}.t_s must have step > 0, stop ≥ start and at most 1e6 frames, got {spec!r}")
        return tuple(np.round(np.arange(start, stop + 0.5 * step, step), 12).tolist())
    if not isinstance(spec, list) or not spec:
        raise ScenarioError(f"{where}.t_s must be a table {{start, stop, step}} or a non-empty list of times (s), got {spec!r}")
    return tuple(_number(where, "t_s", x) for x in spec)


def _star_spec(stars: Any, source: str) -> StarSpec:
    stars = checked_table(stars, f"{source}: [stars]", _STAR_KEYS, ScenarioError)
    cat = stars.get("catalogue", "hipparcos")
    if cat not in ("hipparcos", "synthetic"):
        raise ScenarioError(f"{source}: [stars] catalogue must be 'hipparcos' or 'synthetic', got {cat!r}")
    kw: dict[str, Any] = {"catalogue": cat}
    w = f"{source}: [stars]"
    for key, lo, hi in (
        ("mag_limit_hp", -2.0, 14.0),
        ("detection_probability", 0.0, 1.0),
        ("centroid_sigma_reference_m", 1e-12, 1e-3),
        ("centroid_reference_mag", -2.0, 14.0),
        ("centroid_sigma_floor_m", 0.0, 1e-3),
    ):
        if key in stars:
            kw[key] = _number(w, key, stars[key], lo, hi)
    for key, lo, hi in (("n", 1, 1e7), ("seed", 0, 2**32)):
        if key in stars:
            v = _number(w, key, stars[key], lo, hi)
            if v != int(v):
                raise ScenarioError(f"{w}.{key} must be a whole number, got {stars[key]!r}")
            kw[key] = int(v)
    return StarSpec(**kw)


def _frame_spec(fr: Any, where: str) -> StarFrameSpec:
    fr = checked_table(fr, where, _FRAME_KEYS, ScenarioError)
    att = fr.get("attitude")
    if att not in _ATTITUDES:
        raise ScenarioError(f"{where}.attitude must be one of {_ATTITUDES}, got {att!r}")
    if "t_s" not in fr:
        raise ScenarioError(f"{where} is missing t_s")
    kw: dict[str, Any] = {"attitude": att, "t_s": _times(where, fr["t_s"])}
    for key in _FRAME_KEYS[2:-1]:
        if key in fr:
            lo, hi = (-90.0, 90.0) if key.startswith("dec") else (-720.0, 720.0)
            kw[key] = _number(where, key, fr[key], lo, hi)
    if "night_only" in fr:
        if not isinstance(fr["night_only"], bool):
            raise ScenarioError(f"{where}.night_only must be true or false, got {fr['night_only']!r}")
        kw["night_only"] = fr["night_only"]
    return StarFrameSpec(**kw)


def star_tables(stars: Any, frames: Any, source: str) -> tuple[StarSpec | None, tuple[StarFrameSpec, ...]]:
    """Validate ``[stars]`` and ``[[star_frames]]`` of a scenario document (either may be None)."""
    spec = None if stars is None else _star_spec(stars, source)
    if frames is None:
        return spec, ()
    if not isinstance(frames, list) or not frames:
        raise ScenarioError(f"{source}: [[star_frames]] must list at least one segment (an array of tables)")
    return spec or StarSpec(), tuple(_frame_spec(fr, f"{source}: star_frames[{k}]") for k, fr in enumerate(frames))


def star_catalogue_of(spec: StarSpec) -> Any:
    """The scenario's star catalogue (``orbits.star_catalogue.StarCatalogue``): Hipparcos 2 to half a
    magnitude beyond the detection limit, or the synthetic sky of ``spec.seed``."""
    from .star_catalogue import load_hipparcos, synthetic_catalogue

    if spec.catalogue == "hipparcos":
        return load_hipparcos(spec.mag_limit_hp + 0.5)
    return synthetic_catalogue(
        np.random.default_rng(spec.seed), spec.n, source=f"synthetic sky (seed {spec.seed}, {spec.n} stars)"
    )


def star_frame_geometry(scenario: Any, offset_s: float = 0.0, keep: Any = None) -> dict[str, np.ndarray]:
    """The star frames' true geometry: ``t_s`` (F,) s from the scenario epoch, ``pass_index`` (F,)
    (segment k is pass k of the star set; ``boresight.simulate`` numbers them after the landmark passes),
    ``r_i_m``, ``v_i_m_s`` (F, 3), ``C_IE`` (F, 3, 3), ``keep`` (F,) the frames kept. Night-only zenith
    frames outside the Earth's shadow are dropped. ``offset_s``: the attitude law (and orbit) at
    t + offset (a time-tag error's shift), for the frames ``keep`` of the unshifted geometry."""
    from astropy import units as u
    from astropy.time import Time

    from .star_apparent import observer_states
    from .star_frames import in_earth_shadow, inertial_hold, slew, zenith_pointing

    orbit = scenario.orbit.orbit()
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("t_s", "pass_index", "r_i_m", "v_i_m_s", "C_IE", "keep")}
    for k, fr in enumerate(scenario.star_frames):
        t0 = np.asarray(fr.t_s, float)
        t = t0 + offset_s
        r, v = orbit.state(np.radians(fr.u0_deg) + orbit.mean_motion_rad_s * t)
        if fr.attitude == "inertial_hold":
            C = np.broadcast_to(inertial_hold(fr.ra_deg, fr.dec_deg, fr.roll_deg), (t.size, 3, 3))
        elif fr.attitude == "slew":
            # before and after the slew the attitude holds at its ends (a time-tag shift may look past them)
            frac = np.clip((t - t0[0]) / (t0[-1] - t0[0]), 0.0, 1.0) if t0.size > 1 else np.zeros(t.size)
            C = slew(
                inertial_hold(fr.ra_deg, fr.dec_deg, fr.roll_deg),
                inertial_hold(fr.ra_end_deg, fr.dec_end_deg, fr.roll_end_deg),
                frac,
            )
        else:
            C = zenith_pointing(r, v)
        on = np.ones(t.size, bool)
        if fr.night_only:
            obs = observer_states(Time(scenario.epoch_utc, scale="utc") + t0 * u.s, r, v)
            on = in_earth_shadow(r, -obs.astrom["eh"])
        parts["t_s"].append(t0)
        parts["pass_index"].append(np.full(t.size, k))
        parts["r_i_m"].append(r)
        parts["v_i_m_s"].append(v)
        parts["C_IE"].append(np.asarray(C))
        parts["keep"].append(on)
    out = {k: np.concatenate(v) for k, v in parts.items()}
    sel = out["keep"] if keep is None else np.asarray(keep)
    return {k: v[sel] for k, v in out.items() if k != "keep"} | {"keep": sel}


def star_frame_arrays(scenario: Any, rng: np.random.Generator, catalogue: Any = None) -> tuple[dict[str, Any], np.ndarray, Any]:
    """The deterministic part of the star frames: which stars each frame detects (decided once,
    noise-free, at the scenario's true θ, by ``orbits.star_frames.simulate_star_frames`` with ``rng``)
    and everything ``orbits.measurements.observe`` needs to report them: the ``observe`` keywords
    (frames that see a star only; targets are the detected stars, ``HIP n``, positions NaN; rows in
    canonical order; ``row_directions_i`` each row's apparent direction from the true state;
    ``star_catalogue`` the targets' astrometry; the hidden effects' keywords), each row's HIP number
    (K,) and the sky. ``simulate_star_rows`` draws the errors of runs over them; the scenario study
    engine takes them through ``orbits.campaign_arrays``."""
    from astropy import units as u
    from astropy.time import Time
    from scipy.spatial.transform import Rotation

    from .earth import itrs_to_gcrs_dcm
    from .rotations import ARCSEC
    from .star_apparent import apparent_directions, observer_states
    from .star_frames import KIND_STAR, CentroidNoise, StarDetector, simulate_star_frames

    spec = scenario.stars or StarSpec()
    sky = star_catalogue_of(spec) if catalogue is None else catalogue
    g = star_frame_geometry(scenario)
    times = Time(scenario.epoch_utc, scale="utc") + g["t_s"] * u.s
    theta_nominal = np.zeros(3) if scenario.theta_true_arcsec is None else np.asarray(scenario.theta_true_arcsec, float) * ARCSEC
    detector = StarDetector(
        mag_limit_hp=spec.mag_limit_hp,
        detection_probability=spec.detection_probability,
        centroid=CentroidNoise(0.0, 6.0, 0.0),
        sigma_magnitude=0.0,
    )
    C_ES = scenario.C_ES
    fr = simulate_star_frames(
        sky, scenario.camera, times, g["r_i_m"], g["v_i_m_s"], g["C_IE"], theta_nominal, detector, rng, C_ES=C_ES
    )
    f, d = np.nonzero(fr.mask & (fr.kind == KIND_STAR))
    seen = np.unique(f)  # frames with at least one star
    new = np.full(g["t_s"].size, -1)
    new[seen] = np.arange(seen.size)
    image_index, hip = new[f], fr.hip[f, d]
    kept = np.flatnonzero(g["keep"])[seen]  # the frames, among all of the segments
    g = {k: v[seen] for k, v in g.items() if k != "keep"}
    ids, tgt = np.unique(hip, return_inverse=True)
    order = np.lexsort((tgt, image_index))  # canonical (image, target) order: the rows draw_errors expects
    image_index, hip, tgt = image_index[order], hip[order], tgt[order]
    u_rows = apparent_directions(sky, observer_states(times[seen], g["r_i_m"], g["v_i_m_s"]), sky.index_of(hip), image_index)
    extra: dict[str, Any] = {}
    law = spec.centroid()
    if law is not None:  # each star row's centroid σ from its catalogue magnitude, the same on x and y
        sigma = law.sigma_m(sky.magnitude_hp[sky.index_of(hip)])
        extra["pixel_sigma_rows_m"] = np.repeat(sigma[:, None], 2, axis=1)
    if scenario.effects:
        extra["effects"] = scenario.effects
        if "time_tag" in scenario.effects:  # the exact shift A_rep(t) = A_true(t + dt) of the attitude law
            dt = float(scenario.effects["time_tag"][0])
            keep_all = np.zeros(star_frame_geometry(scenario)["keep"].size, bool)
            keep_all[kept] = True
            C1 = star_frame_geometry(scenario, dt, keep_all)["C_IE"]
            extra["time_tag_rotation_e_rad"] = Rotation.from_matrix(C1 @ np.swapaxes(g["C_IE"], -1, -2)).as_rotvec()
            extra["time_tag_rotation_dt_s"] = dt
    arrays = dict(
        t_s=g["t_s"],
        pass_index=g["pass_index"],
        r_sc_i_m=g["r_i_m"],
        C_GI=itrs_to_gcrs_dcm(times[seen]),
        C_IE=g["C_IE"],
        landmarks_g_m=np.full((ids.size, 3), np.nan),
        landmark_ids=np.char.add("HIP ", ids.astype(str)),
        camera=scenario.camera,
        C_ES=C_ES,
        rows=(image_index, tgt),
        epoch_utc=scenario.epoch_utc,
        frames={"inertial": "GCRS", "earth_fixed": "ITRS"},
        v_sc_i_m_s=g["v_i_m_s"],
        row_directions_i=u_rows,
        star_catalogue=sky.subset(sky.index_of(ids)),
        **extra,
    )
    return arrays, hip, sky


def simulate_star_rows(scenario: Any, rng: np.random.Generator, runs: int = 1, catalogue: Any = None) -> dict[str, Any]:
    """The star frames of ``scenario`` for ``runs`` runs, as rows (module docstring).

    Which stars each frame detects: ``star_frame_arrays`` (``orbits.star_frames.simulate_star_frames``
    at the true θ, noise-free). What the sensors report: ``orbits.measurements.observe`` — the simulator's one
    forward chain, with the rows' apparent directions (``orbits.star_apparent``) as their targets,
    so the scenario's hidden effects act on star frames by their one definition (a time tag through
    the attitude law's shift; position and landmark stages do not reach a star). Returns the image
    table (``t_s``, ``pass_index`` (F,), ``q_is`` (R, F, 4), ``r_sc_i_m``, ``v_sc_i_m_s`` (R, F, 3), ``C_GI``
    (F, 3, 3)), the rows (``image_index``, ``hip`` (K,), ``xy_m`` (R, K, 2)), the ``catalogue`` and ``truth``
    (``theta_rad`` (R, 3), ``delta_rad``, ``gnss_error_m`` (R, F, 3), ``xy_true_m``, ``pixel_noise_m``
    (R, K, 2), ``effects``) — under the names ``boresight.observations.stars.star_observations`` takes them
    (``boresight.simulate`` passes them on as they are). Frames that see no star are left out.
    """
    from .measurements import draw_errors, observe
    from .rotations import ARCSEC

    arrays, hip, sky = star_frame_arrays(scenario, rng, catalogue)
    theta_nominal = None if scenario.theta_true_arcsec is None else np.asarray(scenario.theta_true_arcsec, float) * ARCSEC
    err = scenario.errors()
    drawn = draw_errors(
        rng,
        runs,
        arrays["pass_index"],
        arrays["landmarks_g_m"].shape[0],
        rows=arrays["rows"],
        grid_stream=False,
        theta_true_rad=theta_nominal,
        theta_sigma_rad=scenario.theta_sigma0_arcsec * ARCSEC,
        star_tracker=err["star_tracker"],
        gnss=err["gnss"],
        pixel=err["pixel"],
        catalogue_sigma_m=0.0,
        pixel_sigma_rows_m=arrays.get("pixel_sigma_rows_m"),
    )
    meas = observe(drawn, **arrays)
    truth: dict[str, Any] = {
        k: meas.truth[k] for k in ("theta_rad", "delta_rad", "gnss_error_m", "xy_true_m", "pixel_noise_m") if k in meas.truth
    }
    if "effects" in meas.truth:
        truth["effects"] = meas.truth["effects"]
    return {
        "t_s": arrays["t_s"],
        "pass_index": arrays["pass_index"],
        "q_is": meas.q_is,
        "r_sc_i_m": meas.r_sc_i_m,
        "v_sc_i_m_s": np.broadcast_to(arrays["v_sc_i_m_s"], (runs,) + arrays["v_sc_i_m_s"].shape).copy(),
        "image_index": arrays["rows"][0],
        "hip": hip,
        "xy_m": meas.xy_m,
        "catalogue": sky,
        "C_GI": meas.C_GI,
        "truth": truth,
        "sigma_xy_m": meas.sigma_xy_m,
    }
