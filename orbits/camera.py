"""Pinhole camera: projection (Kiev 2012 eqs 3/20), back-projection (eqs 2/14), visibility; the pushbroom line sensor.

Camera frame K: boresight along −z_K; a landmark imaged at (x, y) on the focal plane lies
along s = [x, y, −F] (Kiev 2012 eq 3 and the unit-vector section). Image coordinates are
metres on the focal plane; a pixel pitch converts to pixels for display only.

A pushbroom line sensor (``LineSensor``, its chips ``LineChip`` and line datation
``LinearLineDatation`` / ``TabulatedLineDatation``, ``docs/pushbroom.md``) is the same
projection with one detector line on the focal plane: its pixels look along
``direction_from_image`` of their focal-plane points and a direction is imaged by ``project``.

Example
-------
>>> import numpy as np
>>> cam = Camera(focal_length_m=2.2, fov_deg=3.4)
>>> xy = project(np.array([0.01, -0.02, -1.0]), cam.focal_length_m)
>>> [round(float(c), 6) for c in xy]
[0.022, -0.044]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import InputValueError, LocationError

__all__ = [
    "Camera",
    "CalibratedCamera",
    "camera_from_keys",
    "DETECTOR_KEYS",
    "CameraCalibration",
    "render_image_points",
    "UNDISTORT_TOL_PX",
    "project",
    "direction_from_image",
    "back_project_to_plane",
    "back_project_to_sphere",
    "LineChip",
    "LineSensor",
    "LinearLineDatation",
    "TabulatedLineDatation",
]


@dataclass(frozen=True)
class Camera:
    """Focal length (m), full square field of view (deg), optional pixel pitch (m).

    A pinhole on the ideal focal plane; ``CalibratedCamera`` adds a detector calibration.
    """

    focal_length_m: float
    fov_deg: float
    pixel_pitch_m: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.focal_length_m) and self.focal_length_m > 0):
            raise InputValueError(f"Camera.focal_length_m must be a positive number, got {self.focal_length_m!r}")
        if not (np.isfinite(self.fov_deg) and 0 < self.fov_deg < 180):
            raise InputValueError(f"Camera.fov_deg must be in (0, 180), got {self.fov_deg!r}")
        if self.pixel_pitch_m is not None and not self.pixel_pitch_m > 0:
            raise InputValueError(f"Camera.pixel_pitch_m must be > 0 or None, got {self.pixel_pitch_m!r}")

    def calibration(self) -> "CameraCalibration | None":
        """The detector calibration (None for a plain pinhole camera)."""
        return None

    @property
    def half_width_m(self) -> float:
        """Half-width of the square field on the focal plane, F tan(FOV/2)."""
        result: float = self.focal_length_m * np.tan(np.radians(self.fov_deg) / 2)
        return result

    def visible(self, s_k: Any) -> np.ndarray:
        """In front (s_z < 0) and inside the square field, ``(..., 3) -> (...)`` bool."""
        s = np.asarray(s_k, dtype=float)
        front = s[..., 2] < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = project(s, self.focal_length_m)
        inside = np.all(np.abs(xy) <= self.half_width_m, axis=-1)
        result: np.ndarray = front & inside
        return result


@dataclass(frozen=True)
class CalibratedCamera(Camera):
    """A camera with a calibrated detector (the scenario's ``[camera]`` keys, see
    ``CameraCalibration``): ``principal_point_px`` [c_u, c_v], ``u_axis``/``v_axis`` (camera-frame
    axes along which the pixel coordinates increase) and OpenCV's distortion ``k1 k2 k3 p1 p2``;
    the focal length in pixels is ``focal_length_m / pixel_pitch_m``. The simulator renders
    through the detector (``render_image_points``) and the observation set carries the
    calibration, so ``simulate`` can write ``u v`` pixel columns.
    """

    principal_point_px: tuple[Any, ...] | None = None
    u_axis: str | None = None
    v_axis: str | None = None
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if isinstance(self.principal_point_px, list):
            object.__setattr__(self, "principal_point_px", tuple(self.principal_point_px))
        object.__setattr__(self, "_calibration", self._make_calibration())

    def calibration(self) -> "CameraCalibration":
        result: CameraCalibration = self.__dict__["_calibration"]  # set in __post_init__
        return result

    def _make_calibration(self) -> "CameraCalibration":
        if self.principal_point_px is None:
            given = [k for k in ("u_axis", "v_axis", *_DISTORTION) if getattr(self, k) not in (None, 0.0, 0)]
            raise InputValueError(
                f"camera: {given} need principal_point_px (and pixel_pitch_m, u_axis, v_axis): a calibrated detector"
            )
        if self.pixel_pitch_m is None:
            raise InputValueError(
                "camera: principal_point_px needs pixel_pitch_m (the focal length in pixels is focal_length_m / pixel_pitch_m)"
            )
        for key in ("u_axis", "v_axis"):
            if getattr(self, key) is None:
                raise InputValueError(
                    f"camera: principal_point_px needs {key} (the camera-frame axis, one of {list(_AXES)}, along which {key[0]} increases)"
                )
        m = {
            "principal_point_px": list(self.principal_point_px),
            "pixel_pitch_m": self.pixel_pitch_m,
            "u_axis": self.u_axis,
            "v_axis": self.v_axis,
            **{k: getattr(self, k) for k in _DISTORTION},
        }
        return CameraCalibration.from_mapping(m, where="camera", focal_length_m=self.focal_length_m)


DETECTOR_KEYS = ("principal_point_px", "u_axis", "v_axis", "k1", "k2", "k3", "p1", "p2")


def camera_from_keys(**keys: Any) -> Camera:
    """A ``Camera``, or a ``CalibratedCamera`` when any detector key is given (scenario ``[camera]``)."""
    cls = CalibratedCamera if any(k in keys for k in DETECTOR_KEYS) else Camera
    return cls(**keys)


def project(s_k: Any, focal_length_m: float) -> np.ndarray:
    """Collinearity equations (Kiev 2012 eq 3): (x, y) = −F (s_x, s_y) / s_z, ``(..., 3) -> (..., 2)``.

    ``s_k`` is the camera-frame vector from the projection centre to the landmark,
    ``C_IK (r_M − r_I)`` in eq 3's notation.
    """
    s = np.asarray(s_k, dtype=float)
    result: np.ndarray = -focal_length_m * s[..., :2] / s[..., 2:3]
    return result


def direction_from_image(xy_m: Any, focal_length_m: float) -> np.ndarray:
    """s = [x, y, −F] for image points ``(..., 2) -> (..., 3)``."""
    xy = np.asarray(xy_m, dtype=float)
    return np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -float(focal_length_m))], axis=-1)


def back_project_to_plane(xy_m: Any, C_AK: Any, r_center_a_m: Any, plane_z_m: Any, focal_length_m: float) -> np.ndarray:
    """Ground point on the plane z_A = ``plane_z_m`` seen at image point (x, y) (Kiev 2012 eq 2).

    ``C_AK`` maps frame A (e.g. topocentric T) to the camera; ``r_center_a_m`` is the projection
    centre in A. Eq 2: X_M = X_I + (Z_M − Z_I)(c11 x + c21 y − c31 F)/(c13 x + c23 y − c33 F), i.e.
    the ray ``C_AKᵀ s`` scaled to reach the plane. Shapes broadcast; returns ``(..., 3)``.
    """
    d = np.einsum("...ji,...j->...i", np.asarray(C_AK, float), direction_from_image(xy_m, focal_length_m))
    r0 = np.asarray(r_center_a_m, dtype=float)
    lam = (np.asarray(plane_z_m, float) - r0[..., 2]) / d[..., 2]
    result: np.ndarray = r0 + lam[..., None] * d
    return result


def back_project_to_sphere(xy_m: Any, C_AK: Any, r_center_a_m: Any, radius_m: Any, focal_length_m: float) -> np.ndarray:
    """Nearest intersection of the image ray with a sphere ``|r|`` = ``radius_m`` centred at A's origin.

    The spherical-Earth counterpart of eq 2. Raises ``LocationError`` (a ``ValueError``) naming the first image point whose ray misses the sphere.
    """
    d = np.einsum("...ji,...j->...i", np.asarray(C_AK, float), direction_from_image(xy_m, focal_length_m))
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    r0 = np.asarray(r_center_a_m, dtype=float)
    b = np.sum(r0 * d, axis=-1)
    c = np.sum(r0 * r0, axis=-1) - np.asarray(radius_m, float) ** 2
    disc = b * b - c
    lam = -b - np.sqrt(np.maximum(disc, 0.0))
    miss = (disc < 0) | (lam <= 0)  # no intersection, or only behind the camera
    if np.any(miss):
        idx = np.argwhere(np.atleast_1d(miss))[0]
        raise LocationError(f"image ray at index {tuple(int(i) for i in idx)} misses the sphere of radius {radius_m} m")
    result: np.ndarray = r0 + lam[..., None] * d
    return result


# ---------------------------------------------------------------------------- pixels and distortion

#: detector axis name -> unit vector in (x_K, y_K)
_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}
_DISTORTION = ("k1", "k2", "k3", "p1", "p2")
#: inverse map: Newton iterations stop when the re-distorted point is within this of the pixel
UNDISTORT_TOL_PX = 1e-9
UNDISTORT_MAX_ITER = 50


#: the keys of a camera block / ``[camera]`` table, in the order their values are checked (a fixed
#: order: with several bad values the first named is always the same one)
_MAPPING_KEYS = (
    "focal_length_m",
    "pixel_pitch_m",
    "focal_length_px",
    "principal_point_px",
    "u_axis",
    "v_axis",
    "camera_matrix",
    "dist_coeffs",
    "fov_deg",
    *_DISTORTION,
)


def _numeric(v: Any) -> bool:
    """A finite number, or a non-empty (nested) list of them; not a bool."""
    if isinstance(v, (list, tuple)):
        return len(v) > 0 and all(_numeric(x) for x in v)
    return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating)) and bool(np.isfinite(v))


def _mapping_focal_length(m: dict[str, Any], where: str, focal_length_m: float | None) -> Any:
    """Check a camera block's keys and values; its focal length in metres (the block's or the file's)."""
    known = set(_MAPPING_KEYS)
    unknown = sorted(set(m) - known)
    if unknown:
        from .errors import unknown_keys_message

        raise InputValueError(unknown_keys_message(where, unknown, known))
    for key in _MAPPING_KEYS:
        if key not in ("u_axis", "v_axis") and key in m and not _numeric(m[key]):
            raise InputValueError(f"{where}: {key} must be a finite number (or a list of them), got {m[key]!r}")
    F = m.get("focal_length_m", focal_length_m)
    if F is None:
        raise InputValueError(f"{where}: needs focal_length_m")
    if (
        focal_length_m is not None
        and "focal_length_m" in m
        and not np.isclose(m["focal_length_m"], focal_length_m, rtol=1e-9, atol=0)
    ):
        raise InputValueError(
            f"{where}: focal_length_m = {m['focal_length_m']!r} differs from the file's focal_length_m = {focal_length_m!r}"
        )
    for key in ("u_axis", "v_axis"):
        if key not in m:
            raise InputValueError(
                f"{where}: needs {key} (the camera-frame axis, one of {list(_AXES)}, along which {key[0]} increases)"
            )
    return F


