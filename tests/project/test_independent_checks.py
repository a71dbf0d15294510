"""Independent checks added by the test-suite audit: each derives its reference without the
library's formulas, so a sign, axis or factor slip shared by the simulator and the estimator
(which the round-trip tests cannot see) fails here.

* Eq 28 case (Kiev 2012; ``scenarios/kiev2012-sensitivity.toml``): the one-image linear
  covariance of the unit-weight image-plane least squares, rebuilt from the collinearity
  equations (eq 3) by finite differences on a hand-made geometry, against
  ``boresight.studies.sensitivity.linear_sensitivities`` (every source and axis).
* The star-tracker error model (digest "Disturbance model", A_meas = (E + Φ(δ)) A, δ in
  star-tracker axes): with one image θ̂ − θ = C_SK δ exactly to first order, whatever the
  geometry — checked per run with unequal σβ per axis and a rotated mount, so a transposed
  mount, a flipped δ or permuted axes fail.
* ``disturbances.error_jacobians``: the residual caused by each drawn error equals J · error
  to second order (halving the errors quarters the remainder), per run — a sign/frame check
  that a variance test with isotropic σ cannot make.
* Per-axis star-tracker σβ in the draws (unequal σ; χ² interval per axis).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

import boresight
import orbits
from boresight.core.algorithms.image_plane import linearize
from boresight.core.disturbances import error_jacobians
from boresight.observations.model import from_measurements
from boresight.studies import sensitivity as se

SENS = "scenarios/kiev2012-sensitivity.toml"
AS = np.pi / 180 / 3600  # one arcsecond in rad, written out (not the library's constant)


# ---------------------------------------------------------------- hand-made rotations


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rodrigues(v):
    """exp(Φ(v)) by Rodrigues' formula."""
    a = np.linalg.norm(v)
    if a == 0.0:
        return np.eye(3)
    k = v / a
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * K @ K


def _c_sk(mount_deg):
    """C_SK = C_ESᵀ for a mount given as intrinsic Z-Y-X Euler angles of C_ES (docs/assumptions.md)."""
    z, y, x = np.radians(mount_deg)
    return _rz(z) @ _ry(y) @ _rx(x)


# ---------------------------------------------------------------- eq 28, first principles


def _eq28_first_principles(yaw_rad=0.0):
    """σθ (″) and per-source a_is of the unit-weight LS for one nadir image of the eq 28 case.

    Geometry (scenario file, t = 0): spacecraft 680 km above the site, boresight −z_K on the
    nadir, four landmarks at (±13 km, 0) and (0, ±13 km) in the site's east/north/up frame with
    heights 50, 100, −20, −80 m; F = 2.2 m. The camera's yaw about the boresight is free (the
    cross is 4-fold symmetric; the result does not depend on it — checked by the caller).
    """
    F, H = 2.2, 680e3
    L = np.array([[13e3, 0, 50], [0, 13e3, 100], [-13e3, 0, -20], [0, -13e3, -80]], float)
    r = np.array([0.0, 0.0, H])
    C_TK = _rz(yaw_rad).T
    C_SK = _c_sk((59.0, 19.0, 132.2))

    def image(theta=np.zeros(3), dk=np.zeros(3), dr=np.zeros(3), dL=np.zeros((4, 3))):
        C = _rodrigues(-theta) @ _rodrigues(dk) @ C_TK  # eq 24 for θ; a star-tracker error turns the predicted frame
        s = (L + dL - (r + dr)) @ C.T
        return (-F * s[:, :2] / s[:, 2:3]).ravel()  # eq 3

    def jac(f, n, h):
        return np.stack([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(n)], axis=-1)

    G = jac(lambda t: image(theta=t), 3, 1e-7)
    A = np.linalg.solve(G.T @ G, G.T)  # unit-weight LS gain (eq 22)
    J = {
        "K": np.eye(8),  # ″ per m of pixel noise
        "R": jac(lambda d: image(dr=d), 3, 1e-2),
        "P": np.concatenate([jac(lambda d, m=m: image(dL=np.eye(4)[m][:, None] * d), 3, 1e-2) for m in range(4)], axis=1),
    }
    for j in range(3):  # β_j: 1″ on star-tracker axis j
        J[f"beta{j + 1}"] = jac(lambda d, j=j: image(dk=C_SK[:, j] * d[0] * AS), 1, 1.0)
    a = {s: np.sqrt(np.diag((A @ Js) @ (A @ Js).T)) / AS for s, Js in J.items()}
    sig = {"K": 3e-6, "R": 15.0, "P": 0.1, "beta1": 4.0, "beta2": 4.0, "beta3": 4.0}
    total = np.sqrt(sum((a[s] * sig[s]) ** 2 for s in a))
    return total, a


