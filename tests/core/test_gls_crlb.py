"""Weighted and optimal forms: Monte Carlo covariance vs predicted covariance, GLS vs the
Cramér–Rao bound, the per-image / per-pass nuisance structure, and the seminar's eq 28 case.

Statistical tests use fixed seeds and 99.9 % χ² intervals: with R = 2000 runs and the known
(zero) mean, Σ (err/σ_pred)² ~ χ²(R), so each variance must lie within
[χ²₀.₀₀₀₅(R), χ²₀.₉₉₉₅(R)]/R = [0.899, 1.107] × the prediction — a factor-of-two error in a
variance (or √2 in a σ) fails by a wide margin.
"""

import tomllib

import numpy as np
import pytest
from builders import with_tables
from oracles import image_covariance
from paths import ROOT
from scipy import stats

import orbits
from boresight import DisturbanceModel, estimate, simulate
from boresight.core.crlb import cramer_rao_bound, fisher_information
from boresight.core.disturbances import error_jacobians
from boresight.core.gls.normal_equations import NormalEquations
from orbits import ARCSEC

R = 2000
LO, HI = stats.chi2.ppf([0.0005, 0.9995], R) / R


def scenario(path="scenarios/kiev2012-algorithm1.toml", times=(5.0, 20.0, 35.0, 50.0), **tables):
    d = tomllib.loads((ROOT / path).read_text())
    if times is not None:
        d["passes"][0]["t_s"] = list(times)
    return orbits.scenario_from_dict(with_tables(d, **tables))


FULL = dict(
    pixel={"sigma_m": 3e-6}, gnss={"sigma_m": 15.0}, star_tracker={"sigma_arcsec": [4.0, 4.0, 4.0]}, catalogue={"sigma_m": 1.0}
)


def normalised_variance(est, obs, cov_rad2=None):
    """Per axis: mean over runs of (error/σ_pred)², which is χ²(R)/R under the prediction."""
    err = est.theta.to_value("arcsec") - obs.truth["theta_rad"] / ARCSEC
    var = np.diagonal(est.covariance.to_value("arcsec2") if cov_rad2 is None else cov_rad2, axis1=-2, axis2=-1)
    return np.mean(err**2 / var, axis=0)


@pytest.fixture(scope="module")
def pixel_only():
    sc = scenario(pixel={"sigma_m": 3e-6})
    return sc, simulate(sc, np.random.default_rng(np.random.SeedSequence(2012)), runs=R)


@pytest.mark.parametrize(
    "alg,weighting", [("image_plane", "unit"), ("ground_plane", "unit"), ("unit_vector", "unit"), ("image_plane", "gls")]
)
def test_pixel_noise_monte_carlo_matches_predicted_covariance(pixel_only, alg, weighting):
    sc, obs = pixel_only
    est = estimate(obs, algorithm=alg, weighting=weighting, model=DisturbanceModel.from_scenario(sc))
    ratio = normalised_variance(est, obs)
    assert np.all((ratio > LO) & (ratio < HI)), ratio
    err = est.theta.to_value("arcsec") - obs.truth["theta_rad"] / ARCSEC
    z = err.mean(0) / (err.std(0, ddof=1) / np.sqrt(R))
    assert np.all(np.abs(z) < stats.norm.ppf(0.9995))  # unbiased


def test_unit_weighting_without_model_scales_by_chi2(pixel_only):
    """No model: covariance = (GᵀG)⁻¹ χ²/dof — still right on average for pixel noise."""
    sc, obs = pixel_only
    est = estimate(obs, algorithm="image_plane", weighting="unit")
    assert est.sigma_includes.startswith("scatter only")
    ratio = normalised_variance(est, obs)
    # Per run, err²/σ̂² with σ̂² = σ² χ²(ν)/ν independent of err (linear LS, Gaussian noise) is
    # F(1, ν): mean ν/(ν−2), variance 2ν²(ν−1)/((ν−2)²(ν−4)). The mean over R runs is normal to a
    # good approximation: 99.9 % interval. (ν = 29 here: mean 1.074 ± 0.036; a factor 2 in the
    # covariance gives 0.54 or 2.15, and forgetting χ²/dof altogether gives ~1e-7.)
    nu = int(est.dof[0])
    assert nu == 29 and np.all(est.dof == nu)
    mean = nu / (nu - 2)
    sd = np.sqrt(2 * nu**2 * (nu - 1) / ((nu - 2) ** 2 * (nu - 4)) / R)
    z = stats.norm.ppf(0.9995)
    assert np.all(np.abs(ratio - mean) < z * sd), (ratio, mean, sd)


