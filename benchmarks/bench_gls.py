"""Benchmark of the block-sparse campaign GLS (not part of the test run): one fit per process.

    python benchmarks/bench_gls.py [campaign] [--solver fast|dense]   # scenarios/campaign-6pass.toml (the default)
    python benchmarks/bench_gls.py large [--images 10000] [--solver fast|dense]
    python benchmarks/bench_gls.py compare                             # fast vs dense, 120-image campaign
    python benchmarks/bench_gls.py rows [--rows 1000000 --targets 100000 --images 10000] [--path auto|dense|sparse]
    python benchmarks/bench_gls.py tiles [--tiles 1|10|100] [--shared]

``campaign``: the 6-pass, 120-image, 1 320-observation campaign (Kiev 2012 noise, star-tracker
and GNSS errors per image and per pass, catalogue errors), simulated with seed 0 and fitted by
``estimate(obs, weighting="gls", model=...)`` (the block-sparse solver) or, with
``--solver dense``, by the same Gauss-Newton loop on the dense route it replaced
(``tests/oracles.py:dense_gls_reference``). ``large``: 20 site-tracking passes over one site whose
10 landmarks every image sees (``--images`` in all, 10 000 by default), same noise model. Each
prints its in-process fit time, θ ± σ and its peak RSS; time the whole process from outside
(start-up, simulation and fit), e.g. ``/usr/bin/time -v python benchmarks/bench_gls.py campaign``,
pairing it with ``--solver dense`` for the ratio, or with ``--solver none`` (start-up and
simulation only) to isolate the fit. ``compare`` prints the largest relative
difference of θ and covariance between the two solvers on the campaign (the target is 1e-9).

``rows``: the GLS on rows alone (``boresight.core.gls.rows``) on a synthetic bundle-adjustment
strip — ``--targets`` targets each seen by ``--rows / --targets`` consecutive images of ``--images``,
20 passes, star-tracker/GNSS columns per image and per pass (6 + 6) and catalogue columns, random
whitened values (seed 0), one run: the fit, the MAP nuisances, the pixel-level residuals and the
reduced rows (no leverage: the reduced system is sparse at this size).

``tiles``: the GLS on rows of campaign-6pass (its rows, columns and noise model at the true θ,
through ``tests/oracles.dense_rows``) with every observation its own ground-control point
(single-use targets; ``--shared``: the landmarks as flown), tiled ``--tiles`` times as independent
campaigns (new images, passes and targets; the same values): the fit, residuals and reduced rows
at 1 320 × tiles rows. θ of a tiled campaign equals the single one's, σ scales by 1/√tiles.

Figures and the exact commands are in docs/estimators.md ("Speed of the campaign fit").
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import orbits  # noqa: E402
from boresight import estimate, simulate  # noqa: E402
from boresight.core.algorithms import image_plane  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from machine import machine_line  # benchmarks/machine.py
from oracles import dense_gls_reference, dense_grid, dense_rows, on_grid  # noqa: E402  (the test oracles: the dense route)

from boresight.core.disturbances import DisturbanceModel  # noqa: E402
from orbits.rotations import ARCSEC  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
CAMPAIGN = os.path.join(HERE, "..", "scenarios", "campaign-6pass.toml")


def campaign():
    sc = orbits.load_scenario(CAMPAIGN)
    return simulate(sc, np.random.default_rng(0)), DisturbanceModel.from_scenario(sc)


def large(images: int, passes: int = 20):
    """``passes`` site-tracking passes over one site; every image sees the same 10 landmarks."""
    import tomllib
    from dataclasses import replace

    with open(CAMPAIGN, "rb") as fh:
        d = tomllib.load(fh)
    per = images // passes
    site = d["passes"][0]
    step = 95.0 / max(per - 1, 1)
    field = {"layout": "random", "n": 10, "half_width_km": 12.0, "height_sigma_m": 300.0, "seed": 7, "placement": "sphere"}
    d["passes"] = [
        dict(
            site,
            direction=("ascending", "descending")[k % 2],
            landmarks=field,
            t_s={"start": -47.5, "stop": -47.5 + (per - 1) * step + 1e-9, "step": step},
        )
        for k in range(passes)
    ]
    sc = orbits.scenario_from_dict(d)
    obs = dense_grid(simulate(sc, np.random.default_rng(0)))  # built on the grid (tests/oracles.py), then rows
    # the passes' landmark fields are the same ground points: one column per landmark
    ids = [f"M{j + 1}" for j in range(10)]
    xy = sum(obs.xy_m[:, :, k * 10 : (k + 1) * 10] for k in range(passes))
    mask = np.zeros((obs.n_images, 10), bool)
    for k in range(passes):
        mask |= obs.mask[:, k * 10 : (k + 1) * 10]
    obs = replace(
        obs,
        landmark_ids=np.array(ids),
        landmark_g_m=obs.landmark_g_m[:, :10],
        xy_m=xy,
        mask=mask,
        truth={"theta_rad": obs.truth["theta_rad"]},
    ).to_rows()
    return obs, DisturbanceModel.from_scenario(sc)


def dense_fit(obs, model, max_iter=20):
    """Today's dense GLS: the Gauss-Newton loop of estimate() on the dense normal equations."""
    theta = np.zeros((obs.runs, 3))
    for _ in range(max_iter):
        G, q = on_grid(image_plane.linearize, obs, theta)  # the grid layout of the dense route
        sol = dense_gls_reference(obs, theta, G, q, model).solve()
        theta = theta + sol.theta
        if np.max(np.abs(sol.theta)) < 1e-6 * ARCSEC:
            break
    return theta[0] / ARCSEC, sol.covariance[0] / ARCSEC**2