def _mapping_distortion(m: dict[str, Any], where: str) -> dict[str, Any]:
    """The distortion coefficients of a named-key block: ``dist_coeffs`` or ``k1 k2 k3 p1 p2`` (default 0)."""
    if "dist_coeffs" not in m:
        return {k: m.get(k, 0.0) for k in _DISTORTION}
    if any(k in m for k in _DISTORTION):
        raise InputValueError(f"{where}: give dist_coeffs or k1 k2 k3 p1 p2, not both")
    d = np.asarray(m["dist_coeffs"], float).ravel()
    if d.size not in (4, 5):
        raise InputValueError(
            f"{where}: dist_coeffs must be OpenCV's [k1, k2, p1, p2] or [k1, k2, p1, p2, k3], got {m['dist_coeffs']!r}"
        )
    return dict(k1=d[0], k2=d[1], p1=d[2], p2=d[3], k3=d[4] if d.size == 5 else 0.0)


@dataclass(frozen=True)
class CameraCalibration:
    """A calibrated camera: pixels (u, v) ↔ ideal focal-plane coordinates (x, y) in metres.

    The model is OpenCV's pinhole + Brown–Conrady (``cv2.projectPoints``), so a calibration made
    with OpenCV is pasted as is (``from_opencv`` takes its camera matrix and distortion vector):

    * detector-normalised coordinates of an ideal focal-plane point (x, y):
      ``a = (e_u · [x, y]) / F``, ``b = (e_v · [x, y]) / F``, where e_u, e_v are the directions
      in which u and v increase, given as ``u_axis``/``v_axis`` ∈ {+x, −x, +y, −y} of the camera
      frame K (boresight −z_K). OpenCV's camera frame is then x_C = e_u, y_C = e_v, z_C = −z_K
      (the line of sight), so a K-frame direction s maps to OpenCV's point
      (e_u·s, e_v·s, −s_z);
    * distortion (OpenCV's convention and coefficient names), r² = a² + b²:
      ``a_d = a (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 a b + p2 (r² + 2 a²)``,
      ``b_d = b (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 b²) + 2 p2 a b``;
    * pixels: ``u = f_u a_d + c_u``, ``v = f_v b_d + c_v`` (focal lengths and principal point in
      pixels; f = F / pixel pitch for square pixels).

    ``pixels_to_focal_plane`` inverts this by Newton's method on (a, b) (analytic 2×2 Jacobian),
    from (a_d, b_d), until the re-distorted point is within ``UNDISTORT_TOL_PX`` = 1e-9 px of the
    pixel; a point that does not converge in ``UNDISTORT_MAX_ITER`` iterations, or lands where the
    distortion folds over (beyond ``fold_radius2``, where the radial map stops increasing, or a
    Jacobian determinant ≤ 0: outside any calibrated region), is an error naming its index.

    >>> cam = CameraCalibration(2.2, (400000.0, 400000.0), (1024.0, 1024.0), "+x", "-y", k1=-0.1)
    >>> uv = cam.focal_plane_to_pixels([[0.001, -0.002]])
    >>> [round(float(c), 3) for c in uv[0]]
    [1205.818, 1387.636]
    >>> [round(float(c), 12) for c in cam.pixels_to_focal_plane(uv)[0]]
    [0.001, -0.002]
    """

    focal_length_m: float
    focal_length_px: tuple[Any, ...]  # (f_u, f_v)
    principal_point_px: tuple[Any, ...]  # (c_u, c_v)
    u_axis: str
    v_axis: str
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    pixel_pitch_m: tuple[Any, ...] | None = None  # (along u, along v), informative

    def __post_init__(self) -> None:
        def number(name: str, v: Any, positive: bool = False) -> Any:
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float, np.integer, np.floating))
                or not np.isfinite(v)
                or (positive and v <= 0)
            ):
                raise InputValueError(
                    f"CameraCalibration.{name} must be a {'positive ' if positive else ''}finite number, got {v!r}"
                )
            return float(v)

        object.__setattr__(self, "focal_length_m", number("focal_length_m", self.focal_length_m, True))
        for name in ("focal_length_px", "principal_point_px") + (("pixel_pitch_m",) if self.pixel_pitch_m is not None else ()):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and name != "principal_point_px":
                v = (v, v)
            if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != 2:
                raise InputValueError(f"CameraCalibration.{name} must be two numbers (u, v), got {v!r}")
            object.__setattr__(
                self, name, tuple(number(f"{name}[{i}]", x, name != "principal_point_px") for i, x in enumerate(v))
            )
        for name in ("u_axis", "v_axis"):
            if getattr(self, name) not in _AXES:
                raise InputValueError(
                    f"CameraCalibration.{name} must be one of {list(_AXES)} (the camera-frame axis along which it increases), got {getattr(self, name)!r}"
                )
        if abs(np.dot(_AXES[self.u_axis], _AXES[self.v_axis])) > 0:
            raise InputValueError(
                f"CameraCalibration: u_axis = {self.u_axis!r} and v_axis = {self.v_axis!r} must be perpendicular (one along x, one along y)"
            )
        for name in _DISTORTION:
            object.__setattr__(self, name, number(name, getattr(self, name)))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_opencv(
        cls, camera_matrix: Any, dist_coeffs: Any, focal_length_m: float, u_axis: str, v_axis: str, pixel_pitch_m: Any = None
    ) -> "CameraCalibration":
        """From OpenCV's 3×3 camera matrix [[f_u, 0, c_u], [0, f_v, c_v], [0, 0, 1]] and distortion
        vector (k1, k2, p1, p2[, k3]) as ``cv2.calibrateCamera`` returns them."""
        K = np.asarray(camera_matrix, float)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 1] != 0 or np.any(K[2] != [0, 0, 1]) or K[1, 0] != 0:
            raise InputValueError(
                f"camera_matrix must be [[f_u, 0, c_u], [0, f_v, c_v], [0, 0, 1]] (no skew), got {np.asarray(camera_matrix).tolist()!r}"
            )
        d = np.asarray(dist_coeffs, float).ravel()
        if d.size not in (4, 5) or not np.all(np.isfinite(d)):
            raise InputValueError(
                f"dist_coeffs must be OpenCV's (k1, k2, p1, p2) or (k1, k2, p1, p2, k3), got {np.asarray(dist_coeffs).tolist()!r} "
                "(the rational and thin-prism terms k4..k6, s1..s4 are not supported)"
            )
        k3 = d[4] if d.size == 5 else 0.0
        return cls(
            focal_length_m,
            (K[0, 0], K[1, 1]),
            (K[0, 2], K[1, 2]),
            u_axis,
            v_axis,
            k1=d[0],
            k2=d[1],
            k3=k3,
            p1=d[2],
            p2=d[3],
            pixel_pitch_m=pixel_pitch_m,
        )

    @classmethod
    def from_mapping(cls, m: dict[str, Any], where: str = "camera", focal_length_m: float | None = None) -> "CameraCalibration":
        """See ``_from_mapping``; every problem is an ``InputValueError`` (a ``ValueError``) naming ``where`` and the key."""
        if not isinstance(m, dict):
            raise InputValueError(f"{where} must be a mapping of calibration keys, got {m!r}")
        try:
            return cls._from_mapping(m, where, focal_length_m)
        except (TypeError, ValueError, OverflowError) as exc:
            msg = str(exc)
            raise InputValueError(msg if msg.startswith(where) else f"{where}: {msg}") from None

    @classmethod
    def _from_mapping(cls, m: dict[str, Any], where: str, focal_length_m: float | None) -> "CameraCalibration":
        """From the observation file's ``camera`` block / the scenario's ``[camera]`` keys.

        Keys: ``u_axis``, ``v_axis`` (required); the principal point as ``principal_point_px``
        [c_u, c_v]; the focal length in pixels as ``focal_length_px`` (one number or [f_u, f_v]) or
        from ``focal_length_m`` / ``pixel_pitch_m`` (one number or [along u, along v]) — both
        given must agree to 1e-6; or OpenCV's ``camera_matrix`` in place of the two; distortion
        ``k1 k2 k3 p1 p2`` (default 0) or OpenCV's ``dist_coeffs`` [k1, k2, p1, p2(, k3)].
        ``focal_length_m`` is the file's (its metadata key) unless the block repeats it.
        """
        F = _mapping_focal_length(m, where, focal_length_m)
        pitch = m.get("pixel_pitch_m")
        try:
            if "camera_matrix" in m:
                cam = cls._from_opencv_keys(m, where, F, pitch)
            else:
                cam = cls._from_named_keys(m, where, F, pitch)
        except (TypeError, ValueError) as exc:  # a refusal that names the block already is not prefixed twice
            msg = str(exc)
            raise InputValueError(msg if msg.startswith(f"{where}: ") else f"{where}: {msg}") from None
        if pitch is not None:
            implied = np.asarray(cam.focal_length_px) * np.asarray(cam.pixel_pitch_m)
            if not np.allclose(implied, cam.focal_length_m, rtol=1e-6, atol=0):
                raise InputValueError(
                    f"{where}: focal length in pixels {list(cam.focal_length_px)} × pixel_pitch_m {list(cam.pixel_pitch_m or ())} = "
                    f"{implied.tolist()} m disagrees with focal_length_m = {cam.focal_length_m!r} (tolerance 1e-6)"
                )
        return cam

    @classmethod
    def _from_opencv_keys(cls, m: dict[str, Any], where: str, F: Any, pitch: Any) -> "CameraCalibration":
        """The block with OpenCV's ``camera_matrix`` (and ``dist_coeffs``)."""
        for clash in ("focal_length_px", "principal_point_px"):
            if clash in m:
                raise InputValueError(f"{where}: give camera_matrix or {clash}, not both")
        if any(k in m for k in _DISTORTION) and "dist_coeffs" in m:
            raise InputValueError(f"{where}: give dist_coeffs or k1 k2 k3 p1 p2, not both")
        return cls.from_opencv(m["camera_matrix"], m.get("dist_coeffs", [0, 0, 0, 0]), F, m["u_axis"], m["v_axis"], pitch)

    @classmethod
    def _from_named_keys(cls, m: dict[str, Any], where: str, F: Any, pitch: Any) -> "CameraCalibration":
        """The block with named keys: ``principal_point_px``, ``focal_length_px`` or ``pixel_pitch_m``, distortion."""
        if "principal_point_px" not in m:
            raise InputValueError(f"{where}: needs principal_point_px [c_u, c_v] (or OpenCV's camera_matrix)")
        fpx = m.get("focal_length_px")
        if fpx is None:
            if pitch is None:
                raise InputValueError(f"{where}: needs pixel_pitch_m or focal_length_px (the focal length in pixels)")
            pp = np.broadcast_to(np.asarray(pitch, float), (2,))
            fpx = tuple(float(F) / pp)
        return cls(
            F, fpx, m["principal_point_px"], m["u_axis"], m["v_axis"], pixel_pitch_m=pitch, **_mapping_distortion(m, where)
        )

    def to_mapping(self) -> dict[str, Any]:
        """The ``camera`` block written to a file (named keys; reads back with ``from_mapping``)."""
        out = {
            "focal_length_m": self.focal_length_m,
            "focal_length_px": list(self.focal_length_px),
            "principal_point_px": list(self.principal_point_px),
            "u_axis": self.u_axis,
            "v_axis": self.v_axis,
            **{k: getattr(self, k) for k in _DISTORTION},
        }
        if self.pixel_pitch_m is not None:
            out["pixel_pitch_m"] = list(self.pixel_pitch_m)
        return out

    @property
    def camera_matrix(self) -> np.ndarray:
        """OpenCV's camera matrix."""
        (fu, fv), (cu, cv) = self.focal_length_px, self.principal_point_px
        return np.array([[fu, 0.0, cu], [0.0, fv, cv], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV's distortion vector (k1, k2, p1, p2, k3)."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    @property
    def fold_radius2(self) -> float:
        """r² (normalised) where the radial map r (1 + k1 r² + k2 r⁴ + k3 r⁶) first stops increasing
        (smallest positive root of 1 + 3 k1 s + 5 k2 s² + 7 k3 s³, s = r²); ∞ if it never does.
        Beyond it the distortion is not invertible and undistortion is refused."""
        roots = np.roots([7 * self.k3, 5 * self.k2, 3 * self.k1, 1.0])
        real = roots[(np.abs(roots.imag) < 1e-12) & (roots.real > 0)].real
        return float(real.min()) if real.size else np.inf

    @property
    def has_distortion(self) -> bool:
        return any(getattr(self, k) != 0 for k in _DISTORTION)

    # ------------------------------------------------------------------ maps
    def _basis(self) -> Any:
        return np.array([_AXES[self.u_axis], _AXES[self.v_axis]])  # rows e_u, e_v in (x, y)

    def _distort(self, ab: Any) -> Any:
        a, b = ab[..., 0], ab[..., 1]
        r2 = a * a + b * b
        radial = 1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        ad = a * radial + 2 * self.p1 * a * b + self.p2 * (r2 + 2 * a * a)
        bd = b * radial + self.p1 * (r2 + 2 * b * b) + 2 * self.p2 * a * b
        return np.stack([ad, bd], -1)

    def _distort_jacobian(self, ab: Any) -> tuple[Any, Any, Any]:
        a, b = ab[..., 0], ab[..., 1]
        r2 = a * a + b * b
        radial = 1 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        dR = self.k1 + r2 * (2 * self.k2 + 3 * self.k3 * r2)  # d radial / d r²
        j11 = radial + 2 * a * a * dR + 2 * self.p1 * b + 6 * self.p2 * a
        j12 = 2 * a * b * dR + 2 * self.p1 * a + 2 * self.p2 * b
        j22 = radial + 2 * b * b * dR + 6 * self.p1 * b + 2 * self.p2 * a
        return j11, j12, j22  # symmetric: j21 = j12

    def focal_plane_to_pixels(self, xy_m: Any) -> np.ndarray:
        """Ideal focal-plane points (..., 2) m → measured pixels (..., 2), distortion applied."""
        xy = np.asarray(xy_m, float)
        ab = xy @ self._basis().T / self.focal_length_m
        d = self._distort(ab)
        result: np.ndarray = d * np.asarray(self.focal_length_px) + np.asarray(self.principal_point_px)
        return result

    def pixels_to_focal_plane(self, uv_px: Any) -> np.ndarray:
        """Measured pixels (..., 2) → ideal focal-plane points (..., 2) m, distortion removed
        (Newton's method; see the class docstring for the tolerance and the checks)."""
        uv = np.asarray(uv_px, float)
        f = np.asarray(self.focal_length_px)
        target = (uv - np.asarray(self.principal_point_px)) / f
        ab = target.copy()
        if self.has_distortion:
            tol = UNDISTORT_TOL_PX / f
            for _ in range(UNDISTORT_MAX_ITER):
                res = self._distort(ab) - target
                if np.all(np.abs(res) <= tol):
                    break
                j11, j12, j22 = self._distort_jacobian(ab)
                det = j11 * j22 - j12 * j12
                with np.errstate(divide="ignore", invalid="ignore"):
                    step = np.stack(
                        [(j22 * res[..., 0] - j12 * res[..., 1]) / det, (j11 * res[..., 1] - j12 * res[..., 0]) / det], -1
                    )
                ab = ab - np.where(np.isfinite(step), step, 0.0)
            res = np.abs(self._distort(ab) - target) * f
            j11, j12, j22 = self._distort_jacobian(ab)
            inside = np.sum(ab * ab, axis=-1) < self.fold_radius2
            bad = ~(
                np.all(res <= UNDISTORT_TOL_PX, axis=-1) & (j11 * j22 - j12 * j12 > 0) & inside & np.all(np.isfinite(ab), axis=-1)
            )
            if np.any(bad):
                idx = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0])
                p = uv.reshape(-1, 2)[0] if uv.ndim == 1 else uv[idx]
                raise InputValueError(
                    f"pixel {p.tolist()} at index {idx} cannot be undistorted: no convergence to {UNDISTORT_TOL_PX:g} px in "
                    f"{UNDISTORT_MAX_ITER} iterations, or beyond where the distortion model is invertible (outside the calibrated field?)"
                )
        result: np.ndarray = ab @ self._basis() * self.focal_length_m
        return result

    def pixels_to_focal_plane_jacobian(self, uv_px: Any) -> np.ndarray:
        """∂(x, y)/∂(u, v) (..., 2, 2) m/px of ``pixels_to_focal_plane`` at the pixels ``uv_px``:
        F Bᵀ J_d⁻¹ diag(1/f_u, 1/f_v), J_d the distortion's Jacobian at the undistorted point and
        B the detector axes (rows e_u, e_v). Without distortion, diag(pitch) up to the axis signs."""
        uv = np.asarray(uv_px, float)
        ab = self.pixels_to_focal_plane(uv) @ self._basis().T / self.focal_length_m
        j11, j12, j22 = self._distort_jacobian(ab)
        det = j11 * j22 - j12 * j12
        Jinv = np.stack([np.stack([j22, -j12], -1), np.stack([-j12, j11], -1)], -2) / det[..., None, None]
        result: np.ndarray = self.focal_length_m * self._basis().T @ Jinv / np.asarray(self.focal_length_px)
        return result

    def focal_plane_sigma_m(self, sigma_px: float, uv_px: Any) -> tuple[Any, ...]:
        """The focal-plane σK (m) of isotropic centroid noise ``sigma_px`` (pixels) at the pixels
        ``uv_px`` (N, 2), and how far a single σK is from the truth at those points.

        Pixel noise σ_px² E₂ maps to the focal plane as C = σ_px² J Jᵀ, J =
        ``pixels_to_focal_plane_jacobian`` (first order; exact without distortion). The returned
        σK = σ_px √(mean over the points of tr(J Jᵀ)/2) — the RMS per-axis σ, which keeps the total
        noise power — and ``spread`` = max |s_i/σK − 1| over the points' principal σ s_i
        (anisotropic pixels, distortion across the field). Without distortion and with square
        pixels σK = σ_px × pitch and spread = 0.

        >>> cam = CameraCalibration(2.2, (2.2 / 13e-6,) * 2, (5119.5, 5119.5), "+x", "-y")
        >>> s, spread = cam.focal_plane_sigma_m(0.3, [[100.0, 9000.0], [5119.5, 5119.5]])
        >>> round(s / 13e-6, 12), spread
        (0.3, 0.0)
        """
        if isinstance(sigma_px, bool) or not np.isfinite(sigma_px) or sigma_px < 0:
            raise InputValueError(f"sigma_px must be a finite number ≥ 0 (pixels), got {sigma_px!r}")
        uv = np.asarray(uv_px, float).reshape(-1, 2)
        if uv.shape[0] == 0:
            raise InputValueError("focal_plane_sigma_m needs at least one pixel position")
        J = self.pixels_to_focal_plane_jacobian(uv)
        s = np.linalg.svd(J, compute_uv=False)  # (N, 2) principal σ per px of noise
        rms = float(np.sqrt(np.mean(np.sum(s * s, axis=-1) / 2)))
        spread = float(np.max(np.abs(s / rms - 1.0)))
        return float(sigma_px) * rms, (0.0 if spread < 1e-12 else spread)

    def pixel_noise_to_pixels(self, noise_xy_m: Any) -> np.ndarray:
        """Focal-plane noise (..., 2) m expressed in pixels (the linear part of the map)."""
        result: np.ndarray = (np.asarray(noise_xy_m, float) @ self._basis().T) * (
            np.asarray(self.focal_length_px) / self.focal_length_m
        )
        return result


