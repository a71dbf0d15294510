"""A row's own pixel σ (``ObservationSet.sigma_xy_m``) in the error structure and the one GLS.

The GLS of a set whose rows carry their own σ must equal an independently weighted oracle
(``tests/oracles.py:row_sigma_gls_reference``: each row's σ read there, Σ = diag(σ_k²) + U V Uᵀ
inverted whole); a set without the column, or with every row NaN, must give the numbers it gave
before the column existed; the file carries the column (format 1.3) through ECSV and Parquet; and a
Monte Carlo of a mixed-σ campaign reports a σ inside the χ² interval of its scatter.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from oracles import row_sigma_gls_reference

from boresight import estimate, simulate
from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.structure import image_covariance_rows, images_by_row_count, residual_variances, row_pixel_sigma
from boresight.observations.model import ObservationError, ObservationFileError, ObservationSet


def _mixed(obs, seed: int = 7, nan_share: float = 0.25):
    """``obs`` with each row's σ drawn from {0.3, 1, 4} × σK (and NaN, the model's σK, on about
    ``nan_share`` of the rows), x and y differing: a strongly heteroscedastic set."""
    rng = np.random.default_rng(seed)
    sk = obs.noise["pixel"]["sigma_m"]
    s = sk * rng.choice([0.3, 1.0, 4.0], size=(obs.n_observations, 2))
    s[rng.random(obs.n_observations) < nan_share] = np.nan
    return dataclasses.replace(obs, sigma_xy_m=s)


@pytest.fixture(scope="module")
def kalman20():
    return simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(28))


def test_gls_with_mixed_sigma_equals_the_independently_weighted_oracle(kalman20):
    """θ̂ and its covariance from ``estimate(weighting="gls")`` against the dense full-Σ oracle with each row's
    own σ: equal to 1e-9 relative (both solve the same GLS; the oracle by a dense inverse). The mixed σ moves
    θ̂ by far more than that from the one-σ fit, so the comparison can fail. Every 7th row dropped: not a
    complete set (shared targets seen in some images only)."""
    obs = _mixed(kalman20).rows(np.arange(kalman20.n_observations) % 7 != 3)
    kalman20 = kalman20.rows(np.arange(kalman20.n_observations) % 7 != 3)
    model = DisturbanceModel.from_observations(obs)
    est = estimate(obs, algorithm="image_plane", weighting="gls", model=model)
    theta_ref, cov_ref = row_sigma_gls_reference(obs, model, est.theta.to_value("rad").reshape(3))
    theta = est.theta.to_value("rad").reshape(3)
    cov = est.covariance.to_value("rad2").reshape(3, 3)
    sig = np.sqrt(np.diag(cov_ref))
    assert np.max(np.abs(theta - theta_ref) / sig) < 1e-9
    np.testing.assert_allclose(cov, cov_ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(cov_ref)))
    plain = estimate(kalman20, algorithm="image_plane", weighting="gls", model=model)
    assert np.max(np.abs(plain.theta.to_value("rad").reshape(3) - theta) / sig) > 1e-3
    assert np.max(np.abs(plain.sigma.to_value("rad").reshape(3) / sig - 1)) > 1e-2


def test_pixel_only_gls_is_weighted_least_squares(kalman20):
    """Pixel noise alone: the GLS is weighted least squares with weights 1/σ_k² (the textbook, solved here
    by numpy's lstsq on the rows scaled by 1/σ) to 1e-9."""
    from boresight.core.measurement import linearize

    obs = _mixed(kalman20, seed=3, nan_share=0.0)
    model = DisturbanceModel(sigma_pixel_m=obs.noise["pixel"]["sigma_m"])
    est = estimate(obs, algorithm="image_plane", weighting="gls", model=model)
    th = est.theta.to_value("rad").reshape(1, 3)
    G, q = linearize(obs, th)
    w = 1.0 / obs.sigma_xy_m.reshape(-1)
    dx, *_ = np.linalg.lstsq(G[0].reshape(-1, 3) * w[:, None], q[0].reshape(-1) * w, rcond=None)
    cov = np.linalg.inv((G[0].reshape(-1, 3) * w[:, None]).T @ (G[0].reshape(-1, 3) * w[:, None]))
    assert np.max(np.abs(dx) / np.sqrt(np.diag(cov))) < 1e-6  # the GLS θ̂ is the WLS fixed point (iteration tol 1e-6″)
    np.testing.assert_allclose(est.covariance.to_value("rad2").reshape(3, 3), cov, rtol=1e-9, atol=1e-9 * np.abs(cov).max())


@pytest.mark.parametrize("algorithm", ["image_plane", "unit_vector", "kalman"])
def test_a_set_without_own_sigma_is_unchanged(kalman20, algorithm):
    """Every row NaN (the model's σ) or every row σK: the numbers of the set without the column, to 1e-9."""
    model = DisturbanceModel.from_observations(kalman20)
    base = estimate(kalman20, algorithm=algorithm, model=model)
    K = kalman20.n_observations
    for s in (np.full((K, 2), np.nan), np.full((K, 2), model.sigma_pixel_m)):
        est = estimate(dataclasses.replace(kalman20, sigma_xy_m=s), algorithm=algorithm, model=model)
        np.testing.assert_allclose(est.theta.value, base.theta.value, rtol=0, atol=1e-9 * base.sigma.value.min())
        np.testing.assert_allclose(est.sigma.value, base.sigma.value, rtol=1e-9)


def test_error_structure_consumers_read_each_rows_sigma(kalman20):
    """The per-residual variances and the per-image covariances (the Kalman R_n, the Monte Carlo weights,
    the doctor) add exactly σ_k² − σK² on each row's diagonal and change nothing else."""
    obs = _mixed(kalman20)
    model = DisturbanceModel.from_observations(obs)
    sig = row_pixel_sigma(obs, model)
    th = np.zeros((1, 3))
    dv = residual_variances(obs, th, model) - residual_variances(kalman20, th, model)
    np.testing.assert_allclose(dv[0], sig**2 - model.sigma_pixel_m**2, rtol=1e-9, atol=1e-24)
    for m, ims in images_by_row_count(obs):
        if not m:
            continue
        d = image_covariance_rows(obs.images(ims), th, model) - image_covariance_rows(kalman20.images(ims), th, model)
        expect = np.zeros_like(d)
        i = np.arange(2 * m)
        expect[..., i, i] = (obs.images(ims).sigma_xy_m ** 2).reshape(ims.size, 2 * m)
        expect[..., i, i] -= np.where(np.isnan(expect[..., i, i]), 0.0, model.sigma_pixel_m**2)
        expect = np.nan_to_num(expect)
        np.testing.assert_allclose(d, expect, rtol=0, atol=1e-9 * model.sigma_pixel_m**2)


def test_slicing_keeps_each_rows_sigma(kalman20):
    obs = _mixed(kalman20)
    sub = obs.images([3, 1, 7])
    start = obs.row_start
    rows = np.concatenate([np.arange(start[n], start[n + 1]) for n in (3, 1, 7)])
    np.testing.assert_array_equal(sub.sigma_xy_m, obs.sigma_xy_m[rows])
    np.testing.assert_array_equal(obs.rows([0, 5]).sigma_xy_m, obs.sigma_xy_m[[0, 5]])
    keep = obs.target_index != 2
    np.testing.assert_array_equal(obs.targets([0, 1, 3]).sigma_xy_m, obs.sigma_xy_m[keep])
    np.testing.assert_array_equal(obs.run(0).sigma_xy_m, obs.sigma_xy_m)


@pytest.mark.parametrize(
    "bad, match",
    [
        (lambda s: s[:-1], r"sigma_xy_m: expected shape"),
        (lambda s: np.where(np.arange(s.size).reshape(s.shape) == 5, -1e-6, s), r"row 2 .* must be in"),
        (lambda s: np.where(np.arange(s.size).reshape(s.shape) == 0, np.nan, s), r"row 0 .* NaN on both"),
        (lambda s: np.where(np.arange(s.size).reshape(s.shape) == 3, np.inf, s), r"row 1 .* must be in"),
    ],
)
def test_a_bad_sigma_is_refused_naming_the_row(kalman20, bad, match):
    s = np.full((kalman20.n_observations, 2), 2e-6)
    with pytest.raises(ObservationError, match=match):
        dataclasses.replace(kalman20, sigma_xy_m=bad(s))


@pytest.mark.parametrize("suffix", [".ecsv", ".parquet"])
def test_file_round_trip_of_each_rows_sigma(kalman20, tmp_path, suffix):
    """Format 1.3: ``sigma_x sigma_y`` (m; NaN for the model's σ) written and read back exactly; a set
    without them is still written as 1.1 (older files read unchanged)."""
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    obs = _mixed(kalman20)
    path = obs.write(tmp_path / f"mixed{suffix}")
    back = ObservationSet.read(path)
    np.testing.assert_array_equal(back.sigma_xy_m, obs.sigma_xy_m)
    if suffix == ".ecsv":
        text = path.read_text()
        assert "format_version: '1.3'" in text and "sigma_x" in text
        plain = kalman20.write(tmp_path / "plain.ecsv")
        assert "format_version: '1.1'" in plain.read_text() and "sigma_x" not in plain.read_text()
        assert ObservationSet.read(plain).sigma_xy_m is None
    model = DisturbanceModel.from_observations(obs)
    a, b = estimate(obs, model=model), estimate(back, model=model)
    np.testing.assert_allclose(b.theta.value, a.theta.value, rtol=0, atol=1e-9 * a.sigma.value.min())


def _edit(path, old: str, new: str, count: int = 1):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, count))


