"""``boresight estimate FILE.ecsv`` and the algorithm registry."""

import json

import numpy as np
import pytest

from boresight import estimate, simulate
from boresight.cli.main import main
from boresight.core.estimation import Estimate, algorithms, register_algorithm


@pytest.fixture(scope="module")
def ecsv(tmp_path_factory):
    from dataclasses import replace

    obs = simulate("scenarios/kiev2012-sensitivity.toml", np.random.default_rng(np.random.SeedSequence(5)))
    obs = replace(obs, noise=None)  # a file without a noise model (format 1.0-like): sigmas must come from options
    path = tmp_path_factory.mktemp("est") / "x.ecsv"
    obs.write(path)
    return obs, path


def test_cli_estimate_prints_theta_and_writes_json(ecsv, tmp_path, capsys):
    obs, path = ecsv
    out = tmp_path / "est.json"
    rc = main(
        [
            "estimate",
            str(path),
            "--algorithm",
            "alg2",
            "--weighting",
            "gls",
            "--scenario",
            "scenarios/kiev2012-sensitivity.toml",
            "--json",
            str(out),
        ]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "ground_plane (gls weighting)" in text and "theta_z" in text
    got = json.loads(out.read_text())
    ref = estimate(
        obs,
        algorithm="ground_plane",
        weighting="gls",
        model=__import__("boresight").DisturbanceModel.from_scenario(
            __import__("orbits").load_scenario("scenarios/kiev2012-sensitivity.toml")
        ),
    )
    assert np.allclose(got["theta_arcsec"], ref.theta.to_value("arcsec"), rtol=0, atol=1e-9)
    sigma = np.sqrt(np.diag(got["covariance_arcsec2"]))
    assert np.allclose(sigma, [6.09, 6.09, 8.36], rtol=0.02)  # the seminar's eq 28 case


def test_cli_sigma_options_override_and_errors(ecsv, capsys):
    _, path = ecsv
    assert (
        main(["estimate", str(path), "--weighting", "diagonal", "--sigma-pixel-m", "3e-6", "--sigma-star-tracker-arcsec", "4"])
        == 0
    )
    assert main(["estimate", str(path), "--weighting", "gls"]) == 1
    assert "needs a disturbance model" in capsys.readouterr().err
    assert main(["estimate", str(path), "--algorithm", "nope"]) == 1
    assert "unknown algorithm 'nope'" in capsys.readouterr().err
    assert main(["estimate", str(path.with_name("missing.ecsv"))]) == 1


def test_cli_multi_run_file(tmp_path, capsys):
    obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(1), runs=3)
    path = obs.write(tmp_path / "runs.ecsv")
    assert main(["estimate", str(path), "--algorithm", "unit_vector"]) == 0
    text = capsys.readouterr().out
    assert text.count("+20.0000") == 3  # θx of every run, noise-free


def test_registry_linearizer_and_estimator():
    obs = simulate("scenarios/kiev2012-algorithm1.toml", np.random.default_rng(1))
    from boresight.core.algorithms import image_plane

    register_algorithm("_test_lin", image_plane.linearize, kind="linearizer", aliases=("_tl",))
    assert "_tl" in algorithms()
    est = estimate(obs, algorithm="_tl")
    assert np.allclose(est.theta.to_value("arcsec"), [20, -15, 40], atol=1e-3)
    with pytest.raises(ValueError, match="has no residual_map, so only weighting='unit'"):
        estimate(obs, algorithm="_tl", weighting="gls", model=__import__("boresight").DisturbanceModel(sigma_pixel_m=1e-6))

    seen = {}

    def fake(o, **kw):
        seen.update(kw)
        return "sentinel"

    register_algorithm("_test_est", fake)
    assert (
        estimate(obs, algorithm="_test_est", weighting="diagonal", iterate=3, prior_sigma_arcsec=10.0, extra_option=1)
        == "sentinel"
    )
    assert seen == {"weighting": "diagonal", "iterate": 3, "model": None, "prior_sigma_arcsec": 10.0, "extra_option": 1}
    with pytest.raises(ValueError, match="kind must be 'estimator' or 'linearizer'"):
        register_algorithm("_x", fake, kind="other")
    assert Estimate.__dataclass_fields__.keys() >= {
        "theta",
        "covariance",
        "residuals",
        "chi2",
        "dof",
        "condition_number",
        "iterations",
    }


def test_cli_kalman_prints_the_noise_model_chi2_verdict_and_warns_on_moved_points(tmp_path, capsys):
    """Issue 31, class 1: ``estimate F --algorithm kalman`` on a file with 10 % of its points moved
    50 px printed "no noise model … no expected range", no warning, exit 0. Now the χ² line is the
    noise model's with its band and the same warning as the default algorithm; the clean file's
    line is inside its band."""
    from dataclasses import replace

    obs = simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(np.random.SeedSequence(1)))
    clean, bad = tmp_path / "clean.ecsv", tmp_path / "bad.ecsv"
    obs.write(clean)
    xy = obs.xy_m.copy()
    pick = np.random.default_rng(1).choice(obs.n_observations, size=obs.n_observations // 10, replace=False)
    xy[0, pick, 0] += 50 * 5e-6
    replace(obs, xy_m=xy).write(bad)
    assert main(["estimate", str(clean), "--algorithm", "kalman"]) == 0
    out = capsys.readouterr().out
    assert "under the noise model" in out and "no noise model" not in out and "OUTSIDE" not in out, out
    main(["estimate", str(bad), "--algorithm", "kalman"])
    out = capsys.readouterr().out
    assert "OUTSIDE the expected range" in out and "warning       χ²/dof" in out, out
