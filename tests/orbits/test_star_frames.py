"""orbits.star_frames: star frames from the measurement chain, the centroid-noise law, false detections."""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from builders import synthetic_sky
from star_camera import CAMERA, THETA

from orbits.camera import project
from orbits.orbit import CircularOrbit
from orbits.rotations import misalignment_dcm, rotvec_dcm
from orbits.star_apparent import apparent_directions, observer_states
from orbits.star_catalogue import StarCatalogueError
from orbits.star_frames import (
    KIND_FALSE,
    KIND_HOT_PIXEL,
    KIND_STAR,
    CentroidNoise,
    StarDetector,
    camera_attitude,
    in_earth_shadow,
    inertial_hold,
    simulate_star_frames,
    slew,
    zenith_pointing,
)


def _away_from_earth(rng, F, orbit):
    """F epochs, states, and inertial holds whose boresight is > 100° from nadir (clear of the Earth)."""
    t = Time("2026-03-01", scale="utc") + np.sort(rng.uniform(0, 20, F)) * u.day
    r, v = orbit.state(rng.uniform(0, 2 * np.pi, F))
    up = r / np.linalg.norm(r, axis=1, keepdims=True)
    b = rng.normal(size=(F, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b = np.where(np.sum(b * up, axis=1, keepdims=True) < 0.2, -b, b)
    b = np.where(np.sum(b * up, axis=1, keepdims=True) < 0.2, up, b)
    C_IE = inertial_hold(np.degrees(np.arctan2(b[:, 1], b[:, 0])), np.degrees(np.arcsin(b[:, 2])), rng.uniform(0, 360, F))
    return t, r, v, C_IE


def test_noise_free_frames_are_the_measurement_chain():
    """With no noise every detected star sits at project(C_IK e), C_IK = exp(−Φ(θ)) C_SK,nom C_ES C_IE."""
    rng = np.random.default_rng(1)
    sky = synthetic_sky(rng)
    t, r, v, C_IE = _away_from_earth(rng, 20, CircularOrbit(600e3, np.radians(97.8)))
    C_ES = rotvec_dcm(np.radians([30.0, -20.0, 100.0]))
    det = StarDetector(centroid=CentroidNoise(0.0, 6.0, 0.0), sigma_magnitude=0.0)
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, THETA, det, rng, C_ES=C_ES)
    assert np.allclose(fr.C_IK, misalignment_dcm(THETA) @ C_ES.T @ C_ES @ C_IE, atol=1e-15)
    stars = fr.mask & (fr.kind == KIND_STAR)
    assert stars.sum() > 100
    f, d = np.nonzero(stars)
    e = apparent_directions(sky, observer_states(t, r, v), sky.index_of(fr.hip[f, d]), f)
    xy = project(np.einsum("kij,kj->ki", fr.C_IK[f], e), CAMERA.focal_length_m)
    assert np.max(np.abs(fr.xy_m[f, d] - xy)) < 1e-15
    assert np.array_equal(fr.xy_m[stars], fr.xy_true_m[stars])
    assert np.all(np.abs(fr.xy_m[stars]) <= CAMERA.half_width_m)
    assert np.all(fr.magnitude[stars] == sky.magnitude_hp[sky.index_of(fr.hip[stars])])
    assert np.all(sky.magnitude_hp[sky.index_of(fr.hip[stars])] <= det.mag_limit_hp)


def test_the_earth_hides_the_stars_behind_it():
    rng = np.random.default_rng(2)
    sky = synthetic_sky(rng)
    orbit = CircularOrbit(600e3, np.radians(97.8))
    t, r, v, _ = _away_from_earth(rng, 10, orbit)
    down = -r / np.linalg.norm(r, axis=1, keepdims=True)
    C_IE = inertial_hold(np.degrees(np.arctan2(down[:, 1], down[:, 0])), np.degrees(np.arcsin(down[:, 2])))
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, THETA, StarDetector(), rng)
    assert not np.any(fr.mask & (fr.kind == KIND_STAR))


def test_centroid_noise_follows_the_stated_law():
    """σ(m) = √(σ_floor² + (σ_ref 10^(0.2 (m − m_ref)))²); the simulated errors divided by σ(m) have
    unit standard deviation: with N ≈ 2 × 600 normalised errors the sample σ is within
    5/√(2N) ≈ 0.10 of 1 (5σ of its sampling error)."""
    law = CentroidNoise(1.3e-6, 6.0, 0.3e-6)
    assert law.sigma_m(6.0) == pytest.approx(np.hypot(0.3e-6, 1.3e-6))
    assert law.sigma_m(11.0) / law.sigma_m(6.0) == pytest.approx(10.0 * np.hypot(0.3e-6 / 10, 1.3e-6) / np.hypot(0.3e-6, 1.3e-6))
    with pytest.raises(StarCatalogueError, match="sigma_reference_m must be a finite number ≥ 0"):
        CentroidNoise(-1.0)
    rng = np.random.default_rng(3)
    sky = synthetic_sky(rng)
    t, r, v, C_IE = _away_from_earth(rng, 100, CircularOrbit(600e3, np.radians(97.8)))
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, THETA, StarDetector(centroid=law), rng)
    stars = fr.mask & (fr.kind == KIND_STAR)
    z = (fr.xy_m[stars] - fr.xy_true_m[stars]) / law.sigma_m(sky.magnitude_hp[sky.index_of(fr.hip[stars])])[:, None]
    n = z.size
    assert n > 1000
    assert abs(np.std(z) - 1.0) < 5 / np.sqrt(2 * n)


