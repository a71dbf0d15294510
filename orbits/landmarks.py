"""Landmark fields around a ground site, in topocentric T coordinates (x east, y north, z up; m).

* ``kiev_m1_m4()`` — the seminar's four landmarks (Kiev 2012, Algorithm 1 scenario):
  M1 = {50; 0; 0.05}, M2 = {0; 50; 0.1}, M3 = {−50; 0; −0.02}, M4 = {0; −50; −0.08} km.
  They are not coplanar (heights 50, 100, −20, −80 m).
* ``grid(n, half_width_m)`` — an n×n regular grid on the tangent plane.
* ``random_field(rng, n, half_width_m, height_sigma_m)`` — uniform in a square, Gaussian heights.

``to_earth_fixed`` places T coordinates in the Earth-fixed frame G. Two placements:
``"tangent_plane"`` (Kiev 2012 eq 27: ρ_iT = C_IT ρ*_I − r_iT, the landmark offset lives in the
flat T frame) and ``"sphere"`` (east/north taken as arc lengths on a sphere, z as height; what
a real terrain does). The catalogue error model is ``catalogue_errors``: independent
N(0, σP²) per axis and landmark (Kiev 2012 disturbance model), fixed over a pass.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputValueError

__all__ = ["kiev_m1_m4", "grid", "random_field", "to_earth_fixed", "catalogue_errors"]


def kiev_m1_m4() -> np.ndarray:
    """The seminar's M1..M4 in T coordinates (m), shape (4, 3)."""
    return np.array([[50e3, 0.0, 50.0], [0.0, 50e3, 100.0], [-50e3, 0.0, -20.0], [0.0, -50e3, -80.0]])


def grid(n: int, half_width_m: float, height_m: float = 0.0) -> np.ndarray:
    """n×n grid over [−w, w]² on the tangent plane at ``height_m``, shape (n², 3)."""
    if n < 1:
        raise InputValueError(f"grid n must be ≥ 1, got {n!r}")
    g = np.linspace(-half_width_m, half_width_m, n) if n > 1 else np.zeros(1)
    xx, yy = np.meshgrid(g, g, indexing="xy")
    return np.stack([xx.ravel(), yy.ravel(), np.full(n * n, float(height_m))], axis=-1)


def random_field(rng: np.random.Generator, n: int, half_width_m: float, height_sigma_m: float = 0.0) -> np.ndarray:
    """``n`` landmarks uniform over [−w, w]², heights N(0, σ²), shape (n, 3)."""
    if n < 1:
        raise InputValueError(f"random_field n must be ≥ 1, got {n!r}")
    xy = rng.uniform(-half_width_m, half_width_m, size=(n, 2))
    h = rng.normal(0.0, height_sigma_m, size=(n, 1)) if height_sigma_m > 0 else np.zeros((n, 1))
    return np.concatenate([xy, h], axis=-1)


def to_earth_fixed(r_t_m: Any, site_g_m: Any, C_GT: Any, placement: str = "tangent_plane") -> np.ndarray:
    """Landmarks from T coordinates ``(M, 3)`` to the Earth-fixed frame G ``(M, 3)``.

    ``C_GT`` maps G → T at the site (rows east, north, up in G axes).
    """
    r_t = np.asarray(r_t_m, dtype=float)
    site = np.asarray(site_g_m, dtype=float)
    if placement == "tangent_plane":
        result: np.ndarray = site + r_t @ C_GT
        return result
    if placement == "sphere":
        radius = np.linalg.norm(site)
        up = C_GT[2]
        horiz = r_t[:, 0:1] * C_GT[0] + r_t[:, 1:2] * C_GT[1]
        dist = np.linalg.norm(horiz, axis=-1, keepdims=True)
        ang = dist / radius
        with np.errstate(invalid="ignore", divide="ignore"):
            dirn = np.where(dist > 0, horiz / np.where(dist > 0, dist, 1.0), 0.0)
        unit = np.cos(ang) * up + np.sin(ang) * dirn
        points: np.ndarray = (radius + r_t[:, 2:3]) * unit
        return points
    raise InputValueError(f"placement must be 'tangent_plane' or 'sphere', got {placement!r}")


def catalogue_errors(rng: np.random.Generator, runs: int, n_landmarks: int, sigma_m: float) -> np.ndarray:
    """Catalogue errors N(0, σP²) per axis, one per landmark and run: shape (runs, M, 3)."""
    return rng.normal(0.0, 1.0, size=(runs, n_landmarks, 3)) * sigma_m