def render_image_points(camera: "Camera", xy_true_m: Any, noise_m: Any) -> np.ndarray:
    """Measured focal-plane points from the true ones and the centroid noise.

    Without a calibrated camera: ``xy_true + noise`` (Kiev 2012's model). With one: the true point
    is imaged through the distortion onto the detector, the centroid noise is added there (in
    pixels: σ_px = σK / pitch), and the measured pixel is undistorted back to the ideal focal
    plane — what a reader of a ``u v`` file does. DECISION: the noise is added on the detector;
    on the ideal plane it is then scaled by the local inverse-distortion Jacobian (≤ a few 1e-3
    for real lenses), which the estimators' σK ignores.
    """
    cal = camera.calibration() if isinstance(camera, Camera) else camera
    if cal is None:
        result: np.ndarray = xy_true_m + noise_m
        return result
    uv = cal.focal_plane_to_pixels(xy_true_m) + cal.pixel_noise_to_pixels(noise_m)
    return cal.pixels_to_focal_plane(uv)


# ---------------------------------------------------------------------------- line sensors (pushbroom)
#
# A pushbroom camera is the frame camera's collinearity model with one detector line on the focal
# plane: pixel j of a chip sits at the focal-plane point x(j) = F (tan ψx(j), tan ψy(j)), so it looks
# along s = direction_from_image(x(j), F) = [F tan ψx, F tan ψy, −F] in K (boresight −z_K, eq 3),
# and a direction s is imaged at project(s, F) exactly as in a frame image. ψx is the along-track
# look angle (about the line, x_K along-track), ψy the across-track one (along the line, y_K): the
# "look-angle" (ψx, ψy) model of the ZY-3 / SPOT / Pléiades geometric calibrations, a polynomial in
# the detector index per chip, or Rugged's ``LineSensor`` table of lines of sight.


