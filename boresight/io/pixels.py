"""Pixel detections → focal-plane metres through a calibrated camera (OpenCV's pinhole +
Brown–Conrady model, so a user can paste an OpenCV calibration).

OpenCV (``calib3d`` docs, "Detailed Description"): a point at normalised coordinates
(x', y') = (X/Z, Y/Z) in the OpenCV camera frame (x right, y down, z forward) is distorted to

    r² = x'² + y'²
    x'' = x'(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x'y' + p2 (r² + 2x'²)
    y'' = y'(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y'²) + 2 p2 x'y'

and imaged at pixel u = fx x'' + cx, v = fy y'' + cy (u along a row, v down the columns: v is
the row index, u the column index). Our camera frame K has the boresight along −z_K and image
points s = [x, y, −F] (Kiev 2012 eq 3); with the detector's u axis along +x_K and v along −y_K
(``detector = "u_right_v_down"``, the default), K = diag(1, −1, −1) · OpenCV, so
x = F x', y = −F y'. ``detector = "u_right_v_up"`` maps v along +y_K (y = +F y').

Undistortion inverts the polynomial by Newton's method on (x', y') with the analytic Jacobian to
round-off (OpenCV's ``undistortPoints`` does a fixed number of fixed-point steps, which is not
exact); the forward model is checked against the inverse on a grid in ``tests/test_ingest.py``.

NOTE: the project's camera-calibration object (``orbits/camera.py``, the format engineer's) will
carry the same model in the observation file; this module is the ingestion-side reader of a
camera TOML and uses that object once it is available.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass

import numpy as np

from .common import IngestError

__all__ = ["PixelCamera", "read_camera_toml", "read_mount_toml"]

_DETECTORS = {"u_right_v_down": np.array([1.0, -1.0]), "u_right_v_up": np.array([1.0, 1.0])}


@dataclass(frozen=True)
class PixelCamera:
    """fx, fy (px), principal point cx, cy (px), Brown–Conrady k1 k2 k3 p1 p2 (OpenCV order), focal length F (m)."""

    focal_length_m: float
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    detector: str = "u_right_v_down"
    fov_deg: float | None = None

    def __post_init__(self):
        for name in ("focal_length_m", "fx_px", "fy_px"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise IngestError(f"camera: {name} must be a positive number, got {v!r}")
        if self.detector not in _DETECTORS:
            raise IngestError(f"camera: detector must be one of {sorted(_DETECTORS)}, got {self.detector!r}")

    @property
    def pixel_pitch_m(self) -> float:
        return self.focal_length_m / self.fx_px

    def _distort(self, xn):
        x, y = xn[..., 0], xn[..., 1]
        r2 = x * x + y * y
        rad = 1 + self.k1 * r2 + self.k2 * r2**2 + self.k3 * r2**3
        xd = x * rad + 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x)
        yd = y * rad + self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y
        return np.stack([xd, yd], -1)

    def _jacobian(self, xn):
        x, y = xn[..., 0], xn[..., 1]
        r2 = x * x + y * y
        rad = 1 + self.k1 * r2 + self.k2 * r2**2 + self.k3 * r2**3
        drad = self.k1 + 2 * self.k2 * r2 + 3 * self.k3 * r2**2  # d rad / d r2
        dxx = rad + x * drad * 2 * x + 2 * self.p1 * y + self.p2 * 6 * x
        dxy = x * drad * 2 * y + 2 * self.p1 * x + self.p2 * 2 * y
        dyx = y * drad * 2 * x + self.p1 * 2 * x + 2 * self.p2 * y
        dyy = rad + y * drad * 2 * y + self.p1 * 6 * y + 2 * self.p2 * x
        return np.stack([np.stack([dxx, dxy], -1), np.stack([dyx, dyy], -1)], -2)

    def focal_plane_to_pixels(self, xy_m) -> np.ndarray:
        """(…, 2) focal-plane metres → (…, 2) pixels (u, v), distortion applied."""
        xn = np.asarray(xy_m, float) / self.focal_length_m * _DETECTORS[self.detector]
        xd = self._distort(xn)
        return np.stack([self.fx_px * xd[..., 0] + self.cx_px, self.fy_px * xd[..., 1] + self.cy_px], -1)

    def pixels_to_focal_plane(self, uv_px) -> np.ndarray:
        """(…, 2) pixels (u, v) → (…, 2) focal-plane metres, distortion removed (Newton to round-off)."""
        uv = np.asarray(uv_px, float)
        xd = np.stack([(uv[..., 0] - self.cx_px) / self.fx_px, (uv[..., 1] - self.cy_px) / self.fy_px], -1)
        xn = xd.copy()
        for _ in range(50):
            f = self._distort(xn) - xd
            step = np.linalg.solve(self._jacobian(xn), f[..., None])[..., 0]
            xn = xn - step
            if np.all(np.abs(step) < 1e-16):
                break
        else:
            raise IngestError("camera: undistortion did not converge (distortion coefficients too large for the field?)")
        return xn * _DETECTORS[self.detector] * self.focal_length_m

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__ if getattr(self, k) is not None}


def read_camera_toml(path) -> PixelCamera:
    """A camera TOML: ``focal_length_m``; ``pixel_pitch_m`` (square pixels) or ``fx_px``/``fy_px``;
    ``cx_px``, ``cy_px``; optional ``k1 k2 k3 p1 p2``, ``detector``, ``fov_deg``. Keys may sit under
    a ``[camera]`` table. Unknown keys are refused."""
    try:
        data = tomllib.loads(open(path, encoding="utf-8").read())
    except FileNotFoundError:
        raise
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise IngestError(f"{path}: not a readable TOML camera file: {exc}") from exc
    data = dict(data.get("camera", data))
    data.pop("mount", None)
    allowed = {"focal_length_m", "pixel_pitch_m", "fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "k3", "p1", "p2", "detector", "fov_deg"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise IngestError(f"{path}: unknown camera key(s) {', '.join(repr(k) for k in unknown)}; allowed: {', '.join(sorted(allowed))}")
    for req in ("focal_length_m", "cx_px", "cy_px"):
        if req not in data:
            raise IngestError(f"{path}: camera key {req!r} is required")
    F = float(data["focal_length_m"])
    if "pixel_pitch_m" in data:
        if "fx_px" in data or "fy_px" in data:
            raise IngestError(f"{path}: give pixel_pitch_m or fx_px/fy_px, not both")
        pitch = float(data.pop("pixel_pitch_m"))
        if not pitch > 0:
            raise IngestError(f"{path}: camera key 'pixel_pitch_m' must be > 0, got {pitch!r}")
        data["fx_px"] = data["fy_px"] = F / pitch
    if "fx_px" not in data or "fy_px" not in data:
        raise IngestError(f"{path}: camera needs pixel_pitch_m or both fx_px and fy_px")
    kw = {k: (str(v) if k == "detector" else float(v)) for k, v in data.items()}
    return PixelCamera(**kw)


def read_mount_toml(path):
    """The nominal star-tracker → camera DCM ``C_SK_nominal`` from a camera TOML's ``[mount]`` table
    (3 rows of 3 numbers), or None (identity) if absent; it must be a rotation (to 1e-9)."""
    data = tomllib.loads(open(path, encoding="utf-8").read())
    mount = data.get("mount")
    if mount is None:
        return None
    unknown = sorted(set(mount) - {"C_SK_nominal"})
    if unknown:
        raise IngestError(f"{path}: unknown [mount] key(s) {', '.join(repr(k) for k in unknown)}; allowed: 'C_SK_nominal'")
    try:
        C = np.asarray(mount["C_SK_nominal"], float)
    except (KeyError, ValueError, TypeError) as exc:
        raise IngestError(f"{path}: [mount] C_SK_nominal must be 3 rows of 3 numbers: {exc}") from exc
    if C.shape != (3, 3) or not np.allclose(C @ C.T, np.eye(3), atol=1e-9) or np.linalg.det(C) < 0:
        raise IngestError(f"{path}: [mount] C_SK_nominal must be a 3×3 rotation matrix (star tracker → camera), got {mount['C_SK_nominal']!r}")
    return C
