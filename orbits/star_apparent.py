"""Apparent direction of a star seen from a spacecraft: catalogue place → proper direction in GCRS.

The camera sees a star along its *proper* direction: where the light arrives from, in the
spacecraft's rest frame, expressed in GCRS axes (the project's inertial frame I). From the
catalogue (``orbits.star_catalogue``) to that direction, for a spacecraft at GCRS position r and
velocity v at time t, in the order of the SOFA/ERFA astrometry chain (SOFA "Astrometry Tools",
§3; Explanatory Supplement to the Astronomical Almanac, 3rd ed., Urban & Seidelmann 2013, §7.2):

1. **Space motion to the epoch** (``StarCatalogue.propagate``: ERFA ``pmsafe``): the star's
   barycentric direction u and parallax ϖ at t, so its BCRS position is P = u / ϖ (au, ϖ in rad).
2. **Parallax**: the observer's BCRS position is b = b_E + r (Earth's barycentre position from
   ERFA ``epv00``, plus the spacecraft's geocentric position; a Galilean sum, the GCRS/BCRS
   scale difference ~1e-8 is far below a µas here). The coordinate direction is
   p = (P − b)/‖P − b‖: annual parallax ≤ ϖ (≤ 0.8″, α Cen), the spacecraft's own offset
   from the geocentre ≤ ‖r‖ ϖ/au ≤ 0.04 mas.
3. **Light deflection by the Sun** (ERFA ``ld``, Expl. Suppl. eq 7.64): with e the Sun →
   observer unit vector at distance E (au) and q the Sun → star direction,
   p₁ = p + (2 GM☉/(c² E)) (e (p·q) − q (p·e)) / (1 + q·e) — 1.75″ at the limb, 4.07 mas
   at 90° from the Sun, and still 2.3 mas at 120°: modelled.
4. **Aberration** (ERFA ``ab``, Expl. Suppl. eq 7.40, rigorous): with V = (v_E + v)/c the
   observer's barycentric velocity in units of c and β⁻¹ = √(1 − V²),
   p₂ = (β⁻¹ p₁ + (1 + p₁·V/(1 + β⁻¹)) V) / (1 + p₁·V) (normalised) — annual aberration
   ≤ 20.5″ (Earth's ~30 km/s) and orbital aberration ≤ 5.3″ (~7.6 km/s in LEO), both from
   one total velocity so their cross terms are kept.

The Earth's state comes from ``epv00``, which is astropy's ``builtin`` solar-system ephemeris
(what ``get_body_barycentric_posvel(..., ephemeris="builtin")`` evaluates).
DECISION: ``epv00`` is called directly (one call gives Earth's barycentric state and its
heliocentric position; the result does not depend on a user's ``solar_system_ephemeris``
setting); its velocity error against DE405 is ≤ 4.9 mm/s, i.e. ≤ 3.4 µas of aberration.
``erfa.apcs`` assembles steps 2–4's observer quantities (b, e, E, V, β⁻¹) exactly as astropy's
ICRS → GCRS transformation does, so ``tests/orbits/test_star_apparent.py`` can hold this module
against astropy's full route (``SkyCoord.apply_space_motion`` → ``GCRS(obsgeoloc, obsgeovel)``)
to 1 mas; they agree to ~1e-3 mas. What neither models — the Earth's and planets' light
deflection, radial velocities, the user's velocity error — is bounded in ``docs/stars.md``.

Everything broadcasts: ``apparent_directions(catalogue, observer)`` gives every star at every
epoch ``(E, S, 3)``; with ``star_index`` and ``epoch_index`` it gives the pairs asked for (the
star-frame simulator evaluates only the stars in each field).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .star_catalogue import StarCatalogue, StarCatalogueError

__all__ = ["ObserverStates", "observer_states", "apparent_directions", "SUN_DEFLECTION_LIMITER"]

#: ERFA ``ld``'s deflection limiter (astropy's value): acts only within ~0.06° of the Sun's centre,
#: inside the solar disc, where no star frame is taken
SUN_DEFLECTION_LIMITER = 1e-6


@dataclass(frozen=True)
class ObserverStates:
    """The observer at E epochs: TDB dates ``(E,)`` and ERFA's astrometry context ``astrom`` ``(E,)``
    (fields ``eb`` barycentric position (au), ``eh``/``em`` heliocentric direction and distance,
    ``v`` barycentric velocity / c, ``bm1`` = √(1 − ‖v‖²); see ``erfa.apcs``)."""

    tdb_jd1: np.ndarray
    tdb_jd2: np.ndarray
    astrom: np.ndarray

    def __len__(self) -> int:
        return int(self.tdb_jd1.size)


def observer_states(times: Any, r_gcrs_m: Any, v_gcrs_m_s: Any) -> ObserverStates:
    """The observer's barycentric state at ``times`` (astropy ``Time``, any scale, shape ``(E,)`` or
    scalar) for a spacecraft at GCRS position ``r_gcrs_m`` ``(E, 3)`` and velocity ``v_gcrs_m_s``
    ``(E, 3)`` (m, m/s); the ground observer of astropy's GCRS is r = v = 0."""
    import erfa
    from astropy.time import Time

    t = Time(times)
    tdb = t.tdb.reshape(-1)
    n = tdb.size
    r = np.asarray(r_gcrs_m, dtype=float).reshape(-1, 3) if np.size(r_gcrs_m) else np.zeros((0, 3))
    v = np.asarray(v_gcrs_m_s, dtype=float).reshape(-1, 3) if np.size(v_gcrs_m_s) else np.zeros((0, 3))
    for name, a in (("r_gcrs_m", r), ("v_gcrs_m_s", v)):
        if a.shape != (n, 3):
            raise StarCatalogueError(f"observer_states: {name} must be (E, 3) = ({n}, 3) for {n} epoch(s), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise StarCatalogueError(
                f"observer_states: {name} has a non-finite value at epoch {int(np.argmin(np.isfinite(a).all(-1)))}"
            )
    jd1, jd2 = np.asarray(tdb.jd1, float), np.asarray(tdb.jd2, float)
    earth_helio, earth_bary = erfa.epv00(jd1, jd2)
    pv = np.empty(n, erfa.dt_pv)
    pv["p"], pv["v"] = r, v
    astrom = erfa.apcs(jd1, jd2, pv, earth_bary, earth_helio["p"])
    return ObserverStates(jd1, jd2, np.asarray(astrom))


