"""The disturbance model (Kiev 2012, "system of perturbations") as seen by the estimators.

``DisturbanceModel`` holds the standard deviations of the four error sources and how the
star-tracker and GNSS errors vary over a pass. ``error_jacobians`` gives the first-order
sensitivities of the residuals to each source (derived here; checked against Monte Carlo in
``tests/core/test_disturbances.py`` through ``tests/oracles.py:image_covariance``, the images × landmarks
layout of the per-image blocks of ``boresight.core.gls.structure``, the one builder of the error structure
from them):

* pixel noise σK: ``σK² I``;
* star-tracker error δ (star-tracker axes), ``A_meas = exp(Φ(δ)) A``: it turns every predicted
  vector of the image by ``δ_K = C_SK δ``, so the residuals move by ``−G_n C_SK δ`` (G_n the
  Algorithm 3 Jacobian) — fully correlated across the image's landmarks;
* GNSS error ξ (inertial axes): ``ds = −C_IK ξ`` for every landmark of the image, residual
  ``+P C_IK ξ`` — also common to the image;
* catalogue error ε (per landmark, Earth-fixed axes): ``ds = C_IK C_GI ε``, independent per
  landmark (but shared by the images that see the same landmark; a per-image covariance
  cannot carry that, see ``docs/assumptions.md``).

A star row (``docs/stars.md``) has the star-tracker sensitivity above and no GNSS or catalogue
column (no position stage: its columns are zero). DECISION: a star's own catalogue error (its
astrometric σ at the epoch, median 16 mas in 2026 at Hp ≤ 7.5) is not a nuisance of the GLS: it
is 1/40 of a 0.1-pixel centroid σ (600 mas on the seminar's camera), bounded in ``docs/stars.md``.

Every sensitivity is per observation (row): an unobserved (image, target) pair has no row, so it
contributes nothing to any estimate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.core.error_sources import ERROR_SOURCES
from boresight.core.measurement import projection_jacobian
from boresight.errors import InputValueError
from orbits.rotations import ARCSEC, misalignment_dcm

__all__ = ["DisturbanceModel", "error_jacobians"]

_MODES = ("per_image", "per_pass", "both")


@dataclass(frozen=True)
class DisturbanceModel:
    """Standard deviations of the disturbances (SI: m, rad) and their time structure: the noise
    model ``estimate`` weights by (``from_scenario``, ``from_observations`` build one).

    Parameters
    ----------
    sigma_pixel_m : float
        Image-coordinate noise σK on the focal plane (m), independent per point.
    sigma_star_tracker_rad : tuple of 3 float
        Star-tracker attitude error σβ per axis (rad).
    star_tracker_mode : str
        ``"per_image"`` (independent per image), ``"per_pass"`` (one draw shared by a pass) or ``"both"``.
    sigma_gnss_m : float
        GNSS position error σR (m), per axis.
    gnss_mode : str
        As ``star_tracker_mode``, for the GNSS error.
    sigma_catalogue_m : float
        Landmark catalogue position error σP (m), per axis.
    sigma_star_tracker_correlated_rad : tuple of 3 float
        The stationary σ per axis of a first-order Gauss–Markov part of the star-tracker error (rad), on top of the
        white ``sigma_star_tracker_rad``: correlated between the tracker's samples as exp(−|Δt|/τ). Modelled on an
        attitude-sample table (pushbroom lines, ``boresight.core.line_scan``); a frame camera's GLS refuses it. Not
        part of a file's noise metadata.
    star_tracker_correlation_time_s : float
        Its correlation time τ (s, > 0).
    sigma_pass_rotation_rad, sigma_image_rotation_rad : tuple of 3 float
        An extra rotation error shared by the images of one pass, or independent per image
        (star-tracker axes, rad): the unexplained scatter ``diagnose`` estimates. Not part of a
        file's noise metadata.

    Raises
    ------
    NoiseModelError
        A mode not in ``("per_image", "per_pass", "both")``, or a σ negative, non-finite or beyond
        its bound (``err.field`` names the field).
    """

    sigma_pixel_m: float = 0.0
    sigma_star_tracker_rad: tuple[float, ...] = (0.0, 0.0, 0.0)
    star_tracker_mode: str = "per_image"
    sigma_gnss_m: float = 0.0
    gnss_mode: str = "per_image"
    sigma_catalogue_m: float = 0.0
    #: an extra rotation error shared by the images of one pass (star-tracker axes, rad), independent
    #: of ``sigma_star_tracker_rad`` and its mode: the unexplained per-pass scatter ``diagnose``
    #: estimates from its ``pass`` residual probe. Not part of a file's noise metadata.
    sigma_pass_rotation_rad: tuple[float, ...] = (0.0, 0.0, 0.0)
    #: the same, independent per image: the unexplained scatter ``diagnose`` estimates from χ²
    sigma_image_rotation_rad: tuple[float, ...] = (0.0, 0.0, 0.0)
    #: the star tracker's Gauss–Markov error: stationary σ per axis (rad) and correlation time (s) (``orbits.strip.TrackerNoise``)
    sigma_star_tracker_correlated_rad: tuple[float, ...] = (0.0, 0.0, 0.0)
    star_tracker_correlation_time_s: float = 30.0

    def __post_init__(self) -> None:
        from boresight.errors import NoiseModelError

        def bad(name: str, reason: Any, value: Any) -> NoiseModelError:
            # ``field``/``reason`` let a caller name the value as its user wrote it (a file key, a
            # command-line option; ``from_noise``, ``boresight.cli.noise_options.model_from_args``)
            err = NoiseModelError(f"DisturbanceModel.{name} {reason}, got {value!r}")
            err.field, err.reason = name, reason
            return err

        for name in ("star_tracker_mode", "gnss_mode"):
            if getattr(self, name) not in _MODES:
                raise bad(name, f"must be one of {_MODES}", getattr(self, name))

        # upper bounds (the scenario's, orbits.scenario_schema): beyond them σ² and the weights overflow
        def triple(name: str, what: str) -> np.ndarray:  # 3 floats, or the refusal naming the field
            try:
                return np.broadcast_to(np.asarray(getattr(self, name), float), (3,))
            except (TypeError, ValueError):
                raise bad(name, what, getattr(self, name)) from None

        for name, hi in (("sigma_pixel_m", 1.0), ("sigma_gnss_m", 1e7), ("sigma_catalogue_m", 1e6)):
            v = getattr(self, name)
            try:
                ok = not isinstance(v, (bool, str)) and np.ndim(v) == 0 and bool(np.isfinite(float(v)) and v >= 0)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise bad(name, "must be a finite number ≥ 0", v)
            if v > hi:
                raise bad(name, f"must be ≤ {hi:g} m (its square must stay finite in the weights)", v)
        # DECISION: the pixel σ divides every residual (the whitening): a positive σ so small that
        # the information Σ G²/σ² overflows (σ² < 1e-200) is refused — 1e-100 m is 1e-94 of a pixel.
        if 0 < self.sigma_pixel_m < 1e-100:
            raise bad("sigma_pixel_m", "must be 0 or ≥ 1e-100 m (the weights 1/σ² must stay finite)", self.sigma_pixel_m)
        st = triple("sigma_star_tracker_rad", "must be 3 finite numbers ≥ 0")
        if not np.all(np.isfinite(st) & (st >= 0)):
            raise bad("sigma_star_tracker_rad", "must be 3 finite numbers ≥ 0", self.sigma_star_tracker_rad)
        if np.any(st > np.radians(10.0)):
            raise bad(
                "sigma_star_tracker_rad", "must be ≤ 10° = 36000 arcsec (the small-angle model)", self.sigma_star_tracker_rad
            )
        object.__setattr__(self, "sigma_star_tracker_rad", tuple(float(v) for v in st))
        for name in ("sigma_pass_rotation_rad", "sigma_image_rotation_rad", "sigma_star_tracker_correlated_rad"):
            pp = triple(name, "must be 3 finite numbers in [0, 10°]")
            if not np.all(np.isfinite(pp) & (pp >= 0)) or np.any(pp > np.radians(10.0)):
                raise bad(name, "must be 3 finite numbers in [0, 10°]", getattr(self, name))
            object.__setattr__(self, name, tuple(float(v) for v in pp))
        object.__setattr__(self, "star_tracker_correlation_time_s", _positive_time(self.star_tracker_correlation_time_s, bad))

    @property
    def has_correlated_tracker(self) -> bool:
        """True when the star tracker's error has a Gauss–Markov part (``sigma_star_tracker_correlated_rad`` > 0)."""
        return any(v > 0 for v in self.sigma_star_tracker_correlated_rad)

    @classmethod
    def from_scenario(cls, scenario: Any) -> "DisturbanceModel":
        """The disturbance model a scenario simulates with (``orbits.Scenario``)."""
        return cls(
            sigma_pixel_m=scenario.sigma_pixel_m,
            sigma_star_tracker_rad=tuple(np.asarray(scenario.sigma_star_tracker_arcsec, float) * ARCSEC),
            star_tracker_mode=scenario.star_tracker_error_mode,
            sigma_gnss_m=scenario.sigma_gnss_m,
            gnss_mode=scenario.gnss_mode if hasattr(scenario, "gnss_mode") else scenario.gnss_error_mode,
            sigma_catalogue_m=scenario.sigma_catalogue_m,
        )

    @classmethod
    def from_noise(cls, mapping: Any, where: str = "noise") -> "DisturbanceModel":
        """The model a noise mapping describes (an observation file's ``noise`` metadata, or the
        scenario file's tables): ``{pixel: {sigma_m}, star_tracker: {sigma_arcsec, error_mode},
        gnss: {sigma_m, error_mode}, catalogue: {sigma_m}}``; absent tables/keys are 0 /
        ``per_image``, as in a scenario file.

        >>> DisturbanceModel.from_noise({"pixel": {"sigma_m": 3e-6}, "gnss": {"sigma_m": 15.0, "error_mode": "per_pass"}}).gnss_mode
        'per_pass'
        """
        from boresight.core.error_sources import ERROR_SOURCES, normalize_noise
        from boresight.errors import NoiseModelError

        n = normalize_noise(mapping, where, ValueError)
        try:
            return cls(
                sigma_pixel_m=n["pixel"]["sigma_m"],
                sigma_star_tracker_rad=tuple(np.asarray(n["star_tracker"]["sigma_arcsec"], float) * ARCSEC),
                star_tracker_mode=n["star_tracker"]["error_mode"],
                sigma_gnss_m=n["gnss"]["sigma_m"],
                gnss_mode=n["gnss"]["error_mode"],
                sigma_catalogue_m=n["catalogue"]["sigma_m"],
            )
        except NoiseModelError as exc:  # name the key as the mapping has it, not the field
            keys: dict[str | None, tuple[str, str]] = {
                s.model_field: (s.noise_key, "sigma_arcsec" if s.noise_key == "star_tracker" else "sigma_m")
                for s in ERROR_SOURCES.values()
            }
            keys.update(star_tracker_mode=("star_tracker", "error_mode"), gnss_mode=("gnss", "error_mode"))
            found = keys.get(exc.field)
            if found is None:
                raise
            table, key = found
            value = (mapping.get(table) or {}).get(key, n[table][key])
            err = NoiseModelError(f"{where}.{table}.{key} = {value!r}: {exc.reason}")
            err.field, err.reason = exc.field, exc.reason
            raise err from None

    def to_noise(self) -> dict[str, dict[str, Any]]:
        """The noise mapping of this model (inverse of ``from_noise``; σβ in arcsec)."""
        return {
            "pixel": {"sigma_m": float(self.sigma_pixel_m)},
            "star_tracker": {
                "sigma_arcsec": [float(v / ARCSEC) for v in self.sigma_star_tracker_rad],
                "error_mode": self.star_tracker_mode,
            },
            "gnss": {"sigma_m": float(self.sigma_gnss_m), "error_mode": self.gnss_mode},
            "catalogue": {"sigma_m": float(self.sigma_catalogue_m)},
        }

    @classmethod
    def from_observations(cls, obs: Any) -> "DisturbanceModel | None":
        """The noise model an ObservationSet carries (its file's ``noise`` metadata), or None."""
        return None if obs.noise is None else cls.from_noise(obs.noise, where="metadata 'noise'")

    def scaled(self, **factors: Any) -> "DisturbanceModel":
        """A copy with sources scaled, e.g. ``scaled(pixel=2.0)`` (keys: pixel, star_tracker, gnss, catalogue)."""
        kw = dict(self.__dict__)
        names = {s.noise_key: s.model_field for s in ERROR_SOURCES.values()}  # boresight.core.error_sources
        for key, f in factors.items():
            if key not in names:
                raise InputValueError(f"unknown disturbance source {key!r}; expected one of {sorted(names)}")
            v = kw[names[key]]
            kw[names[key]] = tuple(np.asarray(v) * f) if isinstance(v, tuple) else v * f
        return DisturbanceModel(**kw)


