"""``ObservationSet``: the one data model shared by flight data and simulations.

The row model (``docs/architecture.md``, "The row model"): three tables — images,
targets, rows (one per observation) — with a leading run axis R (1 for flight data):

=================  ===============  =====================================================
field              shape            meaning (SI units)
=================  ===============  =====================================================
*images*
``t_s``            (N,)             image time, seconds from ``epoch`` (UTC)
``pass_index``     (N,)             which pass of a campaign the image belongs to
``q_is``           (R, N, 4)        star-tracker attitude quaternion, inertial → star tracker,
                                    **scalar last** ``[q1, q2, q3, q4]``
``r_sc_i_m``       (R, N, 3)        GNSS spacecraft position in the inertial frame (m)
``C_GI``           (N, 3, 3)        Earth-fixed → inertial DCM at each image
``v_sc_i_m_s``     (R, N, 3)/None   GNSS spacecraft velocity in the inertial frame (m/s), optional
*targets*
``landmark_ids``   (T,)             target identifiers (str)
``target_kind``    (T,)             ``"landmark"`` or ``"star"`` (a direction at infinity)
``landmark_g_m``   (R, T, 3)        catalogue landmark position, Earth-fixed frame (m); NaN for a star
``stars``          (T_star,)        ``orbits.star_catalogue.StarCatalogue``: the astrometry of the star
                                    targets (direction at the catalogue epoch, proper motion, parallax,
                                    magnitude, HIP id), one entry per star target in target order
*rows*
``image_index``    (K,)             the image of each observation (int)
``target_index``   (K,)             the target of each observation (int)
``xy_m``           (R, K, 2)        measured image coordinates on the focal plane (m)
``sigma_xy_m``     (K, 2)/None      optional: each row's own σ of its x and y (m on the focal plane;
                                    a centroid's σ from its brightness); NaN on a row, or the field
                                    None: the noise model's pixel σ (``DisturbanceModel.sigma_pixel_m``)
=================  ===============  =====================================================

Per-row pixel σ. ``sigma_xy_m`` replaces, row by row, the one pixel σ of the noise model in every
consumer of the error structure (``boresight.core.gls.structure.row_pixel_sigma``: the GLS, the
sandwich, the per-residual variances, the per-image covariances of the Kalman filter, the Monte
Carlo weights and the convention doctor); it is the same in every run (a property of the
detection, like its image and target) and carried by the file's ``sigma_x sigma_y`` columns
(format 1.3, ``docs/data-format.md``). DECISION: a row's own σ wins over the noise model's — an
explicit model (``--sigma-pixel-m``) sets the σ of the rows without one — because the centroider
that measured a point is the best judge of its σ; NaN rows are how a set mixes rows with and
without their own σ (star rows joined to landmark rows).

Rows are in canonical order — sorted by (image, target), each pair at most once — so image n's
rows are ``row_start[n]:row_start[n + 1]``. ``n_observations`` is K. A *complete* set (every
target in every image, the seminar's shape) has ``is_complete`` and its ``xy_m`` reshapes to
(R, N, T, 2) without a copy. No array has an images × targets axis pair. Truth (simulations):
``theta_rad`` (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3), ``catalogue_error_m``
(R, T, 3), ``xy_true_m`` and ``pixel_noise_m`` (R, K, 2), ``effects``.

Star targets. A star row's target is the star's apparent (proper) direction u_k in the inertial
frame (GCRS) at its image's time, seen from the spacecraft's position and velocity: computed once
per set by the one apparent-place function ``orbits.star_apparent.apparent_directions`` (proper
motion, parallax, Sun deflection, annual + orbital aberration; ``docs/stars.md``) and cached
(``row_star_directions_i``). ``row_target_vectors_i`` gives every row's inertial target vector —
C_GI r_L − r for a landmark (m), u_k for a star (unit) — to the measurement model, which projects
either the same way (the projection is scale-free). DECISION: the apparent directions use run 0's
position and velocity: the runs of a set differ by their GNSS errors (metres, cm/s), which move a
star by ≤ 0.04 mas (parallax) and 1 mas per 1.45 m/s (aberration), far below a centroid's σ.

Landmark sight. ``landmark_sight`` says what a landmark row's target vector carries (``LANDMARK_SIGHTS``):
``"geometric"`` (the default, and what every file without the key means: C_GI r_L − r, the seminar's model) or
``"light_time+aberration"``: the direction in which the spacecraft sees the landmark — where it was when the light
left it, with the spacecraft's velocity added to the light's, ~5″ mostly along-track in LEO — from the one
implementation the pushbroom chain uses (``orbits.sight.apparent_sight_i``), times the geometric range, so
anything that uses the range (the ground-sample distance, a plane's depth) is unchanged. The simulator's forward
chain (``orbits.measurements.observe(landmark_sight=…)``, a scenario's ``landmark_sight`` key) applies the same
function, so a set simulated with the corrections and estimated with them is exact (``docs/stars.md``, "One physics
for star and landmark rows"). Each run's own position and velocity (``velocity_i_m_s``) enter. DECISION: the
Earth's spin is ω_E about G's z (``orbits.sight.EARTH_SPIN_G_RAD_S``), not one derived from the images' C_GI: for
the seminar's spherical Earth it is exact; for ITRS the spin axis is ≤ 2.4e-6 rad off z (polar motion) and its
rate differs from ω_E by ~1e-8 (length of day), which in the ≈ 2 ms of light time moves a ground point by
≤ 2e-6 m (4e-12 rad at 500 km), and the precession-nutation rates (~1e-11 rad/s) add ~2e-14 rad: far below
anything measured. DECISION: the GNSS and catalogue columns of the error structure, and the columns of the effects
that move the positions or the catalogue (``core/effect_model.py``: ``gnss_bias``, ``landmark_height_bias``, …),
keep the geometric derivative (∂d/∂r = −E, ∂d/∂r_L = C_GI): the corrected vector's derivative differs by terms of
relative size v/c ≈ 2.5e-5
(the aberration's dependence on the direction) and v_ground/c ≈ 1.5e-6 (light time), an error of that relative size
in those columns only (a Gauss–Newton with such an effect floated converges linearly in its last step, one
iteration more); θ's Jacobian (``core/measurement.py``) is exact for either sight.

Optional descriptions: ``noise`` (the sensor noise model as a mapping with the scenario file's own
tables and keys, ``{pixel: {sigma_m}, star_tracker: {sigma_arcsec, error_mode}, gnss: {sigma_m,
error_mode}, catalogue: {sigma_m}}``; ``DisturbanceModel.from_observations`` turns it into the
estimators' model) and ``camera`` (an ``orbits.camera.CameraCalibration``: pixels ↔ focal plane).
``velocity_i_m_s()`` returns the given velocity, or one derived from the positions where the images
are dense enough (``boresight.observations.velocity``), or None with the reason in ``velocity_status``.

Every ObservationSet is checked as the file reader checks a file: shapes, finite values, unit
quaternions, a proper rotation ``C_SK_nominal`` / ``C_GI``, and the geometry of each image (no
landmark behind the camera; with ``fov_deg``, no measured point beyond the field's 1 % margin),
by the one function ``geometry_problem`` that the reader uses too.

Camera constants: ``focal_length_m``, ``fov_deg``, ``pixel_pitch_m``, and ``C_SK_nominal`` (the
nominal star-tracker → camera DCM). The estimated misalignment θ is defined by
``C_SK,true = exp(−Φ(θ)) C_SK,nominal`` (Kiev 2012 eq 24). The file format is in
``docs/data-format.md``.

Example
-------
>>> import numpy as np
>>> from boresight import simulate
>>> from orbits import load_scenario
>>> obs = simulate(load_scenario("scenarios/kiev2012-algorithm1.toml"), np.random.default_rng(0), runs=2)
>>> obs.runs, obs.n_images, obs.n_landmarks, obs.n_observations, obs.xy_m.shape
(2, 10, 4, 40, (2, 40, 2))
>>> obs.is_complete, obs.row_xy_grid().shape
(True, (2, 10, 4, 2))
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from boresight.core.error_sources import normalize_noise

# DECISION: the old import path of the two errors still works (``from boresight.observations.model import
# ObservationError``), but they are not in ``__all__``: the API reference documents them once, in ``boresight``
from boresight.errors import ObservationError
from boresight.errors import ObservationFileError as ObservationFileError
from orbits.records import ImageRecords, rows_are_canonical
from orbits.rotations import dcm_from_quat
from orbits.sight import LANDMARK_SIGHTS

if TYPE_CHECKING:
    from orbits.camera import CameraCalibration
    from orbits.star_catalogue import StarCatalogue

__all__ = [
    "ObservationSet",
    "canonical_order",
    "from_measurements",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FORMAT_VERSION_LANDMARKS",
    "FORMAT_VERSION_STARS",
    "FORMAT_VERSION_ROW_SIGMA",
    "SIGMA_XY_LIMITS_M",
    "READ_VERSIONS",
    "TARGET_KINDS",
    "LANDMARK_SIGHTS",
    "catalogue_directions",
    "FIELD_MARGIN",
    "LIMITS",
    "geometry_problem",
    "rotation_problem",
]

FORMAT_NAME = "boresight-observations"
FORMAT_VERSION = "1.4"
#: versions this reader reads (1.0: no velocity, noise, camera or pixel columns; 1.1: no star rows;
#: 1.2: no per-row σ columns; 1.3: no ``landmark_sight`` key)
READ_VERSIONS = ("1.0", "1.1", "1.2", "1.3", "1.4")
#: DECISION: a file is written as the lowest version that carries it — 1.1 without star rows or per-row σ,
#: so a reader of 1.1 still reads every landmark file; 1.2 with star rows (``kind`` and the star columns);
#: 1.3 only with a per-row σ (``sigma_x sigma_y``), which an older reader would
#: ignore (it reads unknown columns past) and so weight every row by the noise model's one σ;
#: 1.4 (``FORMAT_VERSION``) only with landmark rows that carry light time and aberration (the ``landmark_sight``
#: key, ``docs/data-format.md``), which a 1.3 reader would read past as geometric
FORMAT_VERSION_LANDMARKS = "1.1"
FORMAT_VERSION_STARS = "1.2"
FORMAT_VERSION_ROW_SIGMA = "1.3"
#: the target kinds of the row model
TARGET_KINDS = ("landmark", "star")


#: DECISION: a measured point may sit a little outside the nominal field (noise, a real
#: misalignment); 1 % of the half-width is allowed, more is a bad row or a bad fov_deg.
FIELD_MARGIN = 1.01

#: DECISION: the largest magnitude of each value, in the field's SI unit, with what it means.
#: Physics is generous here; the point is that every number stays far from overflow when it is
#: squared, summed and inverted (``r_y = -1e308`` reached numpy's eigensolver as a LinAlgError,
#: ``cgi12 = -1e308`` in run 2 passed). The reader applies the same bounds to each column
#: (``boresight.observations.ecsv``), so a file and the same data in memory are refused alike.
LIMITS = {
    "t_s": (1e9, "s", "image time from the epoch: ±31.7 years"),
    "r_sc_i_m": (1e9, "m", "spacecraft position: 2.6 × the Moon's distance"),
    "v_sc_i_m_s": (1e5, "m / s", "spacecraft velocity: 9 × Earth's escape velocity"),
    "landmark_g_m": (1e8, "m", "landmark position: 16 Earth radii"),
    "xy_m": (1e5, "m", "focal-plane coordinate"),
    "focal_length_m": (100.0, "m", "focal length"),
}


@dataclass(frozen=True)
class _SetFields:
    """The fields of an observation set beyond its tables (camera, mount, epoch, frames, truth, velocity,
    noise model, target kinds and star astrometry), in ``ObservationSet``'s field order after the tables;
    the tests' images × landmarks grid (``tests/oracles.py``, ``DenseGrid``) inherits them too."""

    focal_length_m: float
    C_SK_nominal: np.ndarray = field(default_factory=lambda: np.eye(3))
    fov_deg: float | None = None
    pixel_pitch_m: float | None = None
    epoch_utc: str = "2000-01-01T12:00:00"
    frames: dict = field(default_factory=lambda: {"inertial": "GCRS", "earth_fixed": "ITRS"})
    truth: dict | None = None
    v_sc_i_m_s: np.ndarray | None = None
    noise: dict | None = None
    camera: CameraCalibration | None = None
    #: (T,) ``"landmark"`` or ``"star"``; None: every target a landmark
    target_kind: np.ndarray | None = None
    #: the astrometry of the star targets (``orbits.star_catalogue.StarCatalogue``), one entry per
    #: target of kind ``"star"`` in target order; None when the set has no star
    stars: StarCatalogue | None = None
    #: what a landmark row's inertial target vector carries (``LANDMARK_SIGHTS``; module docstring, "Landmark sight"):
    #: ``"geometric"`` (C_GI r_L − r) or ``"light_time+aberration"`` (the apparent direction, ``orbits.sight``)
    landmark_sight: str = "geometric"
    #: False only to inspect a set that fails the geometry check (the convention doctor)
    check_geometry: bool = field(default=True, repr=False)