def _poly_coeffs(name: str, coeffs: Any) -> tuple[float, ...]:
    c = np.atleast_1d(np.asarray(coeffs, dtype=float))
    if c.ndim != 1 or c.size == 0 or not np.all(np.isfinite(c)):
        raise InputValueError(f"LineChip.{name} must be a non-empty list of finite polynomial coefficients, got {coeffs!r}")
    return tuple(float(x) for x in c)


@dataclass(frozen=True, eq=False)
class LineChip:
    """One chip of a detector line: the look angles of its ``n_pixels`` pixels in the chip index j = 0 … n − 1.

    Two forms, both giving tan ψx(j), tan ψy(j) (the focal-plane position over F):

    * a **polynomial** (``tan_psi_x``, ``tan_psi_y``: coefficients in increasing powers of j,
      ``numpy.polynomial.polynomial`` order) — the calibrated look-angle model
      tan ψ(j) = a0 + a1 j + a2 j² + a3 j³ of the ZY-3 / SPOT geometric calibrations.
      DECISION: the law is on tan ψ, not on ψ: tan ψ is the focal-plane coordinate over F, so the
      line sensor and the frame camera share ``direction_from_image`` / ``project`` without a
      conversion; a law on ψ differs by a cubic term the coefficients absorb;
    * a **table** of lines of sight (``LineChip.from_lines_of_sight``, an (n, 3) array of K-frame
      directions, as Rugged's ``LineSensor`` takes them), stored as tan ψ per pixel and
      interpolated linearly in j between pixels (and extrapolated from the end segments).
      DECISION: linear in tan ψ where Rugged interpolates the normalised vectors linearly; the two
      differ by O(Δψ² ψ) between neighbouring pixels (≤ 1e-12 rad for 10 µrad pixels).

    The across-track law must be strictly monotonic over the chip (checked): inverse location solves
    tan ψy(j) = t for j.
    """

    n_pixels: int
    tan_psi_x: tuple[float, ...] = (0.0,)
    tan_psi_y: tuple[float, ...] = (0.0,)
    table_tan_psi: np.ndarray | None = None  # (n_pixels, 2) for a table of lines of sight

    def __post_init__(self) -> None:
        if isinstance(self.n_pixels, bool) or not isinstance(self.n_pixels, (int, np.integer)) or self.n_pixels < 2:
            raise InputValueError(f"LineChip.n_pixels must be an integer ≥ 2, got {self.n_pixels!r}")
        object.__setattr__(self, "tan_psi_x", _poly_coeffs("tan_psi_x", self.tan_psi_x))
        object.__setattr__(self, "tan_psi_y", _poly_coeffs("tan_psi_y", self.tan_psi_y))
        if self.table_tan_psi is not None:
            tab = np.array(self.table_tan_psi, dtype=float)
            if tab.shape != (self.n_pixels, 2) or not np.all(np.isfinite(tab)):
                raise InputValueError(f"LineChip.table_tan_psi must be ({self.n_pixels}, 2) finite values, got shape {tab.shape}")
            tab.setflags(write=False)
            object.__setattr__(self, "table_tan_psi", tab)
        dy = self.tan_psi_derivative(np.linspace(-0.5, self.n_pixels - 0.5, 4 * self.n_pixels + 1))[..., 1]
        if not (np.all(dy > 0) or np.all(dy < 0)):
            raise InputValueError(
                "LineChip: the across-track look angle tan ψy must be strictly monotonic in the pixel index over the chip "
                f"(its derivative changes sign or vanishes: min {dy.min():.3g}, max {dy.max():.3g} per pixel)"
            )

    @classmethod
    def from_lines_of_sight(cls, los_k: Any) -> "LineChip":
        """A chip from a table of K-frame lines of sight (n, 3), one per pixel (Rugged's ``LineSensor``)."""
        los = np.asarray(los_k, dtype=float)
        if los.ndim != 2 or los.shape[1] != 3 or los.shape[0] < 2:
            raise InputValueError(f"lines of sight must be an (n ≥ 2, 3) array, got shape {los.shape}")
        if np.any(~np.isfinite(los)) or np.any(los[:, 2] >= 0):
            bad = int(np.argmax(~np.isfinite(los).all(axis=1) | (los[:, 2] >= 0)))
            raise InputValueError(
                f"line of sight {bad} = {los[bad].tolist()} does not look forward (the camera looks along −z_K)"
            )
        return cls(n_pixels=los.shape[0], table_tan_psi=project(los, 1.0))

    def tan_psi(self, j: Any) -> np.ndarray:
        """(tan ψx, tan ψy) of the (fractional) chip index j, ``(...) -> (..., 2)``."""
        j = np.asarray(j, dtype=float)
        if self.table_tan_psi is None:
            from numpy.polynomial import polynomial as P

            return np.stack([P.polyval(j, self.tan_psi_x), P.polyval(j, self.tan_psi_y)], axis=-1)
        tab = self.table_tan_psi
        i = np.clip(np.floor(j).astype(int), 0, self.n_pixels - 2)
        f = (j - i)[..., None]
        result: np.ndarray = tab[i] * (1 - f) + tab[i + 1] * f
        return result

    def tan_psi_derivative(self, j: Any) -> np.ndarray:
        """d(tan ψx, tan ψy)/dj per pixel, ``(...) -> (..., 2)``."""
        j = np.asarray(j, dtype=float)
        if self.table_tan_psi is None:
            from numpy.polynomial import polynomial as P

            return np.stack([P.polyval(j, P.polyder(self.tan_psi_x)), P.polyval(j, P.polyder(self.tan_psi_y))], axis=-1)
        tab = self.table_tan_psi
        i = np.clip(np.floor(j).astype(int), 0, self.n_pixels - 2)
        result: np.ndarray = tab[i + 1] - tab[i]
        return result


