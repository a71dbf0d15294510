"""Monte Carlo engine: chunk/worker invariance, sample-size rule, moments, kernels, statistics."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import chi2

import boresight
import orbits
from boresight.core.algorithms import ground_plane, image_plane, kalman, unit_vector
from boresight.core.disturbances import DisturbanceModel
from boresight.core.gls.normal_equations import NormalEquations
from boresight.reproductions import kiev2012
from boresight.studies import montecarlo as mc
from boresight.studies.montecarlo.preflight import kalman_weight_blocks
from orbits.rotations import ARCSEC

SENS = "scenarios/kiev2012-sensitivity.toml"


def _same(a: mc.MonteCarloResult, b: mc.MonteCarloResult):
    assert a.algorithms == b.algorithms
    for name in a.algorithms:
        assert a.moments[name] == b.moments[name], name  # bit for bit
        assert np.array_equal(a.samples[name], b.samples[name]), name


# ---------------------------------------------------------------------------- determinism


def test_same_seed_identical_for_chunk_sizes_and_workers():
    runs, kw = 37, dict(block_runs=10, seed=5)
    ref = mc.montecarlo_study(SENS, "all", runs, chunk_runs=1000, workers=1, **kw)
    for chunk in (1, 7):
        _same(ref, mc.montecarlo_study(SENS, "all", runs, chunk_runs=chunk, workers=1, **kw))
    _same(ref, mc.montecarlo_study(SENS, "all", runs, chunk_runs=7, workers=2, **kw))


def test_default_blocks_chunk_invariant_on_a_multi_image_scenario():
    sc = kiev2012.kalman_scenario(10.0, t_s=[0.0, 10.0, 20.0])
    a = mc.montecarlo_study(sc, "all", 2100, seed=2, chunk_runs=1000, workers=1)
    b = mc.montecarlo_study(sc, "all", 2100, seed=2, chunk_runs=700, workers=2)
    _same(a, b)
    assert a.image_counts == (1, 2, 3)


def test_different_seed_differs_and_block_size_is_part_of_identity():
    a = mc.montecarlo_study(SENS, ["image_plane"], 40, seed=1, block_runs=10, workers=1)
    b = mc.montecarlo_study(SENS, ["image_plane"], 40, seed=2, block_runs=10, workers=1)
    assert not np.array_equal(a.moments["image_plane"].mean, b.moments["image_plane"].mean)


def test_dask_engine_matches_local():
    pytest.importorskip("dask.distributed")
    kw = dict(runs=45, seed=4, block_runs=10, chunk_runs=7)
    local = mc.montecarlo_study(SENS, "all", workers=1, **kw)
    eng = mc.make_engine("dask", workers=2, processes=False)
    try:
        remote = mc.montecarlo_study(SENS, "all", engine=eng, **kw)
    finally:
        eng.close()
    _same(local, remote)


def test_dask_process_workers_at_a_scheduler_address_match_local():
    """The cluster route as a cluster user runs it: a ``LocalCluster`` of two *process* workers started
    outside boresight, its address passed as ``scheduler=`` (what ``--scheduler tcp://…`` does). Seven
    chunks over two processes give the same numbers, bit for bit, as one local process: the seeding
    is per block and the blocks are merged in order (``docs/montecarlo.md``, "On a cluster")."""
    distributed = pytest.importorskip("dask.distributed")
    kw = dict(runs=45, seed=4, block_runs=10, chunk_runs=7)
    local = mc.montecarlo_study(SENS, "all", workers=1, **kw)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        remote = mc.montecarlo_study(SENS, "all", engine="dask", scheduler=cluster.scheduler_address, workers=2, **kw)
        with distributed.Client(cluster) as client:
            assert len(client.scheduler_info()["workers"]) == 2  # two worker processes, not threads
    _same(local, remote)


def test_the_command_line_route_to_a_scheduler_address_matches_local(tmp_path):
    """``boresight montecarlo … --engine dask --scheduler ADDRESS`` (the option a cluster user passes) on two
    process workers writes the same table as ``--workers 1`` locally: every column equal, bit for bit."""
    distributed = pytest.importorskip("dask.distributed")
    from astropy.table import Table
    from study_argv import quiet_study

    from boresight.cli.main import main

    opts = ("--block-runs", "10", "--chunk-runs", "7")
    assert main(quiet_study("montecarlo", SENS, *opts, runs=45, seed=4, workers=1, out=tmp_path / "local")) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        dask = ("--engine", "dask", "--scheduler", cluster.scheduler_address)
        assert main(quiet_study("montecarlo", SENS, *opts, *dask, runs=45, seed=4, workers=2, out=tmp_path / "dask")) == 0
    local, remote = (Table.read(tmp_path / d / "montecarlo.ecsv", format="ascii.ecsv") for d in ("local", "dask"))
    assert local.colnames == remote.colnames and len(local) == len(remote) > 0
    for c in local.colnames:
        np.testing.assert_array_equal(np.asarray(local[c]), np.asarray(remote[c]), err_msg=c)
    doc = json.loads((tmp_path / "dask" / "montecarlo.json").read_text())
    assert cluster.scheduler_address in json.dumps(doc)  # the result says where it ran


# ---------------------------------------------------------------------------- pieces


def test_plan_chunks_covers_every_run_once():
    for runs, chunk, block in ((1, 1, 1), (2500, 7, 1000), (10, 3, 4), (999, 1000, 1000)):
        seen = []
        for segs in mc.plan_chunks(runs, chunk, block):
            assert sum(z - a for _, a, z in segs) <= chunk
            seen += [b * block + k for b, a, z in segs for k in range(a, z)]
        assert seen == list(range(runs))


def test_moments_merge_matches_numpy():
    x = np.random.default_rng(0).normal(3.0, 2.0, size=(1001, 2, 3))
    m = mc.Moments.from_samples(x[:13]).merge(mc.Moments.from_samples(x[13:500])).merge(mc.Moments.from_samples(x[500:]))
    np.testing.assert_allclose(m.mean, x.mean(0), rtol=1e-13)
    np.testing.assert_allclose(m.std, x.std(0, ddof=1), rtol=1e-12)
    np.testing.assert_array_equal(m.max_abs, np.abs(x).max(0))


def test_required_runs_and_intervals():
    assert mc.required_runs(0.9973, 0.01) == 45000
    assert abs(mc.t_beta(0.9973) - 3.0) < 1e-4
    # the χ² interval at n = 45 000 has half-width ≈ ε = 0.01
    assert 0.0095 < mc.achieved_epsilon(45000) < 0.0105
    with pytest.raises(ValueError, match="eps must be"):
        mc.required_runs(0.9973, 0.0)
    with pytest.raises(ValueError, match="beta must lie"):
        mc.t_beta(1.5)


def test_bad_inputs_name_the_field():
    with pytest.raises(ValueError, match="algorithm must be one of"):
        mc.montecarlo_study(SENS, ["bogus"], 10)
    with pytest.raises(ValueError, match="runs must be"):
        mc.montecarlo_study(SENS, ["image_plane"], 1)
    with pytest.raises(ValueError, match="chunk_runs must be"):
        mc.montecarlo_study(SENS, ["image_plane"], 10, chunk_runs=0)
    with pytest.raises(ValueError, match="image_counts must lie"):
        mc.montecarlo_study(SENS, ["image_plane"], 10, image_counts=[2])
    with pytest.raises(ValueError, match="engine must be"):
        mc.make_engine("spark", workers=1)


# ---------------------------------------------------------------------------- kernels vs modules


@pytest.fixture(scope="module")
def obs10():
    sc = kiev2012.kalman_scenario(600.0, t_s=[0.0, 10.0, 20.0])
    return sc, boresight.simulate(sc, np.random.default_rng(11), runs=50)


# Kernels vs modules differ only by summation order. Over seeds 0-29 of this fixture the largest
# difference is 3.2e-9″ (ground plane; 2.2e-9″ for gauss_newton, 4e-10″ for the image-plane
# kernel): round-off on θ ≈ 10′ ≈ 3e-3 rad. A bound of 1e-9″ held only for the seed in use
# (seed 13 fails it); 2e-8″ holds for any seed and is still 1e5 below any modelling slip
# (the SO(3) factor J_r transposed leaves 1.5e-4″ after 3 steps from 10′).
ROUND_OFF = 2e-8 * ARCSEC


def _reference_gn(obs, lin, iterations):
    theta = np.zeros((obs.runs, 3))
    for _ in range(iterations):
        G, q = lin(obs, theta)
        ne = NormalEquations()
        ne.update(G.reshape(obs.runs, -1, 3), q.reshape(obs.runs, -1))
        theta = theta + ne.solve().theta
    return theta


def test_image_plane_kernel_matches_module(obs10):
    _, obs = obs10
    ref = _reference_gn(obs, image_plane.linearize, 3)
    got = mc.image_plane_kernel(mc.camera_vectors0(obs), obs.xy_m, obs.focal_length_m, 3)
    assert np.abs(got - ref).max() < ROUND_OFF


def test_kernels_on_an_incomplete_set_match_modules(obs10):
    """Rows, not a grid: with every third observation dropped (the set no longer complete, its
    camera vectors computed row by row) each kernel still equals its module."""
    _, full = obs10
    obs = full.rows(np.arange(full.n_observations) % 3 != 1)
    assert not obs.is_complete
    s0 = mc.camera_vectors0(obs)
    # the grid's batched 3 × 3 product (BLAS) and the rows' component sums differ in the last bits (seen 2e-14)
    np.testing.assert_allclose(s0, mc.camera_vectors0(full)[:, np.arange(full.n_observations) % 3 != 1], rtol=1e-13, atol=0)
    ref = _reference_gn(obs, image_plane.linearize, 3)
    assert np.abs(mc.image_plane_kernel(s0, obs.xy_m, obs.focal_length_m, 3) - ref).max() < ROUND_OFF
    for mod, kernel in ((ground_plane, mc.ground_plane_kernel), (unit_vector, mc.unit_vector_kernel)):
        assert np.abs(kernel(obs, s0, 3) - _reference_gn(obs, mod.linearize, 3)).max() < ROUND_OFF, mod.__name__


@pytest.mark.parametrize("mod, kernel", [(ground_plane, mc.ground_plane_kernel), (unit_vector, mc.unit_vector_kernel)])
def test_fast_kernels_match_modules(obs10, mod, kernel):
    _, obs = obs10
    ref = _reference_gn(obs, mod.linearize, 3)
    assert np.abs(kernel(obs, mc.camera_vectors0(obs), 3) - ref).max() < ROUND_OFF


@pytest.mark.parametrize("mod", [ground_plane, unit_vector])
def test_gauss_newton_matches_normal_equations(obs10, mod):
    _, obs = obs10
    ref = _reference_gn(obs, mod.linearize, 3)
    assert np.abs(mc.gauss_newton(obs, mod.linearize, 3) - ref).max() < ROUND_OFF


@pytest.mark.parametrize("sigma0_arcsec, tol_arcsec", [(10.0, 0.005), (600.0, 0.2)])
def test_kalman_kernel_matches_module(sigma0_arcsec, tol_arcsec):
    """The fast filter takes R_n from the nominal geometry; the module re-evaluates it about
    each run's estimate. They agree to 1e-4 of σθ with the seminar's 10″ prior, and to ~1 % of
    σθ per run with a 10′ prior (R_n moves by O(|θ|) ≈ 3e-3)."""
    sc = kiev2012.kalman_scenario(sigma0_arcsec, t_s=[0.0, 10.0, 20.0])
    obs = boresight.simulate(sc, np.random.default_rng(11), runs=50)
    model = DisturbanceModel.from_scenario(sc)
    res = kalman.kalman_filter(obs, model, sigma0_rad=sigma0_arcsec * ARCSEC, states=("theta",))
    nom = mc.nominal_observations(sc)
    W = kalman_weight_blocks(nom, model)
    s0 = mc.camera_vectors0(obs)
    xh, Ph = mc.kalman_theta_kernel(s0, obs.xy_m, obs.row_start, obs.focal_length_m, W, sigma0_arcsec * ARCSEC, 3)
    assert np.abs(xh - res.theta_history_rad).max() < tol_arcsec * ARCSEC
    sd = np.sqrt(np.diagonal(Ph, axis1=-2, axis2=-1))
    sd_ref = np.sqrt(np.diagonal(res.P_history[..., :3, :3], axis1=-2, axis2=-1))
    np.testing.assert_allclose(sd, sd_ref, rtol=0.02)


# ---------------------------------------------------------------------------- statistics


def test_pixel_noise_only_sigma_within_chi2_interval_of_analytic():
    """σθ from Monte Carlo vs (GᵀG)⁻¹ σK² (eq 22, linear theory), at 99.73 % per axis."""
    sc = orbits.load_scenario(SENS)
    from dataclasses import replace

    sc = replace(sc, sigma_star_tracker_arcsec=(0.0, 0.0, 0.0), sigma_gnss_m=0.0, sigma_catalogue_m=0.0)
    runs = 4000
    r = mc.montecarlo_study(sc, ["image_plane", "unit_vector"], runs, seed=8, workers=1)
    nom = mc.nominal_observations(sc)
    G, _ = image_plane.linearize(nom, np.zeros(3))
    G = G.reshape(-1, 3)
    sigma = np.sqrt(np.diag(np.linalg.inv(G.T @ G))) * sc.sigma_pixel_m / ARCSEC
    for name in ("image_plane", "unit_vector"):
        s = r.moments[name].std[0]
        lo = s * np.sqrt((runs - 1) / chi2.ppf(0.99865, runs - 1))
        hi = s * np.sqrt((runs - 1) / chi2.ppf(0.00135, runs - 1))
        assert np.all((lo < sigma) & (sigma < hi)), (name, s, sigma)


# ---------------------------------------------------------------------------- CLI


def test_cli_montecarlo_writes_outputs(tmp_path, capsys):
    from boresight.cli.main import main

    rc = main(
        ["montecarlo", SENS, "--runs", "300", "--seed", "3", "--out", str(tmp_path), "--workers", "1", "--quiet", "--no-plots"]
    )
    assert rc == 0
    out = capsys.readouterr().out
    assert "image_plane" in out and "seminar" in out
    from astropy.table import Table

    t = Table.read(tmp_path / "montecarlo.ecsv", format="ascii.ecsv")
    assert t["sigma_theta_x"].unit.to_string() == "arcsec" and len(t) == 4
    meta = json.loads((tmp_path / "montecarlo.json").read_text())
    assert meta["seed"] == 3 and meta["runs"] == 300 and "numpy" in meta["versions"]
    assert meta["scenario"]["orbit"]["altitude_km"] == 680.0


def test_cli_bad_algorithm_is_an_error(tmp_path, capsys):
    from boresight.cli.main import main

    assert main(["montecarlo", SENS, "--runs", "10", "--algorithm", "nope", "--out", str(tmp_path), "--quiet"]) == 1
    assert "algorithm must be one of" in capsys.readouterr().err


def test_cached_observation_proxy_caches_and_refuses_unknown_method_names(monkeypatch):
    from boresight.core.algorithms.batched import _CachedObs

    obs = boresight.simulate("scenarios/kiev2012-sensitivity.toml", np.random.default_rng(0), runs=2)
    o = _CachedObs(obs)
    a = o.nominal_camera_attitude()
    assert a is o.nominal_camera_attitude()  # computed once
    np.testing.assert_array_equal(a, obs.nominal_camera_attitude())
    assert o.runs == obs.runs and o.xy_m is obs.xy_m and o.image_index is obs.image_index  # everything else delegates
    monkeypatch.setattr(_CachedObs, "_CACHED", _CachedObs._CACHED + ("renamed_method",))
    with pytest.raises(AttributeError, match="renamed_method"):
        _CachedObs(obs)


@pytest.mark.slow
def test_monte_carlo_sigma_matches_linear_propagation_at_the_seminars_sample_size():
    """45 000 runs (the seminar's rule for ε = 1 % at β = 0.9973) of the eq 28 case: the Monte
    Carlo σθ of Algorithm 3 must contain the linear-propagation σθ in its χ² interval.

    Tolerance from the sampling distribution: (n − 1) s²/σ² ~ χ²(n − 1), so the interval at
    β = 0.999 per axis (0.997 for the three axes together) is ±1.1 % of σ at n = 45 000; a
    factor-of-two (or a 3 %) error in either route fails. (Seed 11 gave deviations of −0.17,
    −0.04, +0.02 %: the linearisation error at these error sizes is well inside the band.)"""
    from boresight.studies import sensitivity as se

    sc = "scenarios/kiev2012-sensitivity.toml"
    r = mc.montecarlo_study(sc, ["image_plane"], runs=45000, seed=11, workers=2)
    mo = r.moments["image_plane"]
    lo, hi = mc.sigma_interval(mo.std[0], mo.count, 0.999)
    lin = np.asarray(se.linear_sensitivities(sc, ["image_plane"]).meta["sigma_theta_arcsec"]["image_plane"][:3])
    assert np.all(hi / lo - 1 < 0.025)  # the interval is as narrow as stated
    assert np.all((lo <= lin) & (lin <= hi)), (mo.std[0], lo, hi, lin)


def test_sub_second_study_runs_without_a_process_pool(monkeypatch):
    """A study estimated under POOL_THRESHOLD_S runs in-process when workers is not given (the pool
    cost more than the work); the numbers are those of any worker count."""
    from boresight.studies.montecarlo import study

    asked = []
    real = study.make_engine

    def spy(eng="local", workers=None, *a, **k):
        asked.append(workers)
        return real(eng, workers, *a, **k)

    monkeypatch.setattr(study, "make_engine", spy)
    sc = orbits.load_scenario("scenarios/kiev2012-sensitivity.toml")
    r = mc.montecarlo_study(sc, ["image_plane"], 300, seed=2, chunk_runs=100)
    assert asked == [1]
    r2 = mc.montecarlo_study(sc, ["image_plane"], 300, seed=2, chunk_runs=100, workers=2)
    assert asked == [1, 2]
    assert r.moments["image_plane"].std.tolist() == r2.moments["image_plane"].std.tolist()


def test_preflight_reports_the_sizes_and_the_checkpoint_disk_it_will_use(tmp_path):
    """The pre-flight dict (``run(preflight=…)``): runs, cases, memory, time, and a checkpoint disk
    estimate within a factor 2 of the block files actually written."""
    from boresight.studies.montecarlo.checkpoint import Checkpoint
    from boresight.studies.montecarlo.preflight import format_preflight

    seen = []
    ck = Checkpoint(tmp_path / "ck")

    mc.montecarlo_study(
        "scenarios/kiev2012-kalman20.toml",
        ["image_plane", "kalman_theta"],
        1200,
        seed=1,
        workers=1,
        block_runs=500,
        checkpoint=ck,
        preflight=seen.append,
    )
    (pf,) = seen
    assert pf["runs"] == 1200 and pf["cases"] == 1 and pf["workers"] == 1 and pf["seconds"] > 0 and pf["memory_bytes"] > 0
    disk = sum(p.stat().st_size for p in (tmp_path / "ck").glob("block-*.npz"))
    assert 0.5 * disk <= pf["disk_bytes"] <= 2.0 * disk, (pf["disk_bytes"], disk)
    line = format_preflight(pf)
    assert line.startswith("pre-flight: 1200 runs, 1 worker(s); estimated memory ") and "disk for checkpoints" in line


def test_sigma_is_a_quantity_in_arcsec_like_the_estimate():
    """``MonteCarloResult.sigma`` speaks the unit style of ``Estimate.theta``: an astropy Quantity in
    arcsec, equal to the plain floats of ``sigma_arcsec``."""
    from astropy import units as u

    r = mc.montecarlo_study(SENS, ["image_plane"], 40, seed=1, block_runs=10, workers=1)
    s = r.sigma("image_plane")
    assert s.unit == u.arcsec and s.shape == (len(r.image_counts), 3)
    assert np.array_equal(s.to_value(u.arcsec), r.sigma_arcsec("image_plane"))