class _ImageDerived:
    """The derived arrays of the image and target tables (attitudes, velocity, target vectors) and the run slicing
    (through ``_subset``), shared by ``ObservationSet`` and the tests' grid (``tests/oracles.py``, ``DenseGrid``)."""

    t_s: np.ndarray
    epoch_utc: str
    landmark_ids: np.ndarray
    landmark_g_m: np.ndarray
    C_GI: np.ndarray
    r_sc_i_m: np.ndarray
    target_kind: np.ndarray | None
    stars: "StarCatalogue | None"
    q_is: np.ndarray
    C_SK_nominal: np.ndarray
    v_sc_i_m_s: np.ndarray | None
    noise: dict | None
    xy_m: np.ndarray
    truth: dict | None
    landmark_sight: str
    runs: int

    def _subset(self, **changes: Any) -> Self:
        raise NotImplementedError

    def run(self, k: Any) -> Self:
        """The run(s) ``k`` (an int or a slice) with a run axis (the same kind of set)."""
        sl = slice(k, k + 1) if isinstance(k, (int, np.integer)) else k
        truth = None
        if self.truth is not None:
            truth = {key: (v[sl] if _has_run_axis(key, v, self.runs) else v) for key, v in self.truth.items()}
        return self._subset(
            q_is=self.q_is[sl],
            r_sc_i_m=self.r_sc_i_m[sl],
            landmark_g_m=self.landmark_g_m[sl],
            xy_m=self.xy_m[sl],
            truth=truth,
            v_sc_i_m_s=None if self.v_sc_i_m_s is None else self.v_sc_i_m_s[sl],
        )

    def attitude_st(self) -> np.ndarray:
        """Measured star-tracker attitude matrices A = C_IS, (R, N, 3, 3)."""
        return dcm_from_quat(self.q_is)

    def nominal_camera_attitude(self) -> np.ndarray:
        """C_IK at θ = 0 from the star tracker: C_SK,nominal A, (R, N, 3, 3)."""
        return self.C_SK_nominal @ self.attitude_st()

    def velocity_i_m_s(self):
        """Inertial spacecraft velocity (R, N, 3) m/s: the given GNSS velocity, else one derived from
        the positions where the images are dense enough (``boresight.observations.velocity``), else None (the
        reason is in ``velocity_status``)."""
        return self._velocity()[0]

    @property
    def velocity_status(self) -> str:
        """``'given'``, ``'derived (...)'`` with the criterion met and the error estimate, or
        ``'unavailable: ...'`` with the reason."""
        return self._velocity()[1]

    # ------------------------------------------------------------------ targets of either kind
    def target_kinds(self) -> np.ndarray:
        """(T,) str: each target's kind, ``"landmark"`` or ``"star"`` (``TARGET_KINDS``); ``target_kind`` itself,
        or every target a landmark where a set has no ``target_kind`` (a format-1.0/1.1 file, a landmark-only set)."""
        kind = getattr(self, "target_kind", None)
        if kind is None:
            return np.full(np.shape(self.landmark_ids)[:1], "landmark")
        return np.asarray(kind)

    def star_rank(self) -> np.ndarray:
        """(T,) the entry of each target in ``stars`` (−1 for a landmark)."""
        is_star = self.target_kinds() == "star"
        return np.where(is_star, np.cumsum(is_star) - 1, -1)

    def star_directions_i(self, image_index, target_index) -> np.ndarray:
        """Apparent (proper) GCRS unit directions (K, 3) of the star targets ``target_index`` seen
        from the spacecraft at the images ``image_index`` (both (K,)); NaN where the target is a landmark.

        The one apparent-place function ``orbits.star_apparent.apparent_directions`` at each image's
        UTC time (``epoch_utc`` + ``t_s``), from run 0's position and velocity (module docstring);
        cached per (image_index, target_index) pair list. Raises ``ObservationError`` when the
        set has no velocity (the orbital aberration, ~5″ in LEO, needs it).
        """
        ii = np.asarray(image_index, np.int64).reshape(-1)
        tt = np.asarray(target_index, np.int64).reshape(-1)
        cache = self.__dict__.setdefault("_star_direction_cache", {})
        key = (ii.tobytes(), tt.tobytes())
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            cache[key] = _apparent_star_directions(self, ii, tt)
        out: np.ndarray = cache[key]
        return out

    def row_target_vectors_i(self, image_index, target_index) -> np.ndarray:
        """The inertial vector of each (image, target) pair, (R, K, 3): from the spacecraft to a landmark
        (``landmark_vectors_i``: C_GI r_L − r (m), or with ``landmark_sight`` = ``"light_time+aberration"`` its
        apparent direction times that range), the apparent unit direction u_k (``star_directions_i``) of a star.
        The measurement model's input (``boresight.core.measurement``): both project alike."""
        ii = np.asarray(image_index, np.int64)
        tt = np.asarray(target_index, np.int64)
        star = self.target_kinds()[tt] == "star"
        if not star.any():
            return self.landmark_vectors_i(ii, tt)
        lm = ~star
        out = np.empty((self.r_sc_i_m.shape[0], ii.size, 3))
        out[:, lm] = self.landmark_vectors_i(ii[lm], tt[lm])
        out[:, star] = self.star_directions_i(ii[star], tt[star])[None]
        return out

    def landmark_vectors_i(self, image_index, target_index, landmark_g_m=None, r_sc_i_m=None) -> np.ndarray:
        """(R, K, 3) the inertial vector from the spacecraft to each landmark row (image, target) (K,): C_GI r_L − r
        (m), geometric; with ``landmark_sight`` = ``"light_time+aberration"`` the apparent unit direction
        (``orbits.sight.apparent_sight_i``: light time and aberration, the Earth's spin ``EARTH_SPIN_G_RAD_S``)
        times the geometric range |C_GI r_L − r|, so what uses the range is unchanged (module docstring,
        "Landmark sight"). ``landmark_g_m`` (R, T, 3) and ``r_sc_i_m`` (R, N, 3) replace the set's own (an
        effect's perturbed catalogue or positions: ``boresight.core.effect_model``)."""
        ii = np.asarray(image_index, np.int64)
        tt = np.asarray(target_index, np.int64)
        L = (self.landmark_g_m if landmark_g_m is None else np.asarray(landmark_g_m, float))[:, tt]
        r = (self.r_sc_i_m if r_sc_i_m is None else np.asarray(r_sc_i_m, float))[:, ii]
        C_GI = self.C_GI[ii]
        d: np.ndarray = np.einsum("kij,rkj->rki", C_GI, L) - r
        if self.landmark_sight == "geometric" or ii.size == 0:
            return d
        from orbits.sight import EARTH_SPIN_G_RAD_S, SightCorrections, apparent_sight_i

        v = self.velocity_i_m_s()
        if v is None:
            raise ObservationError(
                f"ObservationSet: landmark_sight {self.landmark_sight!r} needs the spacecraft velocity (the aberration, "
                f"~5″ in LEO): give v_sc_i_m_s (file columns v_x v_y v_z); {self.velocity_status}"
            )
        sight = apparent_sight_i(r, np.asarray(v)[:, ii], C_GI, L, EARTH_SPIN_G_RAD_S, SightCorrections(True, True))
        out: np.ndarray = sight.direction_i * np.linalg.norm(d, axis=-1, keepdims=True)
        return out

    def landmark_rows(self, target_index) -> np.ndarray:
        """(K,) bool: the rows whose target is a landmark (GNSS and the landmark catalogue act on them only)."""
        return self.target_kinds()[np.asarray(target_index, np.int64)] == "landmark"

    def _velocity(self):
        cache = self.__dict__.get("_velocity_cache")
        if cache is None:
            if self.v_sc_i_m_s is not None:
                cache = (self.v_sc_i_m_s, "given")
            else:
                from boresight.observations.velocity import derive_velocity

                sigma = None
                if self.noise is not None:
                    sigma = self.noise["gnss"]["sigma_m"]
                d = derive_velocity(self.t_s, self.pass_index, self.r_sc_i_m, gnss_sigma_m=sigma)
                cache = (d.v_i_m_s, d.status)
            object.__setattr__(self, "_velocity_cache", cache)
        return cache