def test_reader_refuses_a_bad_sigma_column_naming_column_and_row(kalman20, tmp_path):
    obs = dataclasses.replace(kalman20, sigma_xy_m=np.full((kalman20.n_observations, 2), 2.5e-6))
    path = obs.write(tmp_path / "s.ecsv")
    text = path.read_text()
    data = text.splitlines()
    head = [i for i, line in enumerate(data) if not line.startswith("#")][0]
    cols = data[head].split()
    ix, iy = cols.index("sigma_x"), cols.index("sigma_y")

    def with_row(k, **vals):
        lines = list(data)
        f = lines[head + 1 + k].split()
        for name, v in vals.items():
            f[{"x": ix, "y": iy}[name]] = v
        lines[head + 1 + k] = " ".join(f)
        p = tmp_path / "bad.ecsv"
        p.write_text("\n".join(lines) + "\n")
        return p

    with pytest.raises(ObservationFileError, match=r"'sigma_x' row 4: σ -2.5e-06 m is outside"):
        ObservationSet.read(with_row(4, x="-2.5e-06"))
    with pytest.raises(ObservationFileError, match=r"'sigma_x sigma_y' row 6: one is NaN"):
        ObservationSet.read(with_row(6, y="nan"))
    with pytest.raises(ObservationFileError, match=r"'sigma_y' row 2: non-finite value inf"):
        ObservationSet.read(with_row(2, y="inf"))
    assert np.isnan(ObservationSet.read(with_row(3, x="nan", y="nan")).sigma_xy_m[3]).all()
    _edit(path, "name: sigma_x, unit: m,", "name: sigma_x, unit: um,")
    assert np.allclose(ObservationSet.read(path).sigma_xy_m[:, 0], 2.5e-12)  # units convert as for x y