@dataclass(frozen=True, eq=False)
class LineSensor:
    """A detector line of one or more chips behind one lens of focal length F (m).

    Pixels are numbered along the whole line: chip c holds the columns ``first_pixel(c)`` …
    ``first_pixel(c) + n_pixels − 1`` (chips in order, no gap in the numbering; staggered or
    overlapping chips are expressed by their look angles, not by their numbers). A column p of chip c
    has the chip index j = p − first_pixel(c).

    Two forward-model parameters act on the look directions (``look_direction``), with the frame
    camera's meaning: a per-chip look-angle offset (δψx, δψy) (rad; added to tan ψ: a shift of the
    chip on the focal plane by F δψ) and a focal scale κ: the image of a direction is scaled by
    (1 + κ), as ``orbits.effects``' ``focal_scale`` does on a frame image (x ← (1 + κ) x). Pixel j of
    chip c therefore looks along

        s = direction_from_image(F (tan ψ(j) + δψ_c) / (1 + κ), F).

    >>> line = LineSensor(2.0, (LineChip(4, tan_psi_y=(-0.0015, 0.001)),))
    >>> s = line.look_direction(0, 3.0)   # pixel 3: tan ψy = −0.0015 + 3 × 0.001
    >>> [round(float(v), 12) for v in s]
    [0.0, 0.003, -2.0]
    >>> [round(float(v), 12) for v in line.image_tan_psi(s)]   # the frame camera's project(s, F) / F
    [0.0, 0.0015]
    """

    focal_length_m: float
    chips: tuple[LineChip, ...]
    pixel_pitch_m: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.focal_length_m) and self.focal_length_m > 0):
            raise InputValueError(f"LineSensor.focal_length_m must be a positive number, got {self.focal_length_m!r}")
        chips = tuple(self.chips)
        if not chips or not all(isinstance(c, LineChip) for c in chips):
            raise InputValueError(f"LineSensor.chips must be a non-empty sequence of LineChip, got {self.chips!r}")
        object.__setattr__(self, "chips", chips)
        if self.pixel_pitch_m is not None and not self.pixel_pitch_m > 0:
            raise InputValueError(f"LineSensor.pixel_pitch_m must be > 0 or None, got {self.pixel_pitch_m!r}")

    @property
    def n_chips(self) -> int:
        return len(self.chips)

    @property
    def n_pixels(self) -> int:
        """Pixels on the whole line."""
        return sum(c.n_pixels for c in self.chips)

    @property
    def chip_start(self) -> np.ndarray:
        """(n_chips + 1,) int: the line column of each chip's pixel 0, then the line's length — chip c holds the
        columns ``chip_start[c]`` … ``chip_start[c + 1] − 1``."""
        return np.cumsum([0] + [c.n_pixels for c in self.chips])

    def first_pixel(self, chip: int) -> int:
        """The line column of chip ``chip``'s pixel 0."""
        return int(self.chip_start[chip])

    def chip_of(self, pixel: Any) -> tuple[np.ndarray, np.ndarray]:
        """(chip index, chip index j) of line columns ``pixel`` (fractional columns round to the nearest pixel's chip)."""
        p = np.asarray(pixel, dtype=float)
        starts = self.chip_start
        chip = np.clip(np.searchsorted(starts, p + 0.5, side="right") - 1, 0, self.n_chips - 1)
        return chip, p - starts[chip]

    def _offsets(self, chip_offsets_rad: Any) -> np.ndarray:
        if chip_offsets_rad is None:
            return np.zeros((self.n_chips, 2))
        off = np.asarray(chip_offsets_rad, dtype=float)
        if off.shape != (self.n_chips, 2) or not np.all(np.isfinite(off)):
            raise InputValueError(
                f"chip_offsets_rad must be ({self.n_chips}, 2) finite (δψx, δψy) per chip, got shape {off.shape}"
            )
        return off

    def tan_psi(self, chip: Any, j: Any, focal_scale: float = 0.0, chip_offsets_rad: Any = None) -> np.ndarray:
        """Effective (tan ψx, tan ψy) of pixel j of ``chip``: (tan ψ(j) + δψ_c) / (1 + κ), ``(...) -> (..., 2)``."""
        chip = np.asarray(chip, dtype=int)
        j = np.asarray(j, dtype=float)
        chip, j = np.broadcast_arrays(chip, j)
        out = np.empty(j.shape + (2,))
        for c, ch in enumerate(self.chips):
            sel = chip == c
            if np.any(sel):
                out[sel] = ch.tan_psi(j[sel])
        return self.effective_tan_psi(out, chip, focal_scale, chip_offsets_rad)

    def effective_tan_psi(
        self, tan_psi_law: Any, chip: Any, focal_scale: float = 0.0, chip_offsets_rad: Any = None
    ) -> np.ndarray:
        """(tan ψ + δψ_c) / (1 + κ) of look angles ``tan_psi_law`` (..., 2) given by the chips' laws (``tan_psi`` at
        κ = 0 without offsets): an estimator varying κ and δψ evaluates the laws once."""
        chip = np.asarray(chip, dtype=int)
        result: np.ndarray = (np.asarray(tan_psi_law, float) + self._offsets(chip_offsets_rad)[chip]) / (1.0 + focal_scale)
        return result

    def look_direction(self, chip: Any, j: Any, focal_scale: float = 0.0, chip_offsets_rad: Any = None) -> np.ndarray:
        """K-frame line of sight s = [x, y, −F] of pixel j of ``chip`` (eq 3's collinearity), ``(...) -> (..., 3)``."""
        F = self.focal_length_m
        return direction_from_image(F * self.tan_psi(chip, j, focal_scale, chip_offsets_rad), F)

    def image_tan_psi(self, s_k: Any) -> np.ndarray:
        """(tan ψx, tan ψy) at which a K-frame direction is imaged: project(s, F) / F, ``(..., 3) -> (..., 2)``."""
        result: np.ndarray = project(s_k, self.focal_length_m) / self.focal_length_m
        return result

    def mean_plane_normal(self, focal_scale: float = 0.0, chip_offsets_rad: Any = None) -> np.ndarray:
        """Unit normal (3,) in K of the plane through the origin that best fits all pixels' lines of sight.

        Rugged's ``SensorMeanPlaneCrossing.computeMeanPlaneNormal``: the left singular vector of the
        least singular value of the 3 × 2n matrix [l_i, −l_i] (unit lines of sight and their opposites,
        so the plane contains the origin), oriented so that the first-to-last pixel order is
        counter-clockwise about it (n · (l_first × l_last) ≥ 0).
        """
        chips = np.concatenate([np.full(c.n_pixels, k) for k, c in enumerate(self.chips)])
        j = np.concatenate([np.arange(c.n_pixels, dtype=float) for c in self.chips])
        los = self.look_direction(chips, j, focal_scale, chip_offsets_rad)
        los = los / np.linalg.norm(los, axis=-1, keepdims=True)
        # the left singular vectors of M = [l_i, −l_i] are the eigenvectors of M Mᵀ = 2 Σ l_i l_iᵀ (3 × 3: no SVD of
        # the 3 × 2n matrix); the least singular value's is the smallest eigenvalue's
        _, vecs = np.linalg.eigh(2.0 * los.T @ los)
        n = vecs[:, 0]
        if float(n @ np.cross(los[0], los[-1])) < 0:
            n = -n
        result: np.ndarray = n
        return result