def test_eq28_one_image_linear_covariance_from_first_principles():
    ours, a = _eq28_first_principles()
    ours_yawed, _ = _eq28_first_principles(np.radians(37.0))
    np.testing.assert_allclose(ours_yawed, ours, rtol=1e-6)  # the camera's yaw does not matter
    t = se.linear_sensitivities(SENS, ["image_plane"])
    lib = np.array(t.meta["sigma_theta_arcsec"]["image_plane"][:3])
    # 6.06, 6.06, 8.41″ (docs/reproduction.md, case A "linear"); the seminar's 6.09, 6.09, 8.36
    np.testing.assert_allclose(lib, ours, rtol=2e-3)
    np.testing.assert_allclose(ours, [6.06, 6.06, 8.41], atol=0.01)
    for s in se.SOURCES:
        row = t[(t["method"] == "analytic") & (t["algorithm"] == "image_plane") & (t["source"] == s)][0]
        got = np.array([row["coef_x"], row["coef_y"], row["coef_z"]])
        # tolerance relative to the row's largest entry: a near-zero entry (R on z) is FD noise
        np.testing.assert_allclose(got, a[s], rtol=0, atol=2e-3 * a[s].max(), err_msg=s)


# ---------------------------------------------------------------- star tracker: θ̂ − θ = C_SK δ


def _star_tracker_only(sigma_arcsec, runs, seed, theta=(30.0, -20.0, 50.0)):
    sc = orbits.load_scenario(SENS)
    sc = replace(
        sc,
        theta_true_arcsec=theta,
        theta_sigma0_arcsec=0.0,
        sigma_pixel_m=0.0,
        sigma_gnss_m=0.0,
        sigma_catalogue_m=0.0,
        sigma_star_tracker_arcsec=tuple(sigma_arcsec),
    )
    return sc, boresight.simulate(sc, np.random.default_rng(np.random.SeedSequence(seed)), runs=runs)


def test_one_image_star_tracker_error_passes_into_theta_as_c_sk_delta():
    _, obs = _star_tracker_only((2.0, 4.0, 8.0), runs=6, seed=20240)
    est = boresight.estimate(obs, algorithm="image_plane")
    err = est.theta.to_value("arcsec") - np.array([30.0, -20.0, 50.0])
    delta = obs.truth["delta_rad"][:, 0] / AS  # (R, 3), star-tracker axes
    C_SK = _c_sk((59.0, 19.0, 132.2))
    expect = delta @ C_SK.T
    # second order: θ × δ / 2 ≈ 2.9e-4 × 9″ ≈ 3e-3″; the smallest wrong answer differs by > 1″
    assert np.abs(err - expect).max() < 0.01, (err, expect)
    for wrong in (-expect, delta @ C_SK, delta):  # flipped δ, transposed mount, mount ignored
        assert np.abs(err - wrong).max() > 1.0


def test_star_tracker_draws_have_each_axis_sigma():
    """Per-axis σβ = (1, 4, 9)″: each axis's sample variance in its 99.9 % χ² interval, a swap of
    axes or a factor 2 in σ outside it."""
    sc, _ = _star_tracker_only((1.0, 4.0, 9.0), runs=2, seed=0)
    n = 4000
    d = orbits.draw_scenario_errors(sc, np.random.default_rng(np.random.SeedSequence(77)), n)["delta_rad"][:, 0] / AS
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n) / n  # known zero mean: Σ d² / σ² ~ χ²(n)
    for j, s in enumerate((1.0, 4.0, 9.0)):
        ratio = np.mean(d[:, j] ** 2) / s**2
        assert lo < ratio < hi, (j, ratio)
        assert not (lo < np.mean(d[:, j] ** 2) / (2 * s) ** 2 < hi)


# ---------------------------------------------------------------- error Jacobians vs the exact model