def test_reader_refuses_a_sigma_that_differs_between_runs(tmp_path):
    obs = simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(1), runs=2)
    obs = dataclasses.replace(obs, sigma_xy_m=np.full((obs.n_observations, 2), 2.5e-6))
    path = obs.write(tmp_path / "two.ecsv")
    text = path.read_text().splitlines()
    last = text[-1].split()
    head = [line for line in text if not line.startswith("#")][0].split()
    last[head.index("sigma_x")] = "3e-06"
    text[-1] = " ".join(last)
    path.write_text("\n".join(text) + "\n")
    with pytest.raises(ObservationFileError, match=r"'sigma_x' row \d+: differs from run 0's"):
        ObservationSet.read(path)


def test_montecarlo_of_a_mixed_sigma_campaign_reports_the_scatter(kalman20):
    """``montecarlo FILE`` (``file_study``) on a mixed-σ set: 600 resimulations draw each row's noise with
    its own σ (``draw_errors(pixel_sigma_rows_m=)``) and refit with the GLS. Tolerance: the reported σ
    must lie in the 99.73 % χ² interval of the scatter of 600 runs (``FileStudy.inside``: ±~9 %,
    σ̂/σ ~ √(χ²₅₉₉/599)); with three axes the chance of a false failure is < 1 %. Fitting the same draws
    as if every row had the model's one σ misreports σ by far more (checked here: the test can fail)."""
    from boresight.studies.montecarlo.file_study import file_study

    obs = _mixed(kalman20, seed=11, nan_share=0.0)
    model = DisturbanceModel.from_observations(obs)
    study = file_study(obs, model, runs=600, seed=5)
    assert study.inside().all(), (study.reported_sigma_arcsec, study.sigma_arcsec)
    ratio = study.reported_sigma_arcsec / study.sigma_arcsec
    assert np.all(np.abs(ratio - 1) < 0.1)
    # the one-σ fit of a heteroscedastic set: σ from the model's σK, not the rows' — outside the interval
    wrong = estimate(kalman20, model=model).sigma.to_value("arcsec").reshape(3)
    lo, hi = study.interval()
    assert np.any((wrong < lo) | (wrong > hi)), (wrong, lo, hi)


