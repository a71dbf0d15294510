"""How a spacecraft sees a ground point: light time, aberration and refraction of the line of sight.

One implementation for every chain that looks at the ground — the pushbroom lines (``orbits.pushbroom``,
``docs/pushbroom.md``) and the frame camera's landmark rows (``orbits.measurements`` forward,
``boresight.observations.model.ObservationSet.row_target_vectors_i`` backward; ``docs/stars.md``, "One physics
for star and landmark rows"). Its inputs are plain arrays — the spacecraft's position and velocity in I at each
exposure, C_GI (G → I) at that time and the Earth's spin vector in G — so a pushbroom strip (which interpolates
them from its samples) and an image table (which carries them per image) call the same function.

**Light time.** The ground point is where it was when the light left it, r_T,I = C_GI(t − Δt) r_T,G with
Δt = |r_T,I − r_sc|/c (≈ 1.7-2.0 ms from 505 km: the Earth turns the point by ω R cos φ Δt ≈ 0.6 m at 40° N).
The earlier Earth is C_GI(t) turned back by the Earth's spin w Δt, C_GI(t − Δt) = C_GI(t) exp(Φ(−w Δt))
(``earth_turn``), w in G axes given by the caller (a strip: the rotation between its first and last Earth
samples over their span; an image table: ω_E about G's z, ``EARTH_SPIN_G_RAD_S`` — each caller's DECISION is
where it chooses). The fixed point Δt = |C_GI(t − Δt) r_T,G − r_sc|/c contracts by ≈ v_ground/c ≈ 1.5e-6:
two passes are exact to ~1e-12 m.

**Aberration.** The observed direction is the classical velocity addition (Rugged's choice; the relativistic
correction is (v/c)² ≈ 6e-10 rad): c l + v_sc = k o, o = unit(c l + v_sc), with l the geometric unit direction
to the point where the light left it (|v_sc|/c ≈ 2.5e-5 rad ≈ 5″ perpendicular to the line of sight: ≈ 13 m on
the ground at 500 km, mostly along-track). ``remove_aberration`` inverts it exactly:
l = (k o − v)/c with k = o·v + √((o·v)² − |v|² + c²).

**Refraction** (``Refraction``, off by default, as in Rugged): the point seen is displaced from the true
point, horizontally and away from the spacecraft, by a first-order flat-atmosphere law (``Refraction``'s docstring).

``SightCorrections`` switches the three, so a simulator and an estimator switch them together.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from .earth import OMEGA_EARTH_RAD_S, geodetic_from_itrs
from .errors import InputValueError
from .rotations import rotate

__all__ = [
    "SPEED_OF_LIGHT_M_S",
    "EARTH_SPIN_G_RAD_S",
    "LANDMARK_SIGHTS",
    "Refraction",
    "SightCorrections",
    "ApparentSight",
    "apparent_sight_i",
    "earth_turn",
    "remove_aberration",
]

#: the speed of light (m/s), exact (SI)
SPEED_OF_LIGHT_M_S = 299_792_458.0
#: the Earth's spin vector in G (ITRS) axes, ω_E about z (rad/s): the spin an image table uses for light time when
#: it gives none better (``docs/stars.md``, "One physics for star and landmark rows": the bound of this choice)
EARTH_SPIN_G_RAD_S = np.array([0.0, 0.0, OMEGA_EARTH_RAD_S])
EARTH_SPIN_G_RAD_S.setflags(write=False)
#: what a frame camera's landmark row carries (``orbits.measurements.observe``'s ``landmark_sight``, the data
#: model's ``ObservationSet.landmark_sight``): the geometric vector, or light time and aberration (never refraction)
LANDMARK_SIGHTS = ("geometric", "light_time+aberration")
#: fixed-point passes of the light time (contraction ≈ 1.5e-6: two passes are exact to ~1e-12 m)
LIGHT_TIME_PASSES = 2


@dataclass(frozen=True)
class Refraction:
    """Atmospheric refraction to first order in a flat, exponential atmosphere (off by default; ``docs/pushbroom.md``).

    The refractivity falls with height as N(h) = N₀ exp(−h/H). Snell's law in flat layers, n(h) sin z(h) = const,
    bends the ray toward the vertical on its way down; integrating tan z_top − tan z(h) ≈ N(h) sin z / cos³ z over
    the height gives the horizontal displacement of the point seen from the true point,

        Δx = N₀ H exp(−h/H) sin z / cos³ z,

    away from the spacecraft (the straight line the spacecraft looks along meets the ground farther out), with z the
    zenith angle of the line of sight at the point and h its height. The defaults, N₀ = 2.77e-4 (dry air at 550 nm,
    15 °C, 1013.25 hPa) and H = 8.4 km (the density scale height at 288 K), give 4.6 m at z = 45° against the
    published 3-5 m (Noerdlinger 1999; Labriji et al. 2022) and 2.1 m at 30° off-nadir from 505 km. DECISION: the
    first-order flat model — the Earth's curvature changes Δx by ~H tan z / R ≈ 0.1 % here and the weather N₀ and H
    by ~10 %, so the model removes the bulk of a 1 px effect, not its last decimetre.
    """

    refractivity: float = 2.77e-4
    scale_height_m: float = 8_400.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.refractivity) and 0 <= self.refractivity < 1e-3):
            raise InputValueError(f"Refraction.refractivity (n − 1 at sea level) must be in [0, 1e-3), got {self.refractivity!r}")
        if not (np.isfinite(self.scale_height_m) and self.scale_height_m > 0):
            raise InputValueError(f"Refraction.scale_height_m must be > 0, got {self.scale_height_m!r}")

    def displacement_m(self, zenith_rad: Any, height_m: Any) -> np.ndarray:
        """Δx (m) for zenith angles (rad) at the ground and heights (m) above the ellipsoid."""
        z = np.asarray(zenith_rad, float)
        result: np.ndarray = (
            (self.refractivity * self.scale_height_m * np.exp(-np.asarray(height_m, float) / self.scale_height_m))
            * np.sin(z)
            / np.cos(z) ** 3
        )
        return result

    def shift_g(self, point_g_m: Any, spacecraft_g_m: Any) -> np.ndarray:
        """Apparent − true position (..., 3) in G of points seen from the spacecraft (both in G): Δx along the
        horizontal (geodetic) direction away from the spacecraft."""
        point = np.asarray(point_g_m, float)
        lat, lon, h = geodetic_from_itrs(point)
        up = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
        u = np.asarray(spacecraft_g_m, float) - point
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        cos_z = np.sum(u * up, axis=-1)
        away = -(u - cos_z[..., None] * up)
        norm = np.linalg.norm(away, axis=-1, keepdims=True)
        away = np.divide(away, norm, out=np.zeros_like(away), where=norm > 0)
        result: np.ndarray = self.displacement_m(np.arccos(np.clip(cos_z, -1.0, 1.0)), h)[..., None] * away
        return result


@dataclass(frozen=True)
class SightCorrections:
    """How the direction in which the spacecraft sees a ground point is modelled (module docstring): ``light_time``
    (the point where it was when the light left it), ``aberration`` (the spacecraft's velocity added to the light's)
    and ``refraction`` (a ``Refraction``, or None: none). The defaults are Rugged's (``CorrectionsParams``): light time
    and aberration on, refraction off. Every function that takes a point to a line of sight or back
    (``apparent_sight_i``; in ``orbits.pushbroom`` ``apparent_direction_i``, ``line_sight``, ``direct_location``,
    ``inverse_location``, ``locate_on_chips``) takes one, so the simulator, the estimator and the readers switch
    them together."""

    light_time: bool = True
    aberration: bool = True
    refraction: Refraction | None = None


class ApparentSight(NamedTuple):
    """``apparent_sight_i``'s result: ``direction_i`` (..., 3) the unit direction in I in which the spacecraft sees
    each point, ``light_time_s`` (...) the light's travel time Δt (0 without the light-time correction)."""

    direction_i: np.ndarray
    light_time_s: np.ndarray