@dataclass(frozen=True)
class ObservationSet(_ImageDerived, _SetFields, ImageRecords):
    """The observations of a campaign, flight or simulated: three tables (images, targets, rows) with a
    leading run axis R (1 for flight data) on every array whose values differ between runs (the module
    docstring and ``docs/architecture.md``, "The row model"). Built from its fields, checked on
    construction as the file reader checks a file; ``ObservationSet.read`` / ``write`` for the file.

    Attributes
    ----------
    t_s : numpy.ndarray
        (N,) image times, s from ``epoch_utc``.
    pass_index : numpy.ndarray
        (N,) int: the pass of a campaign each image belongs to.
    q_is : numpy.ndarray
        (R, N, 4) star-tracker attitude quaternion, inertial → star tracker, scalar last.
    r_sc_i_m : numpy.ndarray
        (R, N, 3) GNSS spacecraft position in the inertial frame, m.
    C_GI : numpy.ndarray
        (N, 3, 3) Earth-fixed → inertial DCM at each image.
    landmark_ids : numpy.ndarray
        (T,) str: the target identifiers.
    landmark_g_m : numpy.ndarray
        (R, T, 3) catalogue landmark positions in the Earth-fixed frame, m (NaN for a star).
    image_index, target_index : numpy.ndarray
        (K,) int: the image and the target of each row, rows in canonical (image, target) order.
    xy_m : numpy.ndarray
        (R, K, 2) measured focal-plane point of each row, m.
    focal_length_m : float
        The camera's focal length, m.
    C_SK_nominal : numpy.ndarray
        (3, 3) nominal star-tracker → camera DCM; θ is defined by C_SK,true = exp(−Φ(θ)) C_SK,nominal.
    fov_deg, pixel_pitch_m : float or None
        Full field of view (deg; measured points beyond its 1 % margin are refused) and pixel pitch (m).
    epoch_utc : str
        ISO UTC time that ``t_s`` counts from.
    frames : dict
        The frames' names: ``{"inertial": "GCRS", "earth_fixed": "ITRS"}`` by default.
    truth : dict or None
        Simulations: ``theta_rad`` (R, 3), ``delta_rad`` (R, N, 3), ``gnss_error_m`` (R, N, 3),
        ``catalogue_error_m`` (R, T, 3), ``xy_true_m`` and ``pixel_noise_m`` (R, K, 2), ``effects``.
    v_sc_i_m_s : numpy.ndarray or None
        (R, N, 3) GNSS spacecraft velocity in the inertial frame, m/s (``velocity_i_m_s()`` derives one
        from the positions when it is None).
    noise : dict or None
        The sensor noise model as a mapping with the scenario file's tables and keys
        (``DisturbanceModel.from_observations`` reads it).
    camera : orbits.camera.CameraCalibration or None
        Pixels ↔ focal plane.
    target_kind : numpy.ndarray or None
        (T,) ``"landmark"`` or ``"star"``; None: every target a landmark (``target_kinds()`` gives it either way).
    stars : orbits.star_catalogue.StarCatalogue or None
        The astrometry of the star targets, one entry per star target in target order.
    landmark_sight : str
        What a landmark row's target vector carries: ``"geometric"`` (default) or ``"light_time+aberration"``
        (module docstring, "Landmark sight").
    check_geometry : bool
        False only to inspect a set that fails the geometry check (the convention doctor).
    sample_t_s, sample_index, sample_weight : numpy.ndarray or None
        The attitude-sample table of pushbroom lines: (S,) sample times, (N, 2) the two samples each
        image interpolates between, (N, 2) their weights; None: one sample per image (a frame camera).
    line_scan : orbits.strip.LineScanRecords or None
        The pushbroom context of a set whose images are lines (sensor, datation, trajectory, each line's
        chip and pixel); None for frame images.
    sigma_xy_m : numpy.ndarray or None
        (K, 2) each row's own σ of x and y, m; NaN on a row (or None for all): the noise model's pixel σ.

    Raises
    ------
    ObservationError
        On construction, when a field is inconsistent (shapes, canonical order, a non-finite or
        out-of-range value, a rotation that is not one, a landmark behind the camera, …); the message
        names the field, the run, image or row, and the value.
    """

    # fields: the tables (``ImageRecords``), then ``_SetFields``, then the attitude samples and the line scan
    #: the attitude-sample table (a pushbroom line's star-tracker samples): ``sample_t_s`` (S,) the samples' times
    #: from ``epoch_utc``, ``sample_index`` (N, 2) the two samples each image's attitude interpolates between and
    #: ``sample_weight`` (N, 2) their weights; all None: one sample per image (a frame camera, S = N)
    sample_t_s: np.ndarray | None = None
    sample_index: np.ndarray | None = None
    sample_weight: np.ndarray | None = None
    #: the pushbroom context of a set whose images are lines (``orbits.strip.LineScanRecords``: sensor, datation,
    #: trajectory, each image's measured line, chip and pixel), or None (frame images)
    line_scan: Any = field(default=None, repr=False)
    #: (K, 2) each row's own σ of x and y (m), NaN where the noise model's pixel σ applies; None: every row
    #: the noise model's (module docstring, "Per-row pixel σ")
    sigma_xy_m: np.ndarray | None = None

    def __post_init__(self):
        _validate(self)

    @property
    def n_samples(self) -> int:
        """S: the attitude samples (N for a frame camera, whose image is its own sample)."""
        return self.n_images if self.sample_t_s is None else int(np.shape(self.sample_t_s)[0])

    @property
    def has_samples(self) -> bool:
        """True when the star-tracker errors live on an attitude-sample table (``sample_t_s``), not per image."""
        return self.sample_t_s is not None

    def row_star_directions_i(self) -> np.ndarray:
        """(K, 3) the apparent direction of every row's star (NaN on landmark rows): ``star_directions_i`` of the rows."""
        return self.star_directions_i(self.image_index, self.target_index)

    # ------------------------------------------------------------------ per-row gathers
    def row_landmarks_g_m(self) -> np.ndarray:
        """Catalogue position of each row's target, Earth-fixed, (R, K, 3)."""
        return self.landmark_g_m[:, self.target_index]

    # ------------------------------------------------------------------ descriptions of the rows (what a command prints)
    def landmark_range_span_m(self, run: int = 0) -> tuple[float, float] | None:
        """(nearest, farthest) distance from the spacecraft to a landmark over the landmark rows of ``run``, m: the
        length ``|C_GI r_L − r|`` of ``landmark_vectors_i`` at each row's image (the geometric range either way of
        ``landmark_sight``); None when the set has no landmark row. ``boresight simulate`` prints it."""
        lm = self.landmark_rows(self.target_index)
        if not lm.any():
            return None
        d = np.linalg.norm(self.landmark_vectors_i(self.image_index[lm], self.target_index[lm])[run], axis=-1)
        return float(d.min()), float(d.max())

    def field_angle_span_deg(self, run: int = 0) -> tuple[float, float] | None:
        """(smallest, largest) angle between a row's predicted camera direction at θ = 0 (the nominal mount:
        ``boresight.core.measurement.predicted_camera_vectors``: s in camera axes) and the boresight, −z of the
        camera (``CONVENTIONS.md``), ``arccos(−s_z / |s|)``, deg, over the rows of ``run``; None for a set without rows.
        ``boresight simulate`` prints it: how far off the boresight the targets sit."""
        if self.n_observations == 0:
            return None
        from boresight.core.measurement import predicted_camera_vectors

        s = predicted_camera_vectors(self.run(run), np.zeros(3), (self.image_index, self.target_index))[0]  # (K, 3)
        off = np.degrees(np.arccos(np.clip(-s[..., 2] / np.linalg.norm(s, axis=-1), -1, 1)))
        return float(off.min()), float(off.max())

    def sigma_xy_span_m(self) -> tuple[float, float] | None:
        """(smallest, largest) of the rows' own σ of x and y (``sigma_xy_m``: star centroids weighted by magnitude,
        a flight file's per-row σ), m, over the rows that carry one; None when no row does (every row takes the
        noise model's pixel σ)."""
        own = self.sigma_xy_m
        if own is None or not np.any(np.isfinite(own)):
            return None
        return float(np.nanmin(own)), float(np.nanmax(own))

    def pass_time_span_s(self, pass_label: Any) -> tuple[float, float] | None:
        """(first, last) time ``t_s`` of the images of the pass ``pass_label`` (a value of ``pass_index``), s; None
        when the set has no image of it (a simulated pass whose images saw no landmark). ``boresight simulate``
        prints it per pass."""
        t = np.asarray(self.t_s)[np.asarray(self.pass_index) == pass_label]
        return (float(t.min()), float(t.max())) if t.size else None

    def line_span(self) -> tuple[float, float] | None:
        """(first, last) measured line of a pushbroom set's lines (``line_scan.line``, fractional lines of the
        detector); None for frame images. The pushbroom commands print it in their file header."""
        if self.line_scan is None:
            return None
        line = np.asarray(self.line_scan.line, float)
        return float(line.min()), float(line.max())

    def row_xy_grid(self) -> np.ndarray:
        """``xy_m`` as (R, N, T, 2) — a view, only for a complete set (``is_complete``)."""
        if not self.is_complete:
            raise ObservationError("ObservationSet.row_xy_grid: the set is not complete (not every target in every image)")
        return self.xy_m.reshape(self.runs, self.n_images, self.n_targets, 2)

    # ------------------------------------------------------------------ slicing
    def _subset(self, **changes) -> "ObservationSet":
        """A copy with ``changes``, not checked again: ``run``, ``images``, ``rows`` and ``targets``
        take a subset of a checked set, which passes every check by construction (shapes are kept
        consistent by the slicing, values and geometry are those already checked).
        DECISION: slicing is on the doctor's and the studies' inner loops (a group of images at a
        time); re-running the checks there cost more than the computation on the subset."""
        out = object.__new__(ObservationSet)
        for f in fields(ObservationSet):
            object.__setattr__(out, f.name, changes[f.name] if f.name in changes else getattr(self, f.name))
        return _set_star_position(out, self.__dict__.get("_star_position_i_m"))  # the same images (images() slices it)

    def images(self, sel) -> "ObservationSet":
        """A subset of images (index array, slice or boolean mask over N) with their rows.

        ``image_index`` is renumbered; the target table is kept whole (DECISION: subsets of one
        set share target indices — ``diagnose`` and the Monte Carlo compare targets across
        them; an unobserved target costs one entry of the target table and nothing else).
        """
        idx = np.arange(self.n_images)[sel]
        start = self.row_start
        counts = (start[1:] - start[:-1])[idx]
        new_start = np.concatenate([[0], np.cumsum(counts)])
        k = np.arange(int(new_start[-1]))
        new_image = np.repeat(np.arange(idx.size), counts)
        rows = np.repeat(start[:-1][idx], counts) + (k - new_start[:-1][new_image])
        truth = None
        if self.truth is not None:
            truth = dict(self.truth)
            for key in ("delta_rad", "gnss_error_m"):
                if key in truth:
                    truth[key] = truth[key][:, idx]
            for key in _ROW_TRUTH:
                if key in truth:
                    truth[key] = truth[key][:, rows]
            for key in ("C_IS", "r_sc_i_m"):
                if key in truth:
                    truth[key] = truth[key][idx]
        out = self._subset(
            t_s=self.t_s[idx],
            pass_index=self.pass_index[idx],
            q_is=self.q_is[:, idx],
            r_sc_i_m=self.r_sc_i_m[:, idx],
            C_GI=self.C_GI[idx],
            image_index=new_image.astype(np.int64),
            target_index=self.target_index[rows],
            xy_m=self.xy_m[:, rows],
            truth=truth,
            v_sc_i_m_s=None if self.v_sc_i_m_s is None else self.v_sc_i_m_s[:, idx],
            sample_index=None if self.sample_index is None else self.sample_index[idx],
            sample_weight=None if self.sample_weight is None else self.sample_weight[idx],
            line_scan=None if self.line_scan is None else self.line_scan.images(idx),
            sigma_xy_m=None if self.sigma_xy_m is None else self.sigma_xy_m[rows],
        )
        pos = self.__dict__.get("_star_position_i_m")
        return _set_star_position(out, None if pos is None else pos[idx])

    def rows(self, sel) -> "ObservationSet":
        """A subset of the rows (index array, slice or boolean mask over K; kept in canonical
        order): the images and the target table are kept whole, the rows' truth with them."""
        keep = np.unique(np.arange(self.n_observations)[sel])
        truth = None
        if self.truth is not None:
            truth = {k: (v[:, keep] if k in _ROW_TRUTH else v) for k, v in self.truth.items()}
        return self._subset(
            image_index=self.image_index[keep],
            target_index=self.target_index[keep],
            xy_m=self.xy_m[:, keep],
            truth=truth,
            sigma_xy_m=None if self.sigma_xy_m is None else self.sigma_xy_m[keep],
        )

    def targets(self, sel) -> "ObservationSet":
        """A subset of the targets (index array, slice or boolean mask over T, kept in their
        order) with their rows; ``target_index`` is renumbered, the images are kept whole."""
        idx = np.unique(np.arange(self.n_targets)[sel])
        new = np.full(self.n_targets, -1, np.int64)
        new[idx] = np.arange(idx.size)
        keep = np.nonzero(new[self.target_index] >= 0)[0]
        truth = None
        if self.truth is not None:
            truth = dict(self.truth)
            for k in _ROW_TRUTH:
                if k in truth:
                    truth[k] = truth[k][:, keep]
            if "catalogue_error_m" in truth:
                truth["catalogue_error_m"] = truth["catalogue_error_m"][:, idx]
            if "landmark_g_m" in truth:
                truth["landmark_g_m"] = truth["landmark_g_m"][idx]
        stars = self.stars
        if stars is not None:
            rank = self.star_rank()[idx]
            stars = stars.subset(rank[rank >= 0]) if np.any(rank >= 0) else None
        return self._subset(
            landmark_ids=self.landmark_ids[idx],
            landmark_g_m=self.landmark_g_m[:, idx],
            target_kind=None if self.target_kind is None else np.asarray(self.target_kind)[idx],
            stars=stars,
            image_index=self.image_index[keep],
            target_index=new[self.target_index[keep]],
            xy_m=self.xy_m[:, keep],
            truth=truth,
            sigma_xy_m=None if self.sigma_xy_m is None else self.sigma_xy_m[keep],
        )

    def with_sigma_xy(self, sigma_xy_m) -> "ObservationSet":
        """The set with each row's own pixel σ replaced: ``sigma_xy_m`` (K, 2) m (NaN on a row: the noise model's
        σK) or None (every row the noise model's). Checked as the constructor checks it; nothing else is
        checked again (``_subset``). The studies scale the rows' σ with a source's factor (sensitivity's
        per-source propagation, a Monte Carlo variant) without rebuilding the set."""
        out = self._subset(sigma_xy_m=None if sigma_xy_m is None else np.asarray(sigma_xy_m, float))
        _check_sigma_xy(out)
        return out

    def observed_targets(self) -> "ObservationSet":
        """The set without the targets that have no row (``targets`` of those with one)."""
        seen = np.bincount(self.target_index, minlength=self.n_targets) > 0
        return self if seen.all() else self.targets(seen)

    # ------------------------------------------------------------------ files
    def write(self, path, overwrite: bool = False, image_columns: str = "xy") -> Path:
        """Write as ECSV, or Parquet for a ``.parquet`` path (``docs/data-format.md``);
        ``image_columns="uv"`` writes pixels (needs ``camera``). A set with an attitude-sample table (pushbroom
        lines) is refused: the file format cannot carry the table yet, and read back without it each line's
        star-tracker error would count as its own."""
        if self.has_samples:
            raise ObservationError(
                f"ObservationSet.write {path}: the set's star-tracker errors live on an attitude-sample table "
                f"({self.n_samples} samples for {self.n_images} lines), which the observation file format cannot carry yet"
            )
        return FILE_FORMAT["write"](self, path, overwrite=overwrite, image_columns=image_columns)

    @classmethod
    def read(cls, path) -> "ObservationSet":
        """Read and validate an observation file (``docs/data-format.md``)."""
        return FILE_FORMAT["read"](path)


