"""``orbits.sight``: the one light-time and aberration implementation (the pushbroom lines' and the frame camera's
landmark rows'), on plain arrays, against independent oracles written here.

Geometry: a spacecraft 505 km above a site at 40° N on 2026-03-01 (astropy's ITRS → GCRS), moving at the circular
speed (7.60 km/s) horizontally, north-east; ground points within ±25 km of the site.

Oracles (each says so): the light time by its own fixed point with the Earth's orientation from astropy at
t − Δt (``itrs_to_gcrs_dcm``: precession, nutation, polar motion, UT1 — not the function's ω_E about z), and the
aberration by the relativistic Lorentz formula (a different model: it differs from the classical velocity
addition by (v/c)² ≈ 6.4e-10 rad).
"""

import numpy as np
import pytest

from orbits import ARCSEC
from orbits.earth import MU_EARTH_M3_S2, itrs_to_gcrs_dcm
from orbits.pushbroom import itrs_from_geodetic
from orbits.sight import (
    EARTH_SPIN_G_RAD_S,
    SPEED_OF_LIGHT_M_S,
    SightCorrections,
    apparent_sight_i,
    earth_turn,
    remove_aberration,
)

EPOCH = "2026-03-01T10:00:00"
LAT, LON = np.radians(40.0), np.radians(9.0)
ALTITUDE_M = 505e3


def _geometry(n=40, seed=3):
    """(t, r (3,), v (3,), C_GI (3, 3), ground points (n, 3) in G)."""
    from astropy.time import Time

    t = Time(EPOCH, scale="utc")
    C_GI = itrs_to_gcrs_dcm(t)
    site_up = itrs_from_geodetic(LAT, LON, ALTITUDE_M)
    r = C_GI @ site_up
    up = r / np.linalg.norm(r)
    north_g = np.array([-np.sin(LAT) * np.cos(LON), -np.sin(LAT) * np.sin(LON), np.cos(LAT)])
    east_g = np.array([-np.sin(LON), np.cos(LON), 0.0])
    heading = C_GI @ (north_g + east_g) / np.sqrt(2)
    heading -= (heading @ up) * up
    v = np.sqrt(MU_EARTH_M3_S2 / np.linalg.norm(r)) * heading / np.linalg.norm(heading)
    rng = np.random.default_rng(seed)
    dlat, dlon = rng.uniform(-1, 1, (2, n)) * 25e3 / 6.37e6
    g = itrs_from_geodetic(LAT + dlat, LON + dlon / np.cos(LAT), rng.uniform(0, 2000, n))
    return t, r, v, C_GI, g


def _oracle_light_time(t, r, g, passes=6):
    """TEST ORACLE: the point where the light left it, C_GI(t − Δt) g with astropy's Earth orientation at t − Δt,
    Δt = |C_GI(t − Δt) g − r|/c by 6 passes of its own fixed point (contraction 1.5e-6)."""
    from astropy import units as u

    dt = np.zeros(g.shape[0])
    for _ in range(passes):
        C = itrs_to_gcrs_dcm(t - dt * u.s)
        p = np.einsum("kij,kj->ki", C, g)
        dt = np.linalg.norm(p - r, axis=-1) / SPEED_OF_LIGHT_M_S
    return p, dt