def earth_turn(earth_spin_g_rad_s: Any, v: Any, dt_s: Any) -> np.ndarray:
    """Vectors (..., 3) of G turned by the Earth's spin w (3,) or (..., 3) (rad/s, G axes) over ``dt_s`` (...):
    C_GI(t + Δt) = C_GI(t) exp(Φ(w Δt)), so C_GI(t − Δt) g = C_GI(t) turn(g, −Δt) and
    C_GI(t − Δt)ᵀ x = turn(C_GI(t)ᵀ x, Δt) (module docstring)."""
    rotvec = np.asarray(earth_spin_g_rad_s, float) * np.asarray(dt_s, float)[..., None]
    rotvec, vec = np.broadcast_arrays(rotvec, np.asarray(v, float))
    result: np.ndarray = rotate(rotvec.reshape(-1, 3), vec.reshape(-1, 3)).reshape(vec.shape)
    return result


def remove_aberration(o: Any, v: Any) -> np.ndarray:
    """The geometric unit direction l (..., 3) of observed unit directions o (..., 3) seen from a spacecraft moving
    at v (..., 3) m/s: c l + v = k o, |l| = 1 (module docstring)."""
    o = np.asarray(o, float)
    v = np.asarray(v, float)
    c = SPEED_OF_LIGHT_M_S
    ov = np.sum(o * v, axis=-1, keepdims=True)
    k = ov + np.sqrt(ov * ov - np.sum(v * v, axis=-1, keepdims=True) + c * c)
    result: np.ndarray = (k * o - v) / c
    return result