@pytest.mark.parametrize("modes", [("per_image", "per_image"), ("per_pass", "per_pass"), ("both", "per_image")])
def test_gls_variance_matches_the_cramer_rao_bound(modes):
    st_mode, g_mode = modes
    sc = scenario(
        **{
            **FULL,
            "star_tracker": {**FULL["star_tracker"], "error_mode": st_mode},
            "gnss": {**FULL["gnss"], "error_mode": g_mode},
        }
    )
    obs = simulate(sc, np.random.default_rng(np.random.SeedSequence([7, len(st_mode)])), runs=R)
    model = DisturbanceModel.from_scenario(sc)
    est = estimate(obs, algorithm="image_plane", weighting="gls", model=model)
    crb = cramer_rao_bound(obs.run(0), model, obs.truth["theta_rad"][0]).to_value("arcsec2")
    ratio = normalised_variance(est, obs, np.broadcast_to(crb, (R, 3, 3)))
    assert np.all((ratio > LO) & (ratio < HI)), ratio
    # the GLS χ² is χ²(dof) per run: the sum over runs is χ²(Σ dof)
    total_dof = int(np.sum(est.dof))
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], total_dof)
    assert lo < np.sum(est.chi2) < hi
    if st_mode == "per_pass":
        # unit weighting ignores the shared bias: clearly worse than the bound on θx, θy
        unit = estimate(obs, algorithm="image_plane", weighting="unit", model=model)
        assert np.all(normalised_variance(unit, obs, np.broadcast_to(crb, (R, 3, 3)))[:2] > 2.0)
        assert np.all(normalised_variance(unit, obs)[:2] < HI)  # but its sandwich covariance is honest


@pytest.mark.parametrize("st_mode", ["per_image", "per_pass", "both"])
def test_gls_covariance_equals_dense_fisher_inverse(st_mode):
    """The Schur-complement GLS (per-image whitening + shared nuisances) and the dense Gᵀ Σ⁻¹ G
    route agree to round-off: two algebraic routes to the same first-order covariance."""
    sc = scenario(
        **{
            **FULL,
            "star_tracker": {**FULL["star_tracker"], "error_mode": st_mode},
            "gnss": {**FULL["gnss"], "error_mode": st_mode},
        }
    )
    obs = simulate(sc, np.random.default_rng(8), runs=2)
    model = DisturbanceModel.from_scenario(sc)
    est = estimate(obs, algorithm="image_plane", weighting="gls", model=model)
    info = fisher_information(obs, model, est.theta.to_value("rad"))
    crb = np.linalg.inv(info) / ARCSEC**2
    assert np.allclose(est.covariance.to_value("arcsec2"), crb, rtol=1e-7, atol=1e-9 * np.abs(crb).max())


def test_per_image_pointing_nuisance_is_the_same_gls():
    """A per-image star-tracker error eliminated as a nuisance (Schur complement, prior σβ) equals
    GLS with the per-image covariance; with a flat prior θ is gone (δ_K is the same rotation)."""
    sc = scenario(pixel={"sigma_m": 3e-6}, star_tracker={"sigma_arcsec": [4.0, 4.0, 4.0]})
    obs = simulate(sc, np.random.default_rng(9), runs=3)
    th = obs.truth["theta_rad"]
    model = DisturbanceModel.from_scenario(sc)
    from boresight.core.algorithms.image_plane import linearize

    G, q = linearize(obs, th)
    Gf, qf = G.reshape(3, obs.n_images, -1, 3), q.reshape(3, obs.n_images, -1)
    H = error_jacobians(obs, th)["star_tracker"].reshape(3, obs.n_images, -1, 3)
    nu = NormalEquations()
    nu.update(Gf, qf, np.full(qf.shape, 1 / 3e-6**2), nuisance=H, nuisance_information=np.eye(3) / (4 * ARCSEC) ** 2)
    gls = NormalEquations()
    gls.update(Gf, qf, covariance=image_covariance(obs, th, model))
    a, b = nu.solve(), gls.solve()
    assert np.allclose(a.covariance, b.covariance, rtol=1e-8, atol=0)  # rad²: ~1e-10, below allclose's default atol
    assert np.allclose(a.theta, b.theta, rtol=0, atol=1e-6 * ARCSEC)