#: truth arrays with one entry per row, (R, K, 2)
_ROW_TRUTH = ("xy_true_m", "pixel_noise_m")


#: the observation file's writer and reader, ``{"write": write_observations, "read": read_observations}``,
#: set by ``boresight.observations.ecsv`` (which the package ``boresight.observations`` always imports).
# DECISION: the data model does not import its file format — the format imports the model (one
# direction, no import circle) and registers itself here for ``write``/``read``.
FILE_FORMAT: dict = {}


def _catalogue_directions(o) -> np.ndarray | None:
    return catalogue_directions(o.target_kind, o.stars)


def catalogue_directions(target_kind, stars) -> np.ndarray | None:
    """(T, 3) the ICRS unit vector of each star target at its catalogue epoch (NaN for a landmark),
    or None without stars: what ``geometry_problem`` tests a star row on."""
    if stars is None:
        return None
    is_star = np.asarray(target_kind) == "star"
    out = np.full((is_star.size, 3), np.nan)
    out[is_star] = stars.unit_vectors()
    return out


def _apparent_star_directions(o: Any, ii: np.ndarray, tt: np.ndarray, r_i_m: Any = None) -> np.ndarray:
    """``star_directions_i`` computed: observer states of the images with star rows, then the one
    apparent-place function (``orbits.star_apparent``). ``r_i_m`` (N, 3): the images' positions
    (default run 0's)."""
    out = np.full((ii.size, 3), np.nan)
    rank = o.star_rank()[tt]
    star = rank >= 0
    if not star.any():
        return out
    v = o.velocity_i_m_s()
    if v is None:
        raise ObservationError(
            f"ObservationSet: star rows need the spacecraft velocity (the orbital aberration, ~5″ in LEO): "
            f"give v_sc_i_m_s (file columns v_x v_y v_z); {o.velocity_status}"
        )
    from astropy import units as u
    from astropy.time import Time

    from orbits.star_apparent import apparent_directions, observer_states

    images, local = np.unique(ii[star], return_inverse=True)
    times = Time(o.epoch_utc, scale="utc") + np.asarray(o.t_s, float)[images] * u.s
    if r_i_m is None:
        r_i_m = o.__dict__.get("_star_position_i_m")  # a simulated set's true positions (from_measurements)
    r = np.asarray(o.r_sc_i_m)[0] if r_i_m is None else np.asarray(r_i_m, float)
    observer = observer_states(times, r[images], np.asarray(v)[0, images])
    out[star] = apparent_directions(o.stars, observer, rank[star], local)
    return out