def apparent_sight_i(
    r_i_m: Any,
    v_i_m_s: Any,
    C_GI: Any,
    ground_g_m: Any,
    earth_spin_g_rad_s: Any = EARTH_SPIN_G_RAD_S,
    corrections: SightCorrections = SightCorrections(),
) -> ApparentSight:
    """The unit direction in I in which a spacecraft sees ground points, with the ``corrections`` (by default light
    time and aberration, no refraction; module docstring), and the light time.

    ``r_i_m``, ``v_i_m_s`` (..., 3) the spacecraft's position (m) and velocity (m/s) in I at the exposure (the
    velocity is read only with ``corrections.aberration``: None is accepted without it); ``C_GI`` (..., 3, 3)
    G → I at the exposure; ``ground_g_m`` (..., 3) the points in G; ``earth_spin_g_rad_s`` (3,) or (..., 3) the
    Earth's spin in G axes (``EARTH_SPIN_G_RAD_S`` by default). Every argument broadcasts against the others.
    Without corrections the direction is the geometric unit(C_GI r_T,G − r_sc).
    """
    r = np.asarray(r_i_m, float)
    C = np.asarray(C_GI, float)
    g = np.asarray(ground_g_m, float)
    w = np.asarray(earth_spin_g_rad_s, float)

    def emitted(point_g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the point in I when the light left it, Δt): the fixed point of the module docstring."""
        p = np.einsum("...ij,...j->...i", C, point_g)
        dt = np.zeros(np.broadcast_shapes(p.shape, r.shape)[:-1])
        for _ in range(LIGHT_TIME_PASSES if corrections.light_time else 0):
            dt = np.linalg.norm(p - r, axis=-1) / SPEED_OF_LIGHT_M_S
            p = np.einsum("...ij,...j->...i", C, earth_turn(w, point_g, -dt))  # = C_GI(t − Δt) g
        return p, dt

    p, dt = emitted(g)
    if corrections.refraction is not None:  # the point seen, displaced away from the spacecraft (in G at the emission)
        sc_g = earth_turn(w, np.einsum("...ji,...j->...i", C, r), dt)
        p, _ = emitted(g + corrections.refraction.shift_g(g, sc_g))
    d: np.ndarray = p - r
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    if corrections.aberration:
        if v_i_m_s is None:
            raise InputValueError("apparent_sight_i: the aberration needs the spacecraft's velocity v_i_m_s, got None")
        d = SPEED_OF_LIGHT_M_S * d + np.asarray(v_i_m_s, float)
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return ApparentSight(d, dt)