def test_false_detections_and_hot_pixels():
    """False detections: Poisson with mean λ per frame, so F λ ± 5 √(F λ) in all; hot pixels in
    every frame at their fixed positions; every frame's detections shuffled (kinds interleave)."""
    rng = np.random.default_rng(4)
    sky = synthetic_sky(rng)
    F, lam = 200, 2.0
    t, r, v, C_IE = _away_from_earth(rng, F, CircularOrbit(600e3, np.radians(97.8)))
    hot = [[0.01, 0.02], [-0.03, 0.005]]
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, THETA, StarDetector(false_per_frame=lam, hot_pixels_xy_m=hot), rng)
    n_false = np.sum(fr.mask & (fr.kind == KIND_FALSE))
    assert abs(n_false - F * lam) < 5 * np.sqrt(F * lam)
    is_hot = fr.mask & (fr.kind == KIND_HOT_PIXEL)
    assert np.all(is_hot.sum(axis=1) == 2)
    assert np.array_equal(np.unique(fr.xy_m[is_hot], axis=0), np.unique(hot, axis=0))
    assert np.all(fr.hip[fr.mask & (fr.kind != KIND_STAR)] == -1)
    first_kind = fr.kind[:, 0]
    assert len(set(first_kind.tolist())) > 1  # not stars first, then false, then hot


def test_attitude_helpers():
    C = inertial_hold(30.0, 40.0, 0.0)
    b = -C[2]
    assert np.allclose(
        b,
        [
            np.cos(np.radians(40)) * np.cos(np.radians(30)),
            np.cos(np.radians(40)) * np.sin(np.radians(30)),
            np.sin(np.radians(40)),
        ],
    )
    assert C[0, 2] > 0  # x_E towards the north pole at roll 0
    C1 = inertial_hold(31.0, 40.0, 10.0)
    path = slew(C, C1, [0.0, 0.5, 1.0])
    assert np.allclose(path[0], C) and np.allclose(path[-1], C1)
    assert np.allclose(camera_attitude(C, THETA), misalignment_dcm(THETA) @ C)


def test_the_sun_blinds_a_frame_and_the_night_side_is_in_shadow():
    """A boresight within the Sun exclusion (30°) detects no star; the Earth's cylindrical shadow is
    behind the Earth from the Sun; zenith pointing looks along +r."""
    rng = np.random.default_rng(6)
    sky = synthetic_sky(rng)
    t = Time(["2026-03-20T12:00:00"] * 2, scale="utc")
    r = np.array([[7e6, 0.0, 0.0], [-7e6, 0.0, 0.0]])
    v = np.array([[0.0, 7.5e3, 0.0], [0.0, -7.5e3, 0.0]])
    sun = -observer_states(t, r, v).astrom["eh"]
    near_sun = rotvec_dcm(np.cross(sun[0], [0, 0, 1.0]) / np.linalg.norm(np.cross(sun[0], [0, 0, 1.0])) * np.radians(20)) @ sun[0]
    far = -sun[0]
    b = np.stack([near_sun, far])
    C_IE = inertial_hold(np.degrees(np.arctan2(b[:, 1], b[:, 0])), np.degrees(np.arcsin(b[:, 2])))
    r_clear = 7e6 * np.stack([near_sun, far])  # boresight straight up: the Earth never in the way
    fr = simulate_star_frames(sky, CAMERA, t, r_clear, v, C_IE, THETA, StarDetector(), rng)
    assert fr.sun_blinded.tolist() == [True, False]
    stars = fr.mask & (fr.kind == KIND_STAR)
    assert stars[0].sum() == 0 and stars[1].sum() > 0
    shadow = in_earth_shadow(
        7e6 * np.stack([sun[0], -sun[0], np.cross(sun[0], [0, 0, 1.0]) / np.linalg.norm(np.cross(sun[0], [0, 0, 1.0]))]), sun[0]
    )
    assert shadow.tolist() == [False, True, False]
    C = zenith_pointing(r, v)
    assert np.allclose(-C[:, 2], r / 7e6) and np.allclose(C[:, 0], v / 7.5e3)