@pytest.mark.parametrize(
    "source, key", [("star_tracker", "delta_rad"), ("gnss", "gnss_error_m"), ("catalogue", "catalogue_error_m")]
)
def test_error_jacobians_match_the_exact_residuals_to_second_order(source, key):
    sc = orbits.load_scenario(SENS)
    sc = replace(
        sc,
        theta_true_arcsec=(30.0, -20.0, 50.0),
        theta_sigma0_arcsec=0.0,
        sigma_pixel_m=0.0,
        sigma_star_tracker_arcsec=(2.0, 4.0, 8.0),
    )
    arrays = orbits.campaign_arrays(sc)
    base = orbits.draw_scenario_errors(sc, np.random.default_rng(np.random.SeedSequence(5)), 4, arrays)
    # only this source on, scaled up so the second-order remainder is measurable
    scale = {"delta_rad": 1e3, "gnss_error_m": 1e2, "catalogue_error_m": 1e3}[key]
    remainders = []
    for f in (1.0, 0.5):
        err = {k: (v * f * scale if k == key else (v if k == "theta_rad" else np.zeros_like(v))) for k, v in base.items()}
        obs = from_measurements(orbits.observe(err, **arrays))
        theta = obs.truth["theta_rad"]
        _, q = linearize(obs, theta)  # measured − predicted at the true θ: only this error, (R, K, 2)
        J = error_jacobians(obs, theta)[source]  # (R, K, 2, 3)
        e = err[key][:, obs.target_index if key == "catalogue_error_m" else obs.image_index]  # each row's error
        pred = np.einsum("rkij,rkj->rki", J, e)
        assert np.abs(q).max() > 1e-7  # a real residual (metres on the focal plane)
        assert np.abs(q - pred).max() < 0.05 * np.abs(q).max(), source  # first order holds ...
        assert np.abs(q + pred).max() > np.abs(q).max()  # ... and the opposite sign would not
        remainders.append(np.abs(q - pred).max())
    # ... to second order: halving the error quarters the remainder
    assert remainders[0] / remainders[1] == pytest.approx(4.0, rel=0.05), remainders


# ---------------------------------------------------------------- the CRLB's prior


def test_crlb_prior_adds_information_one_over_sigma0_squared():
    """Fisher information with a prior σθ0 = data information + E/σθ0² (rad⁻²). With σθ0 = 10′
    (the eq 28 case) the prior is ~1e-4 of the data information and invisible in σθ; at 5″ it
    matters, so a prior entered as 1/σθ0 or in arcsec fails here."""
    from boresight import DisturbanceModel
    from boresight.core.crlb import cramer_rao_bound

    sc = orbits.load_scenario(SENS)
    obs = boresight.simulate(sc, np.random.default_rng(np.random.SeedSequence(3)))
    model = DisturbanceModel.from_scenario(sc)
    th = obs.truth["theta_rad"][0]
    info0 = np.linalg.inv(cramer_rao_bound(obs, model, th).to_value("rad2"))
    for s0 in (5.0, 600.0):
        info = np.linalg.inv(cramer_rao_bound(obs, model, th, prior_sigma_arcsec=s0).to_value("rad2"))
        np.testing.assert_allclose(info - info0, np.eye(3) / (s0 * AS) ** 2, rtol=1e-6, atol=1e-6 / (s0 * AS) ** 2)
    # and at 5″ the prior visibly shrinks the bound (σθz 8.4″ → below 5″)
    sz = np.sqrt(cramer_rao_bound(obs, model, th, prior_sigma_arcsec=5.0).to_value("arcsec2")[2, 2])
    assert sz < 5.0


# ---------------------------------------------------------------- bad input to the public sensor models


@pytest.mark.parametrize(
    "make",
    [
        lambda: orbits.PixelNoise(float("nan")),
        lambda: orbits.GnssErrors(float("inf")),
        lambda: orbits.StarTrackerErrors((float("nan"), 0.0, 0.0)),
    ],
    ids=["pixel-nan", "gnss-inf", "star_tracker-nan"],
)
def test_sensor_models_refuse_non_finite_sigma(make):
    with pytest.raises(ValueError, match=r"sigma.*(nan|inf)"):
        make()


def test_star_tracker_errors_refuse_wrong_number_of_sigmas():
    with pytest.raises(ValueError, match=r"StarTrackerErrors\.sigma_rad.*\(1\.0, 2\.0\)"):
        orbits.StarTrackerErrors((1.0, 2.0))