def test_per_pass_bias_sets_a_floor_and_per_image_errors_average_down():
    """Per pass, θ and the pass's star-tracker bias δ_K = C_SK δ are the same rotation: the bound
    never drops below C_SK Σβ C_SKᵀ however many images. Per image, it averages as ~1/N."""
    sig = 4.0
    bounds = {}
    for mode in ("per_pass", "per_image"):
        for times in ((20.0,), tuple(np.arange(5.0, 51.0, 5.0))):
            sc = scenario(times=times, pixel={"sigma_m": 3e-6}, star_tracker={"sigma_arcsec": [sig] * 3, "error_mode": mode})
            obs = simulate(sc, np.random.default_rng(10))
            bounds[mode, len(times)] = cramer_rao_bound(
                obs, DisturbanceModel.from_scenario(sc), obs.truth["theta_rad"][0]
            ).to_value("arcsec2")
    floor = sig**2 * obs.C_SK_nominal @ obs.C_SK_nominal.T  # = σβ² E for equal σβ
    assert np.linalg.eigvalsh(bounds["per_pass", 10] - floor).min() > -1e-6
    assert np.linalg.eigvalsh(bounds["per_pass", 1] - floor).min() > -1e-6
    # ten images bring θx, θy down to the floor and no further (within 1 %)
    assert np.allclose(np.diag(bounds["per_pass", 10])[:2], sig**2, rtol=0.01)
    ratio = np.diag(bounds["per_image", 10]) / np.diag(bounds["per_image", 1])
    assert np.all((ratio > 0.05) & (ratio < 0.2)), ratio  # ≈ 1/10


def test_seminar_eq28_case_is_reproduced_by_the_bound():
    """Kiev 2012 eq 28 case (680 km, F = 2.2 m, σβ = 4″, σP = 0.1 m, σR = 15 m, σK = 3 µm, one
    image, four landmarks 13 km from nadir): the seminar gives σθ = 6.09″, 6.09″, 8.36″."""
    sc = orbits.load_scenario("scenarios/kiev2012-sensitivity.toml")
    obs = simulate(sc, np.random.default_rng(11))
    crb = cramer_rao_bound(obs, DisturbanceModel.from_scenario(sc), obs.truth["theta_rad"][0], prior_sigma_arcsec=600.0)
    sigma = np.sqrt(np.diag(crb.to_value("arcsec2")))
    assert np.allclose(sigma, [6.09, 6.09, 8.36], rtol=0.02), sigma


def test_crlb_shapes_and_unobservable_bound():
    sc = scenario(pixel={"sigma_m": 3e-6})
    obs = simulate(sc, np.random.default_rng(12), runs=2)
    model = DisturbanceModel.from_scenario(sc)
    assert cramer_rao_bound(obs, model).shape == (2, 3, 3)
    assert cramer_rao_bound(obs.run(0), model).shape == (3, 3)
    with pytest.raises(ValueError, match="residual covariance is singular — is sigma_pixel_m zero"):
        cramer_rao_bound(obs, DisturbanceModel())


def test_crlb_is_refused_with_its_estimate_before_allocation(monkeypatch):
    """The dense oracle stays dense (on rows: 2K × 2K), but asks the memory budget first: with a budget of
    1 MiB the bound of 2 runs × 16 observations (4 images × 4 landmarks; 2K = 32 components per run;
    0.08 MiB by ``full_covariance_bytes``) fits and 50 runs (1.9 MiB) are refused, the message naming the
    sizes and the estimate; a traced peak far below the estimate shows nothing was allocated first."""
    import tracemalloc

    from boresight.core.crlb import full_covariance_bytes, full_residual_covariance
    from orbits.limits import MemoryBudgetError

    sc = scenario(pixel={"sigma_m": 3e-6}, catalogue={"sigma_m": 1.0})
    obs = simulate(sc, np.random.default_rng(13), runs=50)
    model = DisturbanceModel.from_scenario(sc)
    monkeypatch.setenv("BORESIGHT_MEMORY_BUDGET_GB", str(1 / 1024))
    assert (
        full_covariance_bytes(2, obs.n_observations, obs.n_images, obs.n_targets, 1)
        < 2**20
        < full_covariance_bytes(50, obs.n_observations, obs.n_images, obs.n_targets, 1)
    )
    assert cramer_rao_bound(obs.run(slice(0, 2)), model).shape == (2, 3, 3)
    tracemalloc.start()
    with pytest.raises(
        MemoryBudgetError,
        match=rf"dense residual covariance .* 50 run\(s\) × {obs.n_observations} observations .*4 images, {obs.n_targets} targets"
        r".* would need about 0\.0\d+ GiB",
    ):
        cramer_rao_bound(obs, model)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 0.05 * full_covariance_bytes(50, obs.n_observations, obs.n_images, obs.n_targets, 1)
    with pytest.raises(MemoryBudgetError, match="full_residual_covariance"):
        full_residual_covariance(obs, np.zeros(3), model)