@dataclass(frozen=True)
class LinearLineDatation:
    """Line datation t(L) = t_ref + (L − L_ref) T (Rugged's ``LinearLineDatation``: a reference line,
    its date and a line rate 1/T). Times are seconds from the strip's epoch."""

    reference_line: float
    reference_time_s: float
    line_period_s: float

    def __post_init__(self) -> None:
        for name in ("reference_line", "reference_time_s", "line_period_s"):
            if not np.isfinite(getattr(self, name)):
                raise InputValueError(f"LinearLineDatation.{name} must be finite, got {getattr(self, name)!r}")
        if not self.line_period_s > 0:
            raise InputValueError(f"LinearLineDatation.line_period_s must be > 0, got {self.line_period_s!r}")

    def time_s(self, line: Any) -> np.ndarray:
        """Nominal time of (fractional) lines."""
        result: np.ndarray = self.reference_time_s + (np.asarray(line, float) - self.reference_line) * self.line_period_s
        return result

    def period_s(self, line: Any) -> np.ndarray:
        """dt/dL at ``line``."""
        return np.full(np.shape(line), self.line_period_s)

    def line(self, time_s: Any) -> np.ndarray:
        """Inverse of ``time_s``."""
        result: np.ndarray = self.reference_line + (np.asarray(time_s, float) - self.reference_time_s) / self.line_period_s
        return result