def _positive_time(v: Any, bad: Any) -> float:
    """``star_tracker_correlation_time_s`` as a float: one finite number > 0, else ``bad``'s refusal naming the field."""
    try:
        ok = not isinstance(v, (bool, str)) and np.ndim(v) == 0 and bool(np.isfinite(float(v)) and float(v) > 0)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise bad("star_tracker_correlation_time_s", "must be a finite number > 0 (s)", v)
    return float(v)


def error_jacobians(obs: Any, theta_rad: Any, rows: Any = None) -> dict[str, np.ndarray]:
    """First-order sensitivities of the residuals to each error source, row by row.

    Returns ``star_tracker`` per rad of δ (star-tracker axes): P Φ(s) C_SK; ``gnss`` per m of ξ
    (inertial axes): P C_IK; ``catalogue`` per m of ε (Earth-fixed axes): −P C_IK C_GI; the pixel
    noise is the identity (implicit). ``rows`` = (image_index, target_index), both (K,): the
    observations (the row model, docs/architecture.md; default: every observation of ``obs``), giving
    (R, K, 2, 3).
    """
    img, tgt = (obs.image_index, obs.target_index) if rows is None else rows
    return _row_error_jacobians(obs, theta_rad, np.asarray(img), np.asarray(tgt))


def _row_error_jacobians(obs: Any, theta_rad: Any, image_index: np.ndarray, target_index: np.ndarray) -> dict[str, np.ndarray]:
    """The error Jacobians (R, K, 2, 3) of the rows (image_index, target_index): gathers of the
    image table (attitude, position, C_GI) and of the target table (landmark), no images × targets array."""
    theta = np.broadcast_to(np.asarray(theta_rad, float), (obs.runs, 3))
    M_th = misalignment_dcm(theta)  # (R, 3, 3)
    C_IK = (M_th[:, None] @ obs.nominal_camera_attitude())[:, image_index]  # (R, K, 3, 3)
    C_SK = M_th @ obs.C_SK_nominal  # (R, 3, 3)
    C_GI = obs.C_GI[image_index]  # (K, 3, 3)
    d = obs.row_target_vectors_i(image_index, target_index)  # r_L − r (landmark) or u_k (star), (R, K, 3)
    s = np.einsum("rkij,rkj->rki", C_IK, d)  # predicted camera vectors (measurement.predicted_camera_vectors)
    P = projection_jacobian(s, obs.focal_length_m)  # (R, K, 2, 3)
    # a star row has no position stage: GNSS and the landmark catalogue do not act on it
    P_lm = P * obs.landmark_rows(target_index)[None, :, None, None]
    # star tracker: the image turns by C_SK δ, the prediction moves by P (C_SK δ × s), the residual by
    # P (s × C_SK δ); column k: −P (C_SK e_k × s)
    cross = -np.cross(s[..., None, :], np.swapaxes(C_SK, -1, -2)[:, None, :, :], axis=-1)  # (R, K, 3, 3)
    return {
        "star_tracker": -np.einsum("rkij,rkmj->rkim", P, cross),
        "gnss": P_lm @ C_IK,
        "catalogue": -(P_lm @ C_IK) @ C_GI,
    }
