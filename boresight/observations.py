"""``ObservationSet``: the one data model shared by flight data and simulations.

Arrays carry a leading run axis R (1 for flight data), N images and M landmarks:

=================  ===============  =====================================================
field              shape            meaning (SI units)
=================  ===============  =====================================================
``t_s``            (N,)             image time, seconds from ``epoch`` (UTC)
``pass_index``     (N,)             which pass of a campaign the image belongs to
``q_is``           (R, N, 4)        star-tracker attitude quaternion, inertial → star tracker,
                                    **scalar last** ``[q1, q2, q3, q4]``
``r_sc_i_m``       (R, N, 3)        GNSS spacecraft position in the inertial frame (m)
``C_GI``           (N, 3, 3)        Earth-fixed → inertial DCM at each image
``landmark_ids``   (M,)             landmark identifiers (str)
``landmark_g_m``   (R, M, 3)        catalogue landmark position, Earth-fixed frame (m)
``xy_m``           (R, N, M, 2)     measured image coordinates on the focal plane (m)
``mask``           (N, M)           True where landmark m was observed in image n
=================  ===============  =====================================================

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
>>> obs.runs, obs.n_images, obs.n_landmarks
(2, 10, 4)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from orbits.errors import BoresightError
from orbits.rotations import dcm_from_quat

__all__ = ["ObservationSet", "ObservationError", "ObservationFileError", "from_measurements", "FORMAT_NAME", "FORMAT_VERSION"]

FORMAT_NAME = "boresight-observations"
FORMAT_VERSION = "1.0"


class ObservationError(BoresightError, ValueError):
    """An ObservationSet is inconsistent; the message names the field and the value."""


class ObservationFileError(ObservationError):
    """An observation file is malformed; the message names the column and the row."""


@dataclass(frozen=True)
class ObservationSet:
    t_s: np.ndarray
    pass_index: np.ndarray
    q_is: np.ndarray
    r_sc_i_m: np.ndarray
    C_GI: np.ndarray
    landmark_ids: np.ndarray
    landmark_g_m: np.ndarray
    xy_m: np.ndarray
    mask: np.ndarray
    focal_length_m: float
    C_SK_nominal: np.ndarray = field(default_factory=lambda: np.eye(3))
    fov_deg: float | None = None
    pixel_pitch_m: float | None = None
    epoch_utc: str = "2000-01-01T12:00:00"
    frames: dict = field(default_factory=lambda: {"inertial": "GCRS", "earth_fixed": "ITRS"})
    truth: dict | None = None

    def __post_init__(self):
        _validate(self)

    # ------------------------------------------------------------------ sizes
    @property
    def runs(self) -> int:
        return self.xy_m.shape[0]

    @property
    def n_images(self) -> int:
        return self.t_s.shape[0]

    @property
    def n_landmarks(self) -> int:
        return self.landmark_ids.shape[0]

    @property
    def n_observations(self) -> int:
        """Landmark observations per run."""
        return int(self.mask.sum())

    # ------------------------------------------------------------------ derived arrays
    def attitude_st(self) -> np.ndarray:
        """Measured star-tracker attitude matrices A = C_IS, (R, N, 3, 3)."""
        return dcm_from_quat(self.q_is)

    def landmarks_i_m(self) -> np.ndarray:
        """Catalogue landmarks in the inertial frame at each image, (R, N, M, 3)."""
        return np.einsum("nij,rmj->rnmi", self.C_GI, self.landmark_g_m)

    def lines_of_sight_i(self) -> np.ndarray:
        """Unit vectors GNSS position → catalogue landmark in I, (R, N, M, 3) (Kiev 2012 eq 29's e_iI)."""
        d = self.landmarks_i_m() - self.r_sc_i_m[:, :, None, :]
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def image_directions(self) -> np.ndarray:
        """Measured unit directions e_K = s/|s|, s = [x, y, −F], (R, N, M, 3) (Kiev 2012 eq 29)."""
        s = np.concatenate([self.xy_m, np.full(self.xy_m.shape[:-1] + (1,), -self.focal_length_m)], axis=-1)
        return s / np.linalg.norm(s, axis=-1, keepdims=True)

    def nominal_camera_attitude(self) -> np.ndarray:
        """C_IK at θ = 0 from the star tracker: C_SK,nominal A, (R, N, 3, 3)."""
        return self.C_SK_nominal @ self.attitude_st()

    # ------------------------------------------------------------------ slicing
    def run(self, k) -> "ObservationSet":
        """The run(s) ``k`` (an int or a slice) as an ObservationSet with a run axis."""
        sl = slice(k, k + 1) if isinstance(k, (int, np.integer)) else k
        truth = None
        if self.truth is not None:
            truth = {key: (v[sl] if _has_run_axis(key, v, self.runs) else v) for key, v in self.truth.items()}
        return replace(
            self, q_is=self.q_is[sl], r_sc_i_m=self.r_sc_i_m[sl], landmark_g_m=self.landmark_g_m[sl], xy_m=self.xy_m[sl], truth=truth
        )

    def images(self, sel) -> "ObservationSet":
        """A subset of images (index array, slice or boolean mask over N)."""
        idx = np.arange(self.n_images)[sel]
        truth = None
        if self.truth is not None:
            truth = dict(self.truth)
            for key in ("delta_rad", "gnss_error_m"):
                if key in truth:
                    truth[key] = truth[key][:, idx]
            if "xy_true_m" in truth:
                truth["xy_true_m"] = truth["xy_true_m"][:, idx]
            for key in ("C_IS", "r_sc_i_m"):
                if key in truth:
                    truth[key] = truth[key][idx]
        return replace(
            self,
            t_s=self.t_s[idx],
            pass_index=self.pass_index[idx],
            q_is=self.q_is[:, idx],
            r_sc_i_m=self.r_sc_i_m[:, idx],
            C_GI=self.C_GI[idx],
            xy_m=self.xy_m[:, idx],
            mask=self.mask[idx],
            truth=truth,
        )

    # ------------------------------------------------------------------ files
    def write(self, path, overwrite: bool = False) -> Path:
        """Write as ECSV (``docs/data-format.md``)."""
        from .io_ecsv import write_ecsv

        return write_ecsv(self, path, overwrite=overwrite)

    @classmethod
    def read(cls, path) -> "ObservationSet":
        """Read and validate an ECSV observation file (``docs/data-format.md``)."""
        from .io_ecsv import read_ecsv

        return read_ecsv(path)


def _has_run_axis(key, v, runs):
    return key in ("theta_rad", "delta_rad", "gnss_error_m", "catalogue_error_m", "xy_true_m") and np.ndim(v) >= 1 and np.shape(v)[0] == runs


def _shape_error(name, expected, got):
    return ObservationError(f"ObservationSet.{name}: expected shape {expected}, got {tuple(got)}")


def _validate(o: ObservationSet):
    for name in ("t_s", "pass_index", "q_is", "r_sc_i_m", "C_GI", "landmark_ids", "landmark_g_m", "xy_m", "mask", "C_SK_nominal"):
        object.__setattr__(o, name, np.asarray(getattr(o, name)))
    object.__setattr__(o, "mask", o.mask.astype(bool))
    if o.t_s.ndim != 1 or o.t_s.size == 0:
        raise _shape_error("t_s", "(N,) with N ≥ 1", o.t_s.shape)
    n = o.t_s.size
    if o.xy_m.ndim != 4 or o.xy_m.shape[1] != n or o.xy_m.shape[3] != 2:
        raise _shape_error("xy_m", f"(R, {n}, M, 2)", o.xy_m.shape)
    r, _, m, _ = o.xy_m.shape
    expected = {
        "pass_index": (n,),
        "q_is": (r, n, 4),
        "r_sc_i_m": (r, n, 3),
        "C_GI": (n, 3, 3),
        "landmark_ids": (m,),
        "landmark_g_m": (r, m, 3),
        "mask": (n, m),
        "C_SK_nominal": (3, 3),
    }
    for name, shape in expected.items():
        if getattr(o, name).shape != shape:
            raise _shape_error(name, shape, getattr(o, name).shape)
    if not (np.isfinite(o.focal_length_m) and o.focal_length_m > 0):
        raise ObservationError(f"ObservationSet.focal_length_m must be > 0, got {o.focal_length_m!r}")
    for name in ("t_s", "q_is", "r_sc_i_m", "C_GI", "landmark_g_m", "C_SK_nominal"):
        a = getattr(o, name)
        if not np.all(np.isfinite(a)):
            idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise ObservationError(f"ObservationSet.{name}: non-finite value at index {idx}")
    bad = ~np.isfinite(o.xy_m) & o.mask[None, :, :, None]
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ObservationError(f"ObservationSet.xy_m: non-finite value at index {idx} (run, image, landmark, axis)")
    norms = np.linalg.norm(o.q_is, axis=-1)
    if np.any(np.abs(norms - 1) > 1e-6):
        idx = tuple(int(i) for i in np.argwhere(np.abs(norms - 1) > 1e-6)[0])
        raise ObservationError(f"ObservationSet.q_is: quaternion at index {idx} has norm {norms[idx]:.9g}, expected 1")
    if len(set(o.landmark_ids.tolist())) != m:
        ids, counts = np.unique(o.landmark_ids, return_counts=True)
        raise ObservationError(f"ObservationSet.landmark_ids: duplicate id {str(ids[counts > 1][0])!r}")


def from_measurements(meas) -> ObservationSet:
    """Wrap ``orbits.simulate.Measurements`` (the simulator's output) as an ObservationSet."""
    cam = meas.camera
    return ObservationSet(
        t_s=meas.t_s,
        pass_index=meas.pass_index,
        q_is=meas.q_is,
        r_sc_i_m=meas.r_sc_i_m,
        C_GI=meas.C_GI,
        landmark_ids=meas.landmark_ids.astype(str),
        landmark_g_m=meas.landmark_g_m,
        xy_m=meas.xy_m,
        mask=meas.mask,
        focal_length_m=cam.focal_length_m,
        C_SK_nominal=meas.C_SK_nominal,
        fov_deg=cam.fov_deg,
        pixel_pitch_m=cam.pixel_pitch_m,
        epoch_utc=meas.epoch_utc,
        frames=dict(meas.frames),
        truth=dict(meas.truth),
    )