def _has_run_axis(key, v, runs):
    return (
        key in ("theta_rad", "delta_rad", "gnss_error_m", "catalogue_error_m") + _ROW_TRUTH
        and np.ndim(v) >= 1
        and np.shape(v)[0] == runs
    )


def _shape_error(name, expected, got):
    return ObservationError(f"ObservationSet.{name}: expected shape {expected}, got {tuple(got)}")


def _coerce(o: ObservationSet):
    for name in ("t_s", "pass_index", "q_is", "r_sc_i_m", "C_GI", "landmark_ids", "landmark_g_m", "xy_m", "C_SK_nominal"):
        object.__setattr__(o, name, np.asarray(getattr(o, name)))
    for name in ("image_index", "target_index"):
        a = np.asarray(getattr(o, name))
        if a.size and not np.issubdtype(a.dtype, np.integer):
            whole = np.issubdtype(a.dtype, np.number) and bool(np.all(np.isfinite(a) & (a == np.round(a))))
            if not whole:
                raise ObservationError(f"ObservationSet.{name}: row indices must be integers, got dtype {a.dtype}")
        object.__setattr__(o, name, a.astype(np.int64))
    kind = o.target_kind
    kind = np.full(o.landmark_ids.shape[:1], "landmark") if kind is None else np.asarray(kind, dtype=str)
    object.__setattr__(o, "target_kind", kind)