def _oracle_relativistic_aberration(n, v):
    """TEST ORACLE: the apparent direction n′ of a source seen along the unit n by an observer moving at v, by the
    Lorentz transformation of the photon's velocity: n′ = (n/γ + β + γ/(γ + 1) (β·n) β) / (1 + β·n)."""
    beta = v / SPEED_OF_LIGHT_M_S
    gamma = 1 / np.sqrt(1 - beta @ beta)
    bn = n @ beta
    out = (n / gamma + beta + (gamma / (gamma + 1)) * bn[:, None] * beta) / (1 + bn)[:, None]
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _angle(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def test_light_time_against_a_brute_force_loop_on_astropys_earth():
    """Light time alone: the direction to where the point was equals the oracle's to 2e-11 rad (measured 3.0e-12), the
    light time to 1e-15 s (measured 2.9e-16). The bound: ω_E about
    z against astropy's rotation over Δt ≈ 1.7 ms differs by polar motion (≤ 2.4e-6 rad of axis) and the length of
    day, ≤ 2e-6 m on the ground (4e-12 rad at 505 km), plus the oracle's own Δt converged to 1e-18 s. The effect is
    real and of the stated size: the point moves by ω ρ Δt ≈ 0.6 m (ρ its distance from the axis, ≈ R cos 40°: 0.25″
    at 505 km), and turning the Earth the wrong way (forward in time) misses the oracle by twice that, 2.4e-6 rad."""
    t, r, v, C_GI, g = _geometry()
    sight = apparent_sight_i(r, v, C_GI, g, EARTH_SPIN_G_RAD_S, SightCorrections(light_time=True, aberration=False))
    p, dt = _oracle_light_time(t, r, g)
    oracle = (p - r) / np.linalg.norm(p - r, axis=-1, keepdims=True)
    assert np.max(_angle(sight.direction_i, oracle)) < 2e-11
    assert np.max(np.abs(sight.light_time_s - dt)) < 1e-15
    assert np.all((dt > 1.67e-3) & (dt < 1.69e-3))  # 503-506 km: heights 0-2 km, offsets ≤ 35 km
    geometric = apparent_sight_i(r, v, C_GI, g, corrections=SightCorrections(False, False)).direction_i
    moved_m = np.linalg.norm(p - np.einsum("ij,kj->ki", C_GI, g), axis=-1)
    np.testing.assert_allclose(moved_m, EARTH_SPIN_G_RAD_S[2] * np.linalg.norm(g[:, :2], axis=-1) * dt, rtol=1e-5)
    assert np.all((moved_m > 0.59) & (moved_m < 0.61))
    assert 0.2 * ARCSEC < np.min(_angle(geometric, oracle)) and np.max(_angle(geometric, oracle)) < 0.3 * ARCSEC
    wrong_way = earth_turn(EARTH_SPIN_G_RAD_S, g, +dt)  # the Earth turned forward: what a sign slip would do
    d_wrong = np.einsum("ij,kj->ki", C_GI, wrong_way) - r
    assert np.min(_angle(d_wrong, oracle)) > 1e-6


def test_aberration_against_the_relativistic_formula_and_its_size():
    """Light time and aberration: equal to the oracle's relativistic aberration of its light-time direction to 5e-10
    rad (the classical addition differs from it by at most (v/c)²/2 ≈ 3.2e-10 rad; measured 2.1e-11); the aberration
    is |v⊥|/c, ≈ 5.2″ for 7.60 km/s across a near-nadir line of sight (measured 5.23-5.24″), toward the velocity;
    ``remove_aberration`` inverts it to 1e-11 (the light-time direction recovered)."""
    t, r, v, C_GI, g = _geometry()
    sight = apparent_sight_i(r, v, C_GI, g)
    p, _ = _oracle_light_time(t, r, g)
    n = (p - r) / np.linalg.norm(p - r, axis=-1, keepdims=True)
    oracle = _oracle_relativistic_aberration(n, v)
    assert np.max(_angle(sight.direction_i, oracle)) < 5e-10
    size = _angle(sight.direction_i, n)
    v_perp = np.linalg.norm(v - (n @ v)[:, None] * n, axis=-1)
    np.testing.assert_allclose(size, v_perp / SPEED_OF_LIGHT_M_S, rtol=1e-4)
    assert np.all((size > 5.15 * ARCSEC) & (size < 5.3 * ARCSEC))
    assert np.all(np.sum((sight.direction_i - n) * v, axis=-1) > 0)  # toward the velocity, not away
    assert np.max(np.abs(remove_aberration(sight.direction_i, v) - n)) < 1e-11
    # and the test can fail: the velocity subtracted instead of added misses by twice the size
    wrong = SPEED_OF_LIGHT_M_S * n - v
    assert np.min(_angle(wrong, oracle)) > 9 * ARCSEC


@pytest.mark.parametrize("corrections", [SightCorrections(), SightCorrections(False, False), SightCorrections(True, False)])
def test_a_batch_equals_each_exposure_on_its_own(corrections):
    """Broadcasting: (R, K) exposures × points at once equal each (r, v, C_GI, point) alone, to round-off; C_GI (K, 3,
    3) broadcasts against a run axis as the data model's image table does."""
    _, r, v, C_GI, g = _geometry(n=6)
    rng = np.random.default_rng(5)
    R = np.stack([r + rng.normal(0, 5.0, (6, 3)) for _ in range(3)])  # (3, 6, 3): GNSS-like differences per run
    V = np.broadcast_to(v, R.shape)
    C = np.broadcast_to(C_GI, (6, 3, 3))
    batch = apparent_sight_i(R, V, C, g, EARTH_SPIN_G_RAD_S, corrections)
    for a in range(3):
        for k in range(6):
            one = apparent_sight_i(R[a, k], V[a, k], C[k], g[k], EARTH_SPIN_G_RAD_S, corrections)
            np.testing.assert_allclose(batch.direction_i[a, k], one.direction_i, rtol=0, atol=1e-15)
            np.testing.assert_allclose(batch.light_time_s[a, k], one.light_time_s, rtol=0, atol=1e-18)


def test_aberration_without_a_velocity_is_refused():
    from orbits.errors import InputValueError

    _, r, _, C_GI, g = _geometry(n=2)
    with pytest.raises(InputValueError, match="needs the spacecraft's velocity"):
        apparent_sight_i(r, None, C_GI, g)
    assert apparent_sight_i(r, None, C_GI, g, corrections=SightCorrections(True, False)).direction_i.shape == (2, 3)