def test_variance_components_scale_the_rows_own_sigma(kalman20):
    """REML on a set whose rows carry their own σ: with every row's σ = σK the components are those of the set
    without the column (1e-9: the same draws, the same fixed point); with every row's σ declared at half the σK
    its noise was drawn with, the pixel factor comes out ≈ 2 (the pixel redundancy here is ~150, so its scale's
    relative σ is ~1/√(2·150) ≈ 6 %: 2 ± 0.3 is 2.5 of those) and ``scaled_rows`` carries it to the rows."""
    from boresight.core.variance_components import variance_components_at

    model = DisturbanceModel.from_observations(kalman20)
    th = estimate(kalman20, model=model).theta.to_value("rad")[0]
    base = variance_components_at(kalman20, th, model)
    same = variance_components_at(
        dataclasses.replace(kalman20, sigma_xy_m=np.full((kalman20.n_observations, 2), model.sigma_pixel_m)), th, model
    )
    for a, b in zip(base.components, same.components, strict=True):
        assert a.source == b.source and np.isclose(a.estimate, b.estimate, rtol=1e-9), (a, b)
    half = dataclasses.replace(kalman20, sigma_xy_m=np.full((kalman20.n_observations, 2), 0.5 * model.sigma_pixel_m))
    vc = variance_components_at(half, th, model)
    assert abs(vc.pixel_factor - 2.0) < 0.3, vc.pixel_factor
    np.testing.assert_allclose(vc.scaled_rows(half).sigma_xy_m, half.sigma_xy_m * vc.pixel_factor)
    assert base.pixel_factor == 1.0 and base.scaled_rows(kalman20) is kalman20


def test_merging_a_file_with_own_sigma_and_one_without(kalman20, tmp_path):
    """``merge_observations`` (``diagnose A B``): the rows of the file with its own σ keep it, the other
    file's rows take the noise model's (NaN), through the written files (1.3 and 1.1)."""
    from boresight.observations.merge import merge_observations

    a = _mixed(kalman20)
    b = simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(29))
    both = merge_observations(
        [ObservationSet.read(a.write(tmp_path / "a.ecsv")), ObservationSet.read(b.write(tmp_path / "b.ecsv"))]
    )
    first = both.image_index < a.n_images
    np.testing.assert_array_equal(both.sigma_xy_m[first], a.sigma_xy_m)
    assert np.all(np.isnan(both.sigma_xy_m[~first]))


def test_a_file_whose_every_row_has_its_own_sigma_needs_no_model_sigma(kalman20, tmp_path):
    """A file whose every row carries its own σ while its noise block's ``pixel: sigma_m`` is 0: the weighted fits'
    checks read ``gls.structure.has_pixel_noise`` (every row's σ > 0), not σK, so ``estimate`` (GLS by default,
    in the library and the CLI) and ``diagnose`` take it and give the θ, σ and verdicts of the same file with
    σK set and every row's σ equal to it. On the code before, both refused it ('needs model.sigma_pixel_m > 0')."""
    import copy

    from cli_run import run_cli

    from boresight.studies.discrepancy import diagnose

    sk = kalman20.noise["pixel"]["sigma_m"]
    own = dataclasses.replace(kalman20, sigma_xy_m=np.full((kalman20.n_observations, 2), sk))
    noise = copy.deepcopy(own.noise)
    noise["pixel"]["sigma_m"] = 0.0
    a = ObservationSet.read(own.write(tmp_path / "with_sigma_k.ecsv"))
    b = ObservationSet.read(dataclasses.replace(own, noise=noise).write(tmp_path / "rows_only.ecsv"))
    ma, mb = DisturbanceModel.from_observations(a), DisturbanceModel.from_observations(b)
    assert mb.sigma_pixel_m == 0.0
    ea, eb = estimate(a, model=ma), estimate(b, model=mb)
    assert eb.weighting == ea.weighting == "gls"
    np.testing.assert_allclose(eb.theta.value, ea.theta.value, rtol=1e-9, atol=0)
    np.testing.assert_allclose(eb.sigma.value, ea.sigma.value, rtol=1e-9, atol=0)
    assert diagnose(b, mb).as_json() == diagnose(a, ma).as_json()
    outs = [run_cli(["estimate", tmp_path / f"{n}.ecsv", "--out", tmp_path / n]) for n in ("with_sigma_k", "rows_only")]
    assert [o[0] for o in outs] == [0, 0], outs[1][2]
    theta_lines = [[line for line in o[1].splitlines() if line.startswith(("θ", "algorithm"))] for o in outs]
    assert theta_lines[0] == theta_lines[1] and "gls weighting" in theta_lines[1][0]
