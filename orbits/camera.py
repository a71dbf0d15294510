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

import numpy as np

__all__ = ["Camera", "project", "direction_from_image", "back_project_to_plane", "back_project_to_sphere"]


@dataclass(frozen=True)
class Camera:
    """Focal length (m), full square field of view (deg), optional pixel pitch (m)."""

    focal_length_m: float
    fov_deg: float
    pixel_pitch_m: float | None = None

    def __post_init__(self):
        if not (np.isfinite(self.focal_length_m) and self.focal_length_m > 0):
            raise ValueError(f"Camera.focal_length_m must be a positive number, got {self.focal_length_m!r}")
        if not (np.isfinite(self.fov_deg) and 0 < self.fov_deg < 180):
            raise ValueError(f"Camera.fov_deg must be in (0, 180), got {self.fov_deg!r}")
        if self.pixel_pitch_m is not None and not self.pixel_pitch_m > 0:
            raise ValueError(f"Camera.pixel_pitch_m must be > 0 or None, got {self.pixel_pitch_m!r}")

    @property
    def half_width_m(self) -> float:
        """Half-width of the square field on the focal plane, F tan(FOV/2)."""
        return self.focal_length_m * np.tan(np.radians(self.fov_deg) / 2)

    def visible(self, s_k) -> np.ndarray:
        """In front (s_z < 0) and inside the square field, ``(..., 3) -> (...)`` bool."""
        s = np.asarray(s_k, dtype=float)
        front = s[..., 2] < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = project(s, self.focal_length_m)
        inside = np.all(np.abs(xy) <= self.half_width_m, axis=-1)
        return front & inside


def project(s_k, focal_length_m: float) -> np.ndarray:
    """Collinearity equations (Kiev 2012 eq 3): (x, y) = −F (s_x, s_y) / s_z, ``(..., 3) -> (..., 2)``.

    ``s_k`` is the camera-frame vector from the projection centre to the landmark,
    ``C_IK (r_M − r_I)`` in eq 3's notation.
    """
    s = np.asarray(s_k, dtype=float)
    return -focal_length_m * s[..., :2] / s[..., 2:3]


def direction_from_image(xy_m, focal_length_m: float) -> np.ndarray:
    """s = [x, y, −F] for image points ``(..., 2) -> (..., 3)``."""
    xy = np.asarray(xy_m, dtype=float)
    return np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -float(focal_length_m))], axis=-1)


def back_project_to_plane(xy_m, C_AK, r_center_a_m, plane_z_m, focal_length_m: float) -> np.ndarray:
    """Ground point on the plane z_A = ``plane_z_m`` seen at image point (x, y) (Kiev 2012 eq 2).

    ``C_AK`` maps frame A (e.g. topocentric T) to the camera; ``r_center_a_m`` is the projection
    centre in A. Eq 2: X_M = X_I + (Z_M − Z_I)(c11 x + c21 y − c31 F)/(c13 x + c23 y − c33 F), i.e.
    the ray ``C_AKᵀ s`` scaled to reach the plane. Shapes broadcast; returns ``(..., 3)``.
    """
    d = np.einsum("...ji,...j->...i", np.asarray(C_AK, float), direction_from_image(xy_m, focal_length_m))
    r0 = np.asarray(r_center_a_m, dtype=float)
    lam = (np.asarray(plane_z_m, float) - r0[..., 2]) / d[..., 2]
    return r0 + lam[..., None] * d


def back_project_to_sphere(xy_m, C_AK, r_center_a_m, radius_m, focal_length_m: float) -> np.ndarray:
    """Nearest intersection of the image ray with a sphere |r| = ``radius_m`` centred at A's origin.

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
    return r0 + lam[..., None] * d