def _check_shapes(o: ObservationSet):
    if o.t_s.ndim != 1 or o.t_s.size == 0:
        raise _shape_error("t_s", "(N,) with N ≥ 1", o.t_s.shape)
    n = o.t_s.size
    if o.image_index.ndim != 1:
        raise _shape_error("image_index", "(K,)", o.image_index.shape)
    k = o.image_index.size
    if o.xy_m.ndim != 3 or o.xy_m.shape[1] != k or o.xy_m.shape[2] != 2:
        raise _shape_error("xy_m", f"(R, {k}, 2)", o.xy_m.shape)
    if o.landmark_ids.ndim != 1:
        raise _shape_error("landmark_ids", "(T,)", o.landmark_ids.shape)
    r, m = o.xy_m.shape[0], o.landmark_ids.size
    expected = {
        "pass_index": (n,),
        "q_is": (r, n, 4),
        "r_sc_i_m": (r, n, 3),
        "C_GI": (n, 3, 3),
        "landmark_g_m": (r, m, 3),
        "target_index": (k,),
        "target_kind": (m,),
        "C_SK_nominal": (3, 3),
    }
    for name, shape in expected.items():
        if getattr(o, name).shape != shape:
            raise _shape_error(name, shape, getattr(o, name).shape)


def _check_rows(o: ObservationSet):
    """Row indices in range, rows in canonical (image, target) order, each pair at most once."""
    for name, size, what in (("image_index", o.n_images, "images"), ("target_index", o.n_targets, "targets")):
        a = getattr(o, name)
        bad = (a < 0) | (a >= size)
        if bad.any():
            k = int(np.argmax(bad))
            raise ObservationError(f"ObservationSet.{name}: row {k} has index {int(a[k])}, the set has {size} {what}")
    kinds = set(np.unique(np.asarray(o.target_kind)).tolist()) - set(TARGET_KINDS)
    if kinds:
        raise ObservationError(f"ObservationSet.target_kind: unknown kind {sorted(kinds)[0]!r} (expected one of {TARGET_KINDS})")
    ok = rows_are_canonical(o.image_index, o.target_index)
    if not ok.all():
        k = int(np.argmax(~ok))
        n, t = int(o.image_index[k + 1]), int(o.target_index[k + 1])
        lm = str(o.landmark_ids[t])
        if n == o.image_index[k] and t == o.target_index[k]:
            raise ObservationError(
                f"ObservationSet: duplicate observation of landmark {lm!r} in image {n} (rows {k} and {k + 1})"
            )
        raise ObservationError(
            f"ObservationSet: rows must be sorted by (image, target): row {k + 1} (image {n}, landmark {lm!r}) comes after "
            f"row {k} (image {int(o.image_index[k])}, landmark {str(o.landmark_ids[o.target_index[k]])!r}); "
            "boresight.observations.model.canonical_order gives the sorting permutation"
        )


def canonical_order(image_index, target_index) -> np.ndarray:
    """The permutation that sorts rows into the canonical (image, target) order (stable)."""
    return np.lexsort((np.asarray(target_index), np.asarray(image_index)))


def _row_where(o: ObservationSet, k: int) -> str:
    return f"image {int(o.image_index[k])}, landmark {str(o.landmark_ids[o.target_index[k]])!r}"


def _check_samples(o: ObservationSet):
    """The attitude-sample table: all three fields or none; times (S,) finite and strictly increasing; each image's
    two samples (N, 2) in 0..S-1 with finite weights in [0, 1] summing to 1 (an interpolation)."""
    given = [o.sample_t_s is not None, o.sample_index is not None, o.sample_weight is not None]
    if not any(given):
        return
    if not all(given):
        raise ObservationError("sample_t_s, sample_index and sample_weight go together (the attitude-sample table): all or none")
    t = np.asarray(o.sample_t_s, float)
    si = np.asarray(o.sample_index)
    sw = np.asarray(o.sample_weight, float)
    N = o.n_images
    if t.ndim != 1 or t.size < 1:
        raise _shape_error("sample_t_s", "(S,)", t.shape)
    if si.shape != (N, 2) or not np.issubdtype(si.dtype, np.integer):
        raise _shape_error("sample_index", f"({N}, 2) integers", si.shape)
    if sw.shape != (N, 2):
        raise _shape_error("sample_weight", f"({N}, 2)", sw.shape)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        k = int(np.argmax(~np.isfinite(t[1:]) | (np.diff(t) <= 0))) + 1 if t.size > 1 else 0
        raise ObservationError(f"sample_t_s must be finite and strictly increasing; sample {k} = {t[k]!r} s")
    bad = ((si < 0) | (si >= t.size)).any(axis=1)
    if bad.any():
        n = int(np.argmax(bad))
        raise ObservationError(f"sample_index of image {n} = {si[n].tolist()} is outside the {t.size} attitude samples")
    bad = ~(np.isfinite(sw).all(axis=1) & (sw >= 0).all(axis=1) & (sw <= 1).all(axis=1) & (np.abs(sw.sum(axis=1) - 1) < 1e-9))
    if bad.any():
        n = int(np.argmax(bad))
        raise ObservationError(f"sample_weight of image {n} = {sw[n].tolist()} is not an interpolation (in [0, 1], summing to 1)")
    object.__setattr__(o, "sample_t_s", t)
    object.__setattr__(o, "sample_index", si.astype(np.int64))
    object.__setattr__(o, "sample_weight", sw)


def _check_focal_length(o: ObservationSet):
    if not (np.isfinite(o.focal_length_m) and 0 < o.focal_length_m <= LIMITS["focal_length_m"][0]):
        raise ObservationError(
            f"ObservationSet.focal_length_m must be > 0 m and ≤ {LIMITS['focal_length_m'][0]:g} m, got {o.focal_length_m!r}"
        )


def _check_stars(o: ObservationSet):
    """Star targets: their astrometry (``stars``, one entry per star target), an inertial frame that is GCRS."""
    n_star = int(np.sum(np.asarray(o.target_kind) == "star"))
    if n_star == 0:
        if o.stars is not None and len(o.stars) > 0:
            raise ObservationError(f"ObservationSet.stars: {len(o.stars)} star(s) given but no target has kind 'star'")
        return
    from orbits.star_catalogue import StarCatalogue

    if not isinstance(o.stars, StarCatalogue):
        raise ObservationError(
            f"ObservationSet.stars must be an orbits.star_catalogue.StarCatalogue (the astrometry of the {n_star} star "
            f"target(s)), got {type(o.stars).__name__}"
        )
    if len(o.stars) != n_star:
        raise ObservationError(f"ObservationSet.stars: {len(o.stars)} entries for {n_star} target(s) of kind 'star'")
    if (o.frames or {}).get("inertial") != "GCRS":
        raise ObservationError(
            f"ObservationSet: star targets need the inertial frame GCRS (their apparent directions are GCRS), "
            f"frames = {o.frames!r}"
        )


def _check_finite(o: ObservationSet):
    for name in ("t_s", "q_is", "r_sc_i_m", "C_GI", "landmark_g_m", "C_SK_nominal"):
        a = getattr(o, name)
        if name == "landmark_g_m":  # a star target has no position (NaN)
            a = a[:, np.asarray(o.target_kind) == "landmark"]
        if not np.all(np.isfinite(a)):
            idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise ObservationError(f"ObservationSet.{name}: non-finite value at index {idx}")
    bad = ~np.isfinite(o.xy_m)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ObservationError(
            f"ObservationSet.xy_m: non-finite value at index {idx} (run, row, axis: run {idx[0]}, {_row_where(o, idx[1])})"
        )


def _check_limits(o: ObservationSet):
    for name in ("t_s", "r_sc_i_m", "landmark_g_m", "xy_m", "v_sc_i_m_s"):
        a = getattr(o, name)
        if a is None:
            continue
        a = np.asarray(a, float)
        limit, unit, what = LIMITS[name]
        big = np.abs(a) > limit
        if big.any():
            idx = tuple(int(i) for i in np.argwhere(big)[0])
            where = f" ({_row_where(o, idx[1])})" if name == "xy_m" else ""
            raise ObservationError(
                f"ObservationSet.{name}: value {float(a[idx]):.6g} {unit} at index {idx}{where} is beyond ±{limit:g} {unit} ({what})"
            )


def _check_quaternion_norms(o: ObservationSet):
    norms = np.linalg.norm(o.q_is, axis=-1)
    if np.any(np.abs(norms - 1) > 1e-6):
        idx = tuple(int(i) for i in np.argwhere(np.abs(norms - 1) > 1e-6)[0])
        raise ObservationError(f"ObservationSet.q_is: quaternion at index {idx} has norm {norms[idx]:.9g}, expected 1")