@dataclass(frozen=True, eq=False)
class TabulatedLineDatation:
    """Line datation from a table of (line, time) pairs, strictly increasing in both; linear between
    entries and extrapolated from the end segments (a line-time table as flight products give it:
    SPOT's and Pléiades' line-date tables). The reference line (for the line-period error) is the first entry."""

    lines: np.ndarray
    times_s: np.ndarray

    def __post_init__(self) -> None:
        lines = np.array(self.lines, dtype=float)
        times = np.array(self.times_s, dtype=float)
        if lines.ndim != 1 or lines.shape != times.shape or lines.size < 2:
            raise InputValueError(
                f"TabulatedLineDatation: lines and times_s must be 1-D of one length ≥ 2, got {lines.shape}, {times.shape}"
            )
        for name, v in (("lines", lines), ("times_s", times)):
            if not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
                k = int(np.argmax(~np.isfinite(v[1:]) | (np.diff(v) <= 0))) + 1
                raise InputValueError(
                    f"TabulatedLineDatation.{name} must be finite and strictly increasing; entry {k} = {v[k]!r}"
                )
            v.setflags(write=False)
        object.__setattr__(self, "lines", lines)
        object.__setattr__(self, "times_s", times)

    @property
    def reference_line(self) -> float:
        return float(self.lines[0])

    def _segment(self, x: Any, nodes: np.ndarray) -> np.ndarray:
        result: np.ndarray = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
        return result

    def _piecewise_linear(self, x: Any, nodes: np.ndarray, values: np.ndarray) -> np.ndarray:
        """values at x on the polyline through (nodes, values), its end segments extended beyond the table
        (one route for both directions: line → time and time → line)."""
        x = np.asarray(x, float)
        i = self._segment(x, nodes)
        slope = (values[i + 1] - values[i]) / (nodes[i + 1] - nodes[i])
        result: np.ndarray = values[i] + (x - nodes[i]) * slope
        return result

    def time_s(self, line: Any) -> np.ndarray:
        return self._piecewise_linear(line, self.lines, self.times_s)

    def period_s(self, line: Any) -> np.ndarray:
        i = self._segment(np.asarray(line, float), self.lines)
        result: np.ndarray = (self.times_s[i + 1] - self.times_s[i]) / (self.lines[i + 1] - self.lines[i])
        return result

    def line(self, time_s: Any) -> np.ndarray:
        return self._piecewise_linear(time_s, self.times_s, self.lines)
