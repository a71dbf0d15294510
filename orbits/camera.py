"""Pinhole camera: projection (Kiev 2012 eqs 3/20), back-projection (eqs 2/14), visibility.

Camera frame K: boresight along −z_K; a landmark imaged at (x, y) on the focal plane lies
along s = [x, y, −F] (Kiev 2012 eq 3 and the unit-vector section). Image coordinates are
metres on the focal plane; a pixel pitch converts to pixels for display only.

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
            raise ValueError(f"Camera.focal_length_m must be a positive number, got {self.focal_length_m!r}")
        if not (np.isfinite(self.fov_deg) and 0 < self.fov_deg < 180):
            raise ValueError(f"Camera.fov_deg must be in (0, 180), got {self.fov_deg!r}")
        if self.pixel_pitch_m is not None and not self.pixel_pitch_m > 0:
            raise ValueError(f"Camera.pixel_pitch_m must be > 0 or None, got {self.pixel_pitch_m!r}")

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
            raise ValueError(
                f"camera: {given} need principal_point_px (and pixel_pitch_m, u_axis, v_axis): a calibrated detector"
            )
        if self.pixel_pitch_m is None:
            raise ValueError(
                "camera: principal_point_px needs pixel_pitch_m (the focal length in pixels is focal_length_m / pixel_pitch_m)"
            )
        for key in ("u_axis", "v_axis"):
            if getattr(self, key) is None:
                raise ValueError(
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

    The spherical-Earth counterpart of eq 2. Raises ``ValueError`` naming the first image point whose ray misses the sphere.
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
        raise ValueError(f"image ray at index {tuple(int(i) for i in idx)} misses the sphere of radius {radius_m} m")
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

        raise ValueError(unknown_keys_message(where, unknown, known))
    for key in _MAPPING_KEYS:
        if key not in ("u_axis", "v_axis") and key in m and not _numeric(m[key]):
            raise ValueError(f"{where}: {key} must be a finite number (or a list of them), got {m[key]!r}")
    F = m.get("focal_length_m", focal_length_m)
    if F is None:
        raise ValueError(f"{where}: needs focal_length_m")
    if (
        focal_length_m is not None
        and "focal_length_m" in m
        and not np.isclose(m["focal_length_m"], focal_length_m, rtol=1e-9, atol=0)
    ):
        raise ValueError(
            f"{where}: focal_length_m = {m['focal_length_m']!r} differs from the file's focal_length_m = {focal_length_m!r}"
        )
    for key in ("u_axis", "v_axis"):
        if key not in m:
            raise ValueError(
                f"{where}: needs {key} (the camera-frame axis, one of {list(_AXES)}, along which {key[0]} increases)"
            )
    return F


def _mapping_distortion(m: dict[str, Any], where: str) -> dict[str, Any]:
    """The distortion coefficients of a named-key block: ``dist_coeffs`` or ``k1 k2 k3 p1 p2`` (default 0)."""
    if "dist_coeffs" not in m:
        return {k: m.get(k, 0.0) for k in _DISTORTION}
    if any(k in m for k in _DISTORTION):
        raise ValueError(f"{where}: give dist_coeffs or k1 k2 k3 p1 p2, not both")
    d = np.asarray(m["dist_coeffs"], float).ravel()
    if d.size not in (4, 5):
        raise ValueError(
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
                raise ValueError(f"CameraCalibration.{name} must be a {'positive ' if positive else ''}finite number, got {v!r}")
            return float(v)

        object.__setattr__(self, "focal_length_m", number("focal_length_m", self.focal_length_m, True))
        for name in ("focal_length_px", "principal_point_px") + (("pixel_pitch_m",) if self.pixel_pitch_m is not None else ()):
            v = getattr(self, name)
            if isinstance(v, (int, float)) and not isinstance(v, bool) and name != "principal_point_px":
                v = (v, v)
            if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != 2:
                raise ValueError(f"CameraCalibration.{name} must be two numbers (u, v), got {v!r}")
            object.__setattr__(
                self, name, tuple(number(f"{name}[{i}]", x, name != "principal_point_px") for i, x in enumerate(v))
            )
        for name in ("u_axis", "v_axis"):
            if getattr(self, name) not in _AXES:
                raise ValueError(
                    f"CameraCalibration.{name} must be one of {list(_AXES)} (the camera-frame axis along which it increases), got {getattr(self, name)!r}"
                )
        if abs(np.dot(_AXES[self.u_axis], _AXES[self.v_axis])) > 0:
            raise ValueError(
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
            raise ValueError(
                f"camera_matrix must be [[f_u, 0, c_u], [0, f_v, c_v], [0, 0, 1]] (no skew), got {np.asarray(camera_matrix).tolist()!r}"
            )
        d = np.asarray(dist_coeffs, float).ravel()
        if d.size not in (4, 5) or not np.all(np.isfinite(d)):
            raise ValueError(
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
        """See ``_from_mapping``; every problem is a ``ValueError`` naming ``where`` and the key."""
        if not isinstance(m, dict):
            raise ValueError(f"{where} must be a mapping of calibration keys, got {m!r}")
        try:
            return cls._from_mapping(m, where, focal_length_m)
        except (TypeError, ValueError, OverflowError) as exc:
            msg = str(exc)
            raise ValueError(msg if msg.startswith(where) else f"{where}: {msg}") from None

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
            raise ValueError(msg if msg.startswith(f"{where}: ") else f"{where}: {msg}") from None
        if pitch is not None:
            implied = np.asarray(cam.focal_length_px) * np.asarray(cam.pixel_pitch_m)
            if not np.allclose(implied, cam.focal_length_m, rtol=1e-6, atol=0):
                raise ValueError(
                    f"{where}: focal length in pixels {list(cam.focal_length_px)} × pixel_pitch_m {list(cam.pixel_pitch_m or ())} = "
                    f"{implied.tolist()} m disagrees with focal_length_m = {cam.focal_length_m!r} (tolerance 1e-6)"
                )
        return cam

    @classmethod
    def _from_opencv_keys(cls, m: dict[str, Any], where: str, F: Any, pitch: Any) -> "CameraCalibration":
        """The block with OpenCV's ``camera_matrix`` (and ``dist_coeffs``)."""
        for clash in ("focal_length_px", "principal_point_px"):
            if clash in m:
                raise ValueError(f"{where}: give camera_matrix or {clash}, not both")
        if any(k in m for k in _DISTORTION) and "dist_coeffs" in m:
            raise ValueError(f"{where}: give dist_coeffs or k1 k2 k3 p1 p2, not both")
        return cls.from_opencv(m["camera_matrix"], m.get("dist_coeffs", [0, 0, 0, 0]), F, m["u_axis"], m["v_axis"], pitch)

    @classmethod
    def _from_named_keys(cls, m: dict[str, Any], where: str, F: Any, pitch: Any) -> "CameraCalibration":
        """The block with named keys: ``principal_point_px``, ``focal_length_px`` or ``pixel_pitch_m``, distortion."""
        if "principal_point_px" not in m:
            raise ValueError(f"{where}: needs principal_point_px [c_u, c_v] (or OpenCV's camera_matrix)")
        fpx = m.get("focal_length_px")
        if fpx is None:
            if pitch is None:
                raise ValueError(f"{where}: needs pixel_pitch_m or focal_length_px (the focal length in pixels)")
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
                raise ValueError(
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
            raise ValueError(f"sigma_px must be a finite number ≥ 0 (pixels), got {sigma_px!r}")
        uv = np.asarray(uv_px, float).reshape(-1, 2)
        if uv.shape[0] == 0:
            raise ValueError("focal_plane_sigma_m needs at least one pixel position")
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