def _check_landmark_ids(o: ObservationSet):
    if len(set(o.landmark_ids.tolist())) != o.landmark_ids.size:
        ids, counts = np.unique(o.landmark_ids, return_counts=True)
        raise ObservationError(f"ObservationSet.landmark_ids: duplicate id {str(ids[counts > 1][0])!r}")


def _check_rotations(o: ObservationSet):
    for name, a in (("C_SK_nominal", o.C_SK_nominal[None]), ("C_GI", o.C_GI)):
        bad = rotation_problem(a)
        if bad is not None:
            k, what = bad
            where = "" if name == "C_SK_nominal" else f" at image {k}"
            raise ObservationError(f"ObservationSet.{name}{where}: {what}")


def _check_velocity(o: ObservationSet):
    if o.v_sc_i_m_s is None:
        return
    r, n = o.runs, o.n_images
    object.__setattr__(o, "v_sc_i_m_s", np.asarray(o.v_sc_i_m_s, float))
    if o.v_sc_i_m_s.shape != (r, n, 3):
        raise _shape_error("v_sc_i_m_s", (r, n, 3), o.v_sc_i_m_s.shape)
    if not np.all(np.isfinite(o.v_sc_i_m_s)):
        idx = tuple(int(i) for i in np.argwhere(~np.isfinite(o.v_sc_i_m_s))[0])
        raise ObservationError(f"ObservationSet.v_sc_i_m_s: non-finite value at index {idx}")


#: a row's own σ (m): as ``DisturbanceModel.sigma_pixel_m``, > 0 (a weight 1/σ² stays finite) and ≤ 1 m
SIGMA_XY_LIMITS_M = (1e-100, 1.0)


