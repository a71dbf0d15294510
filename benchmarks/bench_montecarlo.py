"""Benchmark of the Monte Carlo engine (not part of the test run): prints its figures.

    python benchmarks/bench_montecarlo.py [--workers 2] [--runs 45000] [--skip-million]

1. The Kiev 2012 sensitivity case (one image, 4 landmarks), 45 000 runs, each least-squares
   algorithm and the Kalman variant alone: runs/s and landmark observations/s (end to end:
   draws, simulation, estimation, statistics).
2. The whole eq 28 study: base case + one scaled set per source (β1, β2, β3, P, R, K), 45 000
   runs each, every least-squares algorithm, common random numbers — wall time (target ≤ 5 s).
3. The 20-image Kalman study (``kiev2012.kalman_scenario``), 45 000 runs (target ≤ 5 s).
4. Speed-up over a straightforward per-run Python loop on the same inputs (≥ 500 runs):
   Gauss-Newton with ``numpy.linalg.solve`` per run (Algorithm 3) and filterpy's
   ``KalmanFilter`` per run and image (target ≥ 200×).
5. Peak RSS (this process + workers, sampled with psutil) at 45 000 and 10⁶ runs (≤ 500 MB).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from machine import machine_line  # benchmarks/machine.py

import orbits  # noqa: E402
from boresight.reproductions import kiev2012  # noqa: E402
from boresight.studies import montecarlo as mc  # noqa: E402
from boresight.studies import sensitivity as se  # noqa: E402
from orbits.rotations import ARCSEC  # noqa: E402

SENS = os.path.join(os.path.dirname(__file__), "..", "scenarios", "kiev2012-sensitivity.toml")


class PeakRSS:
    """Peak of the summed RSS of this process and its children, sampled every 0.25 s."""

    def __init__(self):
        import psutil

        self.proc = psutil.Process()
        self.peak = 0
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    def _rss(self):
        # PSS (proportional set size): pages shared by fork between parent and workers are
        # counted once, not once per process as a plain RSS sum would.
        total = self.proc.memory_full_info().pss
        for c in self.proc.children(recursive=True):
            try:
                total += c.memory_full_info().pss
            except Exception:  # a worker that just exited
                pass
        return total

    def _run(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, self._rss())
            time.sleep(0.25)  # memory_full_info parses smaps: sample sparingly

    def __enter__(self):
        self._t.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._t.join()
        self.peak = max(self.peak, self._rss())


def loop_least_squares(s0, xy, F, iterations=2):
    """Straightforward reference: one run at a time, Gauss-Newton with numpy.linalg.solve."""
    from boresight.core.algorithms.image_plane import misalignment_jacobian, projection_jacobian
    from orbits.rotations import misalignment_dcm, skew

    out = np.empty((s0.shape[0], 3))
    for r in range(s0.shape[0]):
        theta = np.zeros(3)
        for _ in range(iterations):
            s = s0[r].reshape(-1, 3) @ misalignment_dcm(theta).T
            pred = -F * s[:, :2] / s[:, 2:3]
            q = (xy[r].reshape(-1, 2) - pred).reshape(-1)
            G = (projection_jacobian(s, F) @ skew(s) @ misalignment_jacobian(theta)).reshape(-1, 3)
            theta = theta + np.linalg.solve(G.T @ G, G.T @ q)
        out[r] = theta
    return out


def loop_kalman(s0, xy, F, R_img, sigma0_rad, iterations=3):
    """Straightforward reference: filterpy KalmanFilter, one run at a time, IEKF per image."""
    from filterpy.kalman import KalmanFilter

    from boresight.core.algorithms.image_plane import misalignment_jacobian, projection_jacobian
    from orbits.rotations import misalignment_dcm, skew

    R_, N = s0.shape[:2]
    m = 2 * s0.shape[2]
    out = np.empty((R_, N, 3))
    for r in range(R_):
        kf = KalmanFilter(dim_x=3, dim_z=m)
        kf.x = np.zeros((3, 1))
        kf.P = np.eye(3) * sigma0_rad**2
        kf.Q = np.zeros((3, 3))  # θ is constant (filterpy's default Q is the identity)
        for n in range(N):
            kf.predict()
            x_lin = kf.x_prior[:, 0].copy()
            for _ in range(iterations):
                s = s0[r, n] @ misalignment_dcm(x_lin).T
                pred = -F * s[:, :2] / s[:, 2:3]
                res = (xy[r, n] - pred).reshape(-1)
                H = (projection_jacobian(s, F) @ skew(s) @ misalignment_jacobian(x_lin)).reshape(-1, 3)
                kf.x, kf.P = kf.x_prior.copy(), kf.P_prior.copy()
                kf.update((res + H @ x_lin).reshape(m, 1), R=R_img[n], H=H)
                x_lin = kf.x[:, 0].copy()
            out[r, n] = kf.x[:, 0]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--runs", type=int, default=45000)
    ap.add_argument("--loop-runs", type=int, default=500)
    ap.add_argument("--skip-million", action="store_true")
    a = ap.parse_args(argv)
    print(machine_line())  # where the figures below were taken
    W, R = a.workers, a.runs
    print(f"workers = {W}")
    sc = orbits.load_scenario(SENS)
    n_obs = sum(len(p.t_s) for p in sc.passes) * 4

    # warm the imports (fork start method: workers inherit them)
    mc.montecarlo_study(sc, "all", 200, seed=0, workers=1)

    print(f"\n1. Kiev sensitivity case, {R} runs per algorithm (end to end, {W} workers)")
    for name in mc.ALGORITHMS:
        t0 = time.perf_counter()
        r = mc.montecarlo_study(sc, [name], R, seed=1, workers=W)
        dt = time.perf_counter() - t0
        sd = r.moments[name].std[-1]
        print(
            f"   {name:<13} {dt:6.2f} s  {R / dt:10.0f} runs/s  {R * n_obs / dt:11.0f} landmark obs/s   σθ = {sd[0]:.3f}/{sd[1]:.3f}/{sd[2]:.3f}″"
        )

    print(f"\n2. eq 28 study: base + 6 scaled sources x {R} runs, {', '.join(mc.LEAST_SQUARES)} ({W} workers)")
    with PeakRSS() as mem:
        t0 = time.perf_counter()
        st = se.sensitivity_study(sc, mc.LEAST_SQUARES, runs=R, seed=1, workers=W)
        dt_study = time.perf_counter() - t0
    print(
        f"   wall {dt_study:.2f} s (target ≤ 5 s)   = {7 * 3 * R / dt_study:.0f} estimates/s   peak RSS {mem.peak / 2**20:.0f} MB"
    )
    print(f"   FD vs analytic: max |Δ|/SE = {max(st.agreement.values()):.2f}")

    print(f"\n3. 20-image Kalman study, {R} runs ({W} workers)")
    sck = kiev2012.kalman_scenario(10.0)
    with PeakRSS() as mem:
        t0 = time.perf_counter()
        rk = mc.montecarlo_study(sck, ["kalman_theta"], R, seed=1, workers=W)
        dt_k = time.perf_counter() - t0
    sd = rk.moments["kalman_theta"].std
    print(
        f"   wall {dt_k:.2f} s (target ≤ 5 s)  {R / dt_k:.0f} runs/s  {R * 80 / dt_k:.0f} landmark obs/s  peak RSS {mem.peak / 2**20:.0f} MB"
    )
    print("   images: " + "  ".join(f"{k}: {s[0]:.2f}/{s[1]:.2f}/{s[2]:.2f}″" for k, s in zip(rk.image_counts, sd)))

    print(
        f"\n4. speed-up over a per-run Python loop ({a.loop_runs} runs, same inputs, estimation only, 1 process;"
        " vectorised kernels in the engine's chunks)"
    )
    from boresight.core.disturbances import DisturbanceModel

    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
    from oracles import image_covariance  # the images × landmarks layout of the per-image blocks (a test oracle)

    from boresight.observations.model import from_measurements
    from boresight.studies.montecarlo.preflight import kalman_weight_blocks

    # the vectorised kernels are timed as the engine runs them: in chunks of default_chunk_runs, each chunk
    # simulated on its own (as the engine draws it). DECISION: not one simulate(runs=R) sliced into chunks —
    # an ObservationSet's mask is shared by its runs, so at R = 45 000 some run pushed every landmark of the
    # one-image sensitivity case off the detector and the kernel got no observation (the crash of
    # `--skip-million` at its default size; the smoke run's 200 runs never met it).
    def chunks(scenario, seed, per_chunk):
        rng = np.random.default_rng(seed)
        out = []
        for i in range(0, R, per_chunk):
            # as the engine builds its chunks (studies/montecarlo/chunks.py): every nominal row kept in every run.
            # Not boresight.simulate, which drops a row from every run of the batch when one run's point lands
            # beyond the detector (detector_edge=True): at 5 000 runs a chunk kept 1 of the 4 landmarks and
            # the kernel met a singular 3 x 3 normal matrix (the RuntimeWarnings of earlier runs).
            o = from_measurements(orbits.simulate_passes(scenario, rng, runs=min(per_chunk, R - i)))  # complete rows
            out.append((mc.camera_vectors0(o), o))
        return out

    L = a.loop_runs
    c = mc.default_chunk_runs(4, ("image_plane",))
    parts = chunks(sc, 5, c)
    t0 = time.perf_counter()
    th_vec = np.concatenate([mc.image_plane_kernel(s0, o.xy_m, o.focal_length_m, 2) for s0, o in parts])
    t_vec = (time.perf_counter() - t0) / R
    s0, obs = parts[0]
    L = min(L, obs.runs)
    grid = (obs.runs, obs.n_images, obs.n_targets)  # the loops' images × landmarks layout (a complete set's view)
    t0 = time.perf_counter()
    th_loop = loop_least_squares(s0.reshape(grid + (3,))[:L], obs.row_xy_grid()[:L], obs.focal_length_m)
    t_loop = (time.perf_counter() - t0) / L
    print(
        f"   least squares (Alg 3): loop {1 / t_loop:8.0f} runs/s, vectorised {1 / t_vec:9.0f} runs/s: {t_loop / t_vec:6.0f}x"
        f"  (max |Δθ| {np.abs(th_vec[:L] - th_loop).max() / ARCSEC:.1e}″)"
    )
    model = DisturbanceModel.from_scenario(sck)
    Rimg = image_covariance(mc.nominal_observations(sck), np.zeros(3), model)[0]
    c = mc.default_chunk_runs(80, ("kalman_theta",))
    Wk = kalman_weight_blocks(mc.nominal_observations(sck), model)
    parts = chunks(sck, 6, c)
    t0 = time.perf_counter()
    xh = np.concatenate(
        [mc.kalman_theta_kernel(s0k, o.xy_m, o.row_start, o.focal_length_m, Wk, 10 * ARCSEC, 3)[0] for s0k, o in parts]
    )
    t_vec = (time.perf_counter() - t0) / R
    s0k, obk = parts[0]
    grid = (obk.runs, obk.n_images, obk.n_targets)
    t0 = time.perf_counter()
    xl = loop_kalman(s0k.reshape(grid + (3,))[:L], obk.row_xy_grid()[:L], obk.focal_length_m, Rimg, 10 * ARCSEC)
    t_loop = (time.perf_counter() - t0) / L
    print(
        f"   Kalman, 20 images:     loop {1 / t_loop:8.0f} runs/s, vectorised {1 / t_vec:9.0f} runs/s: {t_loop / t_vec:6.0f}x"
        f"  (max |Δθ| {np.abs(xh[:L] - xl).max() / ARCSEC:.1e}″)"
    )

    print("\n5. peak memory (PSS of a fresh process + its workers)")
    import subprocess

    for scen, runs in [("sens", R), ("kalman20", R)] + ([] if a.skip_million else [("sens", 1_000_000)]):
        out = subprocess.run(
            [sys.executable, __file__, "--memory-only", scen, str(runs), str(W)], capture_output=True, text=True, check=True
        )
        print("   " + out.stdout.strip())


def memory_only(scen, runs, workers):
    sc = orbits.load_scenario(SENS) if scen == "sens" else kiev2012.kalman_scenario(10.0)
    with PeakRSS() as mem:
        t0 = time.perf_counter()
        mc.montecarlo_study(sc, "all", runs, seed=1, workers=workers)
        dt = time.perf_counter() - t0
    print(f"{sc.name}, all algorithms, {runs:>8} runs: peak {mem.peak / 2**20:6.0f} MB, {dt:.1f} s")


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--memory-only":
        memory_only(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))
    else:
        main()