def apparent_directions(
    catalogue: StarCatalogue, observer: ObserverStates, star_index: Any = None, epoch_index: Any = None
) -> np.ndarray:
    """Proper directions (GCRS unit vectors) of catalogue stars seen by the observer (module docstring).

    Without indices: every star at every epoch, ``(E, S, 3)``. With ``star_index`` and
    ``epoch_index`` (integer arrays that broadcast together, e.g. ``(K,)`` pairs): ``(..., 3)``.
    """
    import erfa

    if star_index is None and epoch_index is None:
        star_index = np.arange(len(catalogue))[None, :]
        epoch_index = np.arange(len(observer))[:, None]
    elif star_index is None or epoch_index is None:
        raise StarCatalogueError("apparent_directions: give both star_index and epoch_index, or neither")
    si, ei = np.asarray(star_index), np.asarray(epoch_index)  # broadcast by the ufuncs, never materialised
    a = {k: observer.astrom[k][ei] for k in ("eb", "eh", "em", "v", "bm1")}
    ra, dec, px_mas = catalogue.propagate(observer.tdb_jd1[ei], observer.tdb_jd2[ei], si)
    distance_au = 1.0 / (px_mas * (np.pi / 180.0 / 3600.0 / 1000.0))  # 1/ϖ, ϖ in rad
    star_au = erfa.s2c(ra, dec) * distance_au[..., None]
    rel = star_au - a["eb"]  # step 2: from the observer
    _, p = erfa.pn(rel)
    _, q = erfa.pn(a["em"][..., None] * a["eh"] + rel)  # Sun → star (the star is ≫ 1 au away: q ≈ p)
    p1 = erfa.ld(1.0, p, q, a["eh"], a["em"], SUN_DEFLECTION_LIMITER)  # step 3
    p2 = erfa.ab(p1, a["v"], a["em"], a["bm1"])  # step 4
    result: np.ndarray = np.asarray(p2)
    return result