def _check_sigma_xy(o: ObservationSet):
    """``sigma_xy_m`` (K, 2): on each row both NaN (the noise model's σ) or both finite in ``SIGMA_XY_LIMITS_M``."""
    if o.sigma_xy_m is None:
        return
    s = np.asarray(o.sigma_xy_m, dtype=float)
    if s.shape != (o.n_observations, 2):
        raise _shape_error("sigma_xy_m", (o.n_observations, 2), s.shape)
    lo, hi = SIGMA_XY_LIMITS_M
    nan = np.isnan(s)
    bad = (nan[:, 0] != nan[:, 1]) | np.any(~nan & ~((s >= lo) & (s <= hi)), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise ObservationError(
            f"ObservationSet.sigma_xy_m: row {k} ({_row_where(o, k)}) has σ {s[k].tolist()} m; a row's own σ must be "
            f"in [{lo:g}, {hi:g}] m on both axes, or NaN on both (the noise model's pixel σ)"
        )
    object.__setattr__(o, "sigma_xy_m", s)


def _check_noise(o: ObservationSet):
    if o.noise is not None:
        object.__setattr__(o, "noise", normalize_noise(o.noise, "ObservationSet.noise", ObservationError))


def _check_camera(o: ObservationSet):
    if o.camera is None:
        return
    from orbits.camera import CameraCalibration

    if not isinstance(o.camera, CameraCalibration):
        raise ObservationError(
            f"ObservationSet.camera must be an orbits.camera.CameraCalibration or None, got {type(o.camera).__name__}"
        )
    if not np.isclose(o.camera.focal_length_m, o.focal_length_m, rtol=1e-9, atol=0):
        raise ObservationError(
            f"ObservationSet.camera.focal_length_m = {o.camera.focal_length_m!r} differs from focal_length_m = {o.focal_length_m!r}"
        )


def _check_fov(o: ObservationSet):
    if o.fov_deg is not None and not (isinstance(o.fov_deg, (int, float, np.number)) and 0 < o.fov_deg < 180):
        raise ObservationError(f"ObservationSet.fov_deg must be a number in (0, 180) or None, got {o.fov_deg!r}")


def _check_geometry(o: ObservationSet):
    if not o.check_geometry:
        return
    bad = geometry_problem(
        o.q_is,
        o.r_sc_i_m,
        o.C_GI,
        o.landmark_g_m,
        o.C_SK_nominal,
        o.image_index,
        o.target_index,
        o.xy_m,
        o.focal_length_m,
        o.fov_deg,
        star_directions_i=_catalogue_directions(o),
    )
    if bad is not None:
        raise ObservationError(
            f"ObservationSet: {bad.describe(o.landmark_ids)} (index run {bad.run}, image {bad.image}, landmark {bad.landmark}); "
            "a convention slip? boresight.observations.doctor.check names the usual ones"
        )


#: the checks ``ObservationSet`` runs in this order; the first that fails raises (so the order is
#: part of the behaviour: shapes before values, values before geometry).
def _check_landmark_sight(o: ObservationSet):
    if o.landmark_sight not in LANDMARK_SIGHTS:
        raise ObservationError(
            f"ObservationSet.landmark_sight must be one of {', '.join(repr(k) for k in LANDMARK_SIGHTS)}, got {o.landmark_sight!r}"
        )


_CHECKS = (
    _check_landmark_sight,
    _coerce,
    _check_shapes,
    _check_rows,
    _check_samples,
    _check_stars,
    _check_focal_length,
    _check_finite,
    _check_limits,
    _check_quaternion_norms,
    _check_landmark_ids,
    _check_rotations,
    _check_velocity,
    _check_sigma_xy,
    _check_noise,
    _check_camera,
    _check_fov,
    _check_geometry,
)


def _validate(o: ObservationSet):
    for check in _CHECKS:
        check(o)


# ---------------------------------------------------------------------------- shared checks
# One implementation for the in-memory ObservationSet and the file reader (io_ecsv), so a file
# and the same data built in memory are accepted or refused alike.


def rotation_problem(C, atol: float = 1e-9):
    """First matrix of a stack (K, 3, 3) that is not a proper rotation: ``(k, description)`` or None.

    Orthogonality (C Cᵀ = I to ``atol``) *and* det C = +1: a reflection (a negated or swapped row)
    is orthogonal but turns θ into nonsense.
    """
    C = np.asarray(C, float)
    if C.ndim != 3 or C.shape[1:] != (3, 3):
        return 0, f"expected 3×3 matrices, got shape {C.shape[1:]}"
    if not np.all(np.isfinite(C)):
        k = int(np.argmax(~np.all(np.isfinite(C), axis=(1, 2))))
        return k, "not a rotation matrix (non-finite entries)"
    with np.errstate(over="ignore", invalid="ignore"):  # 1e308 entries: C Cᵀ overflows → inf → refused below
        orth = np.abs(C @ np.swapaxes(C, -1, -2) - np.eye(3)).max(axis=(1, 2))
    bad = ~(orth <= atol)
    if np.any(bad):
        k = int(np.argmax(bad))
        return k, f"not a rotation matrix (|C Cᵀ − I| = {orth[k]:.3g})"
    det = np.linalg.det(C)
    if np.any(det < 0):
        k = int(np.argmax(det < 0))
        return k, f"a reflection, not a rotation (det = {det[k]:.9g}; a proper rotation has det = +1)"
    return None


@dataclass(frozen=True)
class GeometryProblem:
    """The first implausible observation found by ``geometry_problem``."""

    kind: str  # "behind" | "outside"
    run: int
    image: int
    landmark: int
    axis: int  # 0/1 for "outside" (x/y), -1 for "behind"
    value: float  # camera-frame z (m) or the image coordinate (m)
    limit: float  # 0 or the allowed half-width (m)
    fov_deg: float | None = None
    row: int = -1  # the row (observation) index

    def describe(self, landmark_ids) -> str:
        lm = str(np.asarray(landmark_ids)[self.landmark])
        if self.kind == "behind":
            return f"landmark {lm!r} in image {self.image} is behind the camera (camera-frame z = {self.value:.6g} m ≥ 0)"
        return (
            f"landmark {lm!r} in image {self.image} is outside the field of view ({'xy'[self.axis]} = {self.value:.6g} m, "
            f"half-width {self.limit / FIELD_MARGIN:.6g} m for fov_deg = {self.fov_deg}, {FIELD_MARGIN - 1:.0%} margin)"
        )


def field_half_width_m(focal_length_m: float, fov_deg: float) -> float:
    """Half-width of the square field on the focal plane, F tan(fov/2)."""
    return float(focal_length_m) * np.tan(np.radians(fov_deg) / 2)


def geometry_problem(
    q_is,
    r_sc_i_m,
    C_GI,
    landmark_g_m,
    C_SK_nominal,
    image_index,
    target_index,
    xy_m,
    focal_length_m,
    fov_deg=None,
    star_directions_i=None,
):
    """The first observation (row) that is behind the camera or outside the field, or None.

    Rows: ``image_index``, ``target_index`` (K,) and ``xy_m`` (R, K, 2). Behind: with the nominal
    mount and θ = 0 its camera-frame z component (boresight along −z_K) is ≥ 0 — θ is a small
    angle, so no real observation can be there. ``star_directions_i`` (T, 3): the inertial unit
    direction of each star target (NaN for a landmark; the catalogue direction is enough here:
    the apparent-place terms are arcseconds), whose rows are tested on it instead of a position. Outside (only with ``fov_deg``): a measured
    coordinate beyond ``FIELD_MARGIN`` × F tan(fov/2). Memory O(R K): no images × targets array.
    """
    # only the camera z axis is needed: w = (C_SK A)₃ in I, wg = C_GIᵀ w in G, sz = wg·L − w·r per
    # image, gathered to rows (3×3 batched matmuls are slow for many runs)
    A = dcm_from_quat(q_is)
    c = np.asarray(C_SK_nominal, float)[2]
    w = c[0] * A[..., 0, :] + c[1] * A[..., 1, :] + c[2] * A[..., 2, :]  # (R, N, 3)
    G = np.asarray(C_GI, float)
    wg = w[..., 0:1] * G[:, 0, :] + w[..., 1:2] * G[:, 1, :] + w[..., 2:3] * G[:, 2, :]  # (R, N, 3)
    ii = np.asarray(image_index)
    tt = np.asarray(target_index)
    L = np.asarray(landmark_g_m, float)[:, tt]  # (R, K, 3)
    wk = wg[:, ii]  # (R, K, 3)
    sz = wk[..., 0] * L[..., 0] + wk[..., 1] * L[..., 1] + wk[..., 2] * L[..., 2]
    sz -= np.sum(w * r_sc_i_m, axis=-1)[:, ii]
    if star_directions_i is not None:
        u = np.asarray(star_directions_i, float)[tt]  # (K, 3)
        star = np.isfinite(u[:, 0])
        if star.any():
            sz[:, star] = np.einsum("rkj,kj->rk", w[:, ii[star]], u[star])
    behind = ~(sz < 0)
    if behind.any():
        rr, kk = (int(i) for i in np.argwhere(behind)[0])
        return GeometryProblem("behind", rr, int(ii[kk]), int(tt[kk]), -1, float(sz[rr, kk]), 0.0, row=kk)
    if fov_deg is not None:
        limit = FIELD_MARGIN * field_half_width_m(focal_length_m, fov_deg)
        xy = np.asarray(xy_m)
        out = ~(np.abs(xy) <= limit)
        if out.any():
            rr, kk, aa = (int(i) for i in np.argwhere(out)[0])
            return GeometryProblem("outside", rr, int(ii[kk]), int(tt[kk]), aa, float(xy[rr, kk, aa]), limit, fov_deg, row=kk)
    return None


def from_measurements(meas, noise: dict | None = None, detector_edge: bool = False) -> ObservationSet:
    """Wrap ``orbits.measurements.Measurements`` (the simulator's output) as an ObservationSet.

    The simulator decides visibility from the nominal geometry (θ = 0); with a large true θ a
    measured point can land beyond the field the set's ``fov_deg`` describes, which the shared
    geometry check refuses. DECISION: with ``detector_edge=True`` (``boresight.simulate``, what
    ``boresight simulate`` writes) such an observation is dropped from every run of the batch, as
    a real detector records only what lands on it (the rows are shared by the runs), so a
    simulated file always passes its own reader. When a dropped row is on the detector in some other run of the
    batch (the runs coupled), a ``UserWarning`` says how many: never a silently thinner campaign. With ``detector_edge=False`` (Monte Carlo
    studies of idealised set-ups, where dropping an observation would couple the runs of a
    chunk) the observations are kept and the set carries ``fov_deg = None`` (no field check).
    """
    cam = meas.camera
    xy = meas.xy_m
    truth = dict(meas.truth)
    img, tgt = np.asarray(meas.image_index), np.asarray(meas.target_index)
    sigma_xy = getattr(meas, "sigma_xy_m", None)  # the simulator's per-row centroid σ (star rows by magnitude)
    fov = cam.fov_deg
    if fov is not None:
        limit = FIELD_MARGIN * field_half_width_m(cam.focal_length_m, fov)
        beyond = np.any(~(np.abs(xy) <= limit), axis=(0, 2))  # (K,) a row beyond the field in some run
        if np.any(beyond) and detector_edge:
            # rows inside the field in some run, dropped only because another run of the batch left it:
            # said, never silent (a 5 000-run kiev2012-sensitivity batch kept 1 of its 4 landmarks)
            coupled = beyond & np.any(np.all(np.abs(xy) <= limit, axis=2), axis=0)
            if xy.shape[0] > 1 and np.any(coupled):
                import warnings

                warnings.warn(
                    f"simulate: {int(beyond.sum())} of {beyond.size} observations land beyond the detector in at least "
                    f"one of the {xy.shape[0]} runs and are dropped from every run ({int(coupled.sum())} of them are on "
                    "the detector in other runs; a set's rows are shared by its runs). Simulate fewer runs per call "
                    "for a file, or run a Monte Carlo study (boresight.montecarlo_study), which keeps every nominal row.",
                    UserWarning,
                    stacklevel=3,
                )
            keep = np.flatnonzero(~beyond)
            xy, img, tgt = xy[:, keep], img[keep], tgt[keep]
            sigma_xy = None if sigma_xy is None else np.asarray(sigma_xy)[keep]
            truth = {k: (np.asarray(v)[:, keep] if k in _ROW_TRUTH else v) for k, v in truth.items()}
        elif np.any(beyond):
            fov = None
    calibration = getattr(cam, "calibration", None)
    stars = getattr(meas, "stars", None)
    kind = None
    if stars is not None:  # star targets: those at infinity (NaN position), in target order
        kind = np.where(np.isnan(np.asarray(meas.landmark_g_m)[0, :, 0]), "star", "landmark")
    obs = ObservationSet(
        target_kind=kind,
        stars=stars,
        t_s=meas.t_s,
        pass_index=meas.pass_index,
        q_is=meas.q_is,
        r_sc_i_m=meas.r_sc_i_m,
        C_GI=meas.C_GI,
        landmark_ids=meas.landmark_ids.astype(str),
        landmark_g_m=meas.landmark_g_m,
        image_index=img,
        target_index=tgt,
        xy_m=xy,
        focal_length_m=cam.focal_length_m,
        C_SK_nominal=meas.C_SK_nominal,
        fov_deg=fov,
        pixel_pitch_m=cam.pixel_pitch_m,
        epoch_utc=meas.epoch_utc,
        frames=dict(meas.frames),
        truth=truth,
        v_sc_i_m_s=getattr(meas, "v_sc_i_m_s", None),
        noise=noise,
        camera=calibration() if callable(calibration) else calibration,
        sigma_xy_m=sigma_xy,
        landmark_sight=getattr(meas, "landmark_sight", "geometric"),
    )
    if stars is not None and "r_sc_i_m" in truth:
        # DECISION: a simulated set's star directions from the true positions, not run 0's reported
        # ones: a position enters a star's direction only through its parallax (5 m of GNSS error at
        # ≥ 1 pc: < 1e-16 rad), and so a Monte Carlo run's estimate does not depend on which run
        # comes first in its chunk (bit-identical studies for any chunking: tests/studies/test_star_studies.py)
        _set_star_position(obs, np.asarray(truth["r_sc_i_m"], float))
    return obs


def _set_star_position(o: Any, r_i_m: Any) -> Any:
    """``o`` with the images' positions (N, 3) its star directions are computed from (None: run 0's);
    ``run``, ``images``, ``rows`` and ``targets`` keep them (``from_measurements``)."""
    if r_i_m is not None:
        o.__dict__["_star_position_i_m"] = r_i_m
    return o