def fast_fit(obs, model):
    est = estimate(obs, weighting="gls", model=model)
    return est.theta.value, est.covariance.value


def report(name, obs, fit, model):
    t = time.perf_counter()
    theta, cov = fit(obs, model)
    dt = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    sig = np.sqrt(np.diag(cov))
    print(
        f"{name}: {obs.n_images} images, {obs.n_landmarks} landmarks, {obs.n_observations} observations; "
        f"fit {dt:.3f} s in process; peak RSS {peak:.0f} MB"
    )
    print("theta " + ", ".join(f"{a:+.4f} ± {b:.4f}" for a, b in zip(theta, sig)) + " arcsec")
    return theta, cov


def rows_case(n_rows: int, n_targets: int, n_images: int, path: str) -> None:
    """The synthetic strip of the module docstring through the GLS on rows."""
    from boresight.core.gls.rows import RowColumns, RowStructure, row_gls, row_reduced_rows, row_residuals

    rng = np.random.default_rng(0)
    seen = max(n_rows // n_targets, 2)
    first = (np.arange(n_targets) * (n_images - seen)) // max(n_targets - 1, 1)
    img = (first[:, None] + np.arange(seen)).ravel()
    tgt = np.repeat(np.arange(n_targets), seen)
    order = np.lexsort((tgt, img))
    st = RowStructure(img[order], tgt[order], np.arange(n_images) * 20 // n_images, n_targets)
    K = st.n_rows
    cols = RowColumns(
        X=rng.normal(size=(1, K, 2, 3)),
        q=rng.normal(size=(1, K, 2)),
        A=0.3 * rng.normal(size=(1, K, 2, 6)),
        B=0.05 * rng.normal(size=(1, K, 2, 6)),
        C=0.5 * rng.normal(size=(1, K, 2, 3)),
    )
    c0 = time.process_time()
    fit = row_gls(st, cols, path=path)
    c1 = time.process_time()
    sol = fit.normal_equations.solve(check=False)
    e = row_residuals(fit, sol.theta)
    c2 = time.process_time()
    _, zt = row_reduced_rows(fit, None, leverage=False)
    c3 = time.process_time()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"rows: {K} rows, {n_targets} targets, {n_images} images, path {fit.path}; CPU fit {c1 - c0:.2f} s, "
        f"residuals {c2 - c1:.2f} s, reduced rows {c3 - c2:.2f} s; peak RSS {peak:.0f} MB; "
        f"rms residual {np.sqrt(np.mean(e**2)):.4f}"
    )


def tiles_case(tiles: int, shared: bool) -> None:
    """campaign-6pass's rows (single-use targets unless ``shared``) tiled ``tiles`` times, through row_gls."""
    from boresight.core.gls.rows import RowColumns, RowStructure, row_gls, row_reduced_rows, row_residuals

    obs, model = campaign()
    th = obs.truth["theta_rad"]
    G, q = on_grid(image_plane.linearize, obs, th)  # dense_rows takes the grid layout
    st1, c1 = dense_rows(obs, th, G, q, model)
    T1 = st1.n_targets if shared else st1.n_rows
    t1 = st1.target_index if shared else np.arange(st1.n_rows)
    P1 = int(np.max(st1.pass_of_image)) + 1
    k = np.arange(tiles)[:, None]
    st = RowStructure(
        (st1.image_index + k * st1.n_images).ravel(),
        (t1 + k * T1).ravel(),
        (st1.pass_of_image + k * P1).ravel(),
        T1 * tiles,
    )
    cols = RowColumns(*(np.tile(Z, (1, tiles) + (1,) * (Z.ndim - 2)) for Z in (c1.X, c1.q, c1.A, c1.B, c1.C)))
    c0 = time.process_time()
    fit = row_gls(st, cols)
    sol = fit.normal_equations.solve()
    e = row_residuals(fit, sol.theta)
    _, zt = row_reduced_rows(fit, None, leverage=False)
    cpu = time.process_time() - c0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    sig = np.sqrt(np.diag(sol.covariance[0])) / ARCSEC
    print(
        f"tiles x{tiles} ({'shared' if shared else 'single-use'}): {st.n_rows} rows, {st.n_images} images, "
        f"{st.n_targets} targets, path {fit.path}; CPU (fit, residuals, reduced rows) {cpu:.2f} s; peak RSS {peak:.0f} MB; "
        f"dθ {np.round(sol.theta[0] / ARCSEC, 6).tolist()} arcsec, σ {np.round(sig, 6).tolist()} arcsec; rms e {np.sqrt(np.mean(e**2)):.4f}"
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "case", nargs="?", default="campaign", choices=("campaign", "large", "compare", "rows", "tiles"), help="default: campaign"
    )
    ap.add_argument(
        "--solver",
        choices=("fast", "dense", "none"),
        default="fast",
        help="none: start-up and simulation only (the yardstick that isolates the fit)",
    )
    ap.add_argument("--images", type=int, default=10000)
    ap.add_argument("--rows", type=int, default=1000000)
    ap.add_argument("--targets", type=int, default=100000)
    ap.add_argument("--path", choices=("auto", "dense", "sparse"), default="auto")
    ap.add_argument("--tiles", type=int, default=1)
    ap.add_argument("--shared", action="store_true")
    a = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    if a.case == "rows":
        rows_case(a.rows, a.targets, a.images, a.path)
        return
    if a.case == "tiles":
        tiles_case(a.tiles, a.shared)
        return
    if a.case == "compare":
        obs, model = campaign()
        t1, c1 = report("fast", obs, fast_fit, model)
        t2, c2 = report("dense", obs, dense_fit, model)
        print(
            f"max relative difference: theta {np.max(np.abs(t1 - t2)) / np.max(np.abs(t2)):.2e}, "
            f"covariance {np.max(np.abs(c1 - c2)) / np.max(np.abs(c2)):.2e}"
        )
        return
    obs, model = campaign() if a.case == "campaign" else large(a.images)
    if a.solver == "none":
        print(f"{a.case}: {obs.n_images} images, {obs.n_observations} observations simulated; no fit")
        return
    report(f"{a.case} ({a.solver})", obs, fast_fit if a.solver == "fast" else dense_fit, model)


if __name__ == "__main__":
    main()
