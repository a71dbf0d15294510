"""Pre-flight of a study, before any run: which image counts determine θ, the Kalman filter's
per-image weights, the memory it will need (refused over the budget), the time it will take and
the disk its checkpoints will use, and the line the commands print."""

from __future__ import annotations

import os
import time

import numpy as np

from boresight.errors import ObservabilityError, StudyError
from boresight.studies.montecarlo.chunks import scaled_model, scaled_rows
from orbits.limits import BYTES_PER_OBSERVATION, check_memory
from orbits.rotations import ARCSEC


def observable_counts(sc, nom, algs, counts, *, explicit: bool, notes: list, weighting: str = "unit", model=None) -> tuple:
    """The image counts whose nominal (noise-free) geometry determines θ for every
    least-squares algorithm of the study — the same ``ObservabilityError`` check as
    ``boresight.estimate``. A Kalman-only study checks its largest count (with fewer images the
    filter legitimately returns its prior)."""
    from boresight import estimate

    ls = [a for a in algs if a != "kalman_theta"]
    check = list(counts) if ls else [max(counts)]
    keep: list[int] = []
    first_error: tuple[str, ObservabilityError] | None = None
    for k in counts:
        if k not in check:
            keep.append(k)
            continue
        sub = nom if k == nom.n_images else nom.images(slice(0, k))
        try:
            for a in ls or ["image_plane"]:
                estimate(sub, algorithm=a, iterate=1, weighting=weighting if ls else "unit", model=model if ls else None)
        except ObservabilityError as exc:
            msg = f"{sc.source}: {a} with the first {k} image(s): {exc}"
            if explicit or not ls:
                raise ObservabilityError(
                    msg + (" — choose --image-counts whose images determine θ" if explicit else ""),
                    weak_axis=exc.weak_axis,
                    condition_number=exc.condition_number,
                ) from None
            first_error = first_error or (msg, exc)
            notes.append(f"{k} image(s) skipped: θ is not observable from them ({a}: {' '.join(str(exc).split())})")
            continue
        keep.append(k)
    if not keep:
        assert first_error is not None  # every count was skipped, each with its error
        msg, err = first_error
        raise ObservabilityError(msg, weak_axis=err.weak_axis, condition_number=err.condition_number)
    return tuple(keep)


def kalman_setup(sc, nom, algs, variants, explicit: bool, notes: list):
    """R_n⁻¹ per image and variant and the prior σ for the Kalman kernel; drops "kalman" (with a
    note) when the noise model gives a singular R_n and the filter was not asked for by name."""
    if "kalman_theta" not in algs:
        return algs, {}, 0.0
    from boresight.core.disturbances import DisturbanceModel

    # DECISION: R_n from the nominal geometry, once, for all runs. The module's filter
    # re-evaluates it about each run's estimate; R_n moves by O(|θ|): the estimates agree
    # to 1e-4 of σθ with a 10″ prior and ~1 % of σθ with a 10′ prior
    # (tests/studies/test_montecarlo.py), and it turns 45 000 × 20-image runs from minutes into seconds.
    base_model = DisturbanceModel.from_scenario(sc)
    W = {}
    for vname, factors in variants:
        model = scaled_model(base_model, dict(factors))
        blocks = kalman_weight_blocks(scaled_rows(nom, dict(factors)), model)
        if blocks is None:
            msg = (
                f"{sc.source}: the Kalman filter needs an invertible per-image noise covariance R_n, and this scenario's "
                f"noise model{' (variant ' + vname + ')' if vname else ''} gives a singular one "
                f"(pixel σ = {sc.sigma_pixel_m:g} m): set [pixel] sigma_m > 0"
            )
            if explicit:
                raise StudyError(msg)
            notes.append("kalman_theta skipped: " + msg.split(": ", 1)[1])
            return tuple(a for a in algs if a != "kalman_theta"), {}, 0.0
        W[vname] = blocks
    sigma0 = (sc.theta_sigma0_arcsec if sc.theta_true_arcsec is None else max(np.abs(sc.theta_true_arcsec).max(), 1.0)) * ARCSEC
    return algs, W, sigma0


def kalman_weight_blocks(nom, model) -> list | None:
    """R_n⁻¹ of each image over its own rows, at the nominal geometry: a list of N (2m_n, 2m_n)
    arrays (the Kalman kernel's ``W``, ``batched.kalman_theta_kernel``), or None when some R_n is
    singular. R_n is ``gls.structure.image_covariance_rows``, images grouped by their row count
    (never 2T × 2T). R_n = σK² E + (PSD terms) is positive definite whenever σK > 0; only without
    pixel noise can it be singular, and only then are its eigenvalues worth their cost."""
    from boresight.core.gls.structure import has_pixel_noise, image_covariance_rows, images_by_row_count

    blocks: list = [None] * nom.n_images
    for m, idx in images_by_row_count(nom):
        if m == 0:
            for n in idx:
                blocks[n] = np.zeros((0, 0))
            continue
        Rn = image_covariance_rows(nom.images(idx), np.zeros(3), model)[0]  # (u, 2m, 2m)
        singular = not np.all(np.isfinite(Rn))
        if not singular and not has_pixel_noise(nom, model):
            ev = np.linalg.eigvalsh(Rn)
            singular = not np.all(ev[:, 0] > 1e-12 * np.maximum(ev[:, -1], 1e-300))
        if singular:
            return None
        for n, w in zip(idx, np.linalg.inv(Rn)):
            blocks[n] = np.ascontiguousarray(w)
    return blocks


def kalman_iterations_for(sigma0_rad: float, tol_rad: float = 1e-4 * ARCSEC) -> int:
    """IEKF steps per image for a prior σ0: at least 3, and enough that the quadratic
    convergence bound (4σ0)^(2^k) (rad; a 4σ0 start) falls below ``tol_rad`` (1e-4″).

    DECISION: the Kalman kernel iterates a fixed number of times per image (bit-identical
    chunks, no per-run branching); with a 10′ prior 3 steps converge (the seminar's case), with a
    10° prior 6 are needed — fixed 3 steps gave σθ 1.5 % too large (tests/project/test_reliability.py).

    >>> kalman_iterations_for(600 * ARCSEC), kalman_iterations_for(36000 * ARCSEC)
    (3, 6)
    """
    e = min(4.0 * float(sigma0_rad), 0.9)
    k = 3
    while e ** (2**k) > tol_rad and k < 12:
        k += 1
    return k


#: a weighted study's chunk holds at most this much of the library estimator's working set per worker
WEIGHTED_CHUNK_BYTES = 256 * 2**20


def weighted_bytes_per_run(nom, algs, counts, weighting, model) -> tuple[float, float]:
    """Peak bytes per run of ``boresight.estimate`` under ``weighting`` on this scenario (the
    largest image count, the hungriest least-squares algorithm), measured with ``tracemalloc``
    on two noise-free runs, × 1.5; and the seconds per run of its estimates (one warm-up step on one
    run, × 3 steps × the image counts: the pre-flight's time model for weighted studies).

    DECISION: measured, not modelled: the block-sparse GLS's working set depends on the
    passes, the landmark groups and the error modes (0.03 MB per run for the one-image eq 28
    case, 0.3 MB for 20 images, 9 MB for the 6-pass campaign), and a formula would drift from
    the code. The measurement costs one two-run estimate.
    """
    import tracemalloc

    from boresight import estimate

    ls = [a for a in algs if a != "kalman_theta"]
    if not ls:
        return 0.0, 0.0
    k = max(counts)
    sub = nom if k == nom.n_images else nom.images(slice(0, k))
    two = sub.run(np.zeros(2, int))
    peak, seconds = 0, 0.0
    was_tracing = tracemalloc.is_tracing()
    for a in ls:
        t0 = time.perf_counter()
        estimate(sub, a, weighting=weighting, model=model, iterate=1)  # warm-up: first-call caches
        # the time of one library step on one run × ~3 steps per run × the image counts (pre-flight)
        seconds += 3 * len(counts) * (time.perf_counter() - t0)
        if not was_tracing:
            tracemalloc.start()
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        try:
            estimate(two, a, weighting=weighting, model=model, iterate=1)
            peak = max(peak, tracemalloc.get_traced_memory()[1] - base)
        finally:
            if not was_tracing:
                tracemalloc.stop()
    return 1.5 * peak / 2, seconds


#: bookkeeping bytes per planned chunk (a list of block segments)
_BYTES_PER_CHUNK = 200
#: bytes per drawn error component in a block (θ, δ, GNSS, catalogue, pixel noise: float64)
_BYTES_PER_DRAW = 8


def study_bytes(
    runs,
    chunk_runs,
    block_runs,
    obs_per_run,
    n_counts,
    n_algs,
    n_variants,
    keep_runs,
    workers,
    weighted_bytes_per_run: float = 0.0,
) -> float:
    """The study's working set (bytes): each worker holds its chunk's simulation and estimator
    arrays and the blocks it draws (and, under diagonal/GLS weighting, the library estimator's
    working set: ``weighted_bytes_per_run``); the driver holds the chunk plan and the kept samples."""
    # DECISION: the cases (base and scaled variants) are estimated one after the other on the same
    # draws, so the working set is one case's plus every case's per-run errors — not n_variants
    # times it (traced peak of a 13-run campaign-6pass chunk: 25 MB with 1 case, 28 MB with 7;
    # 130-270 bytes per observation per run, under BYTES_PER_OBSERVATION)
    n_chunks = -(-runs // chunk_runs)
    per_worker = (
        min(chunk_runs, runs)
        * (obs_per_run * BYTES_PER_OBSERVATION + weighted_bytes_per_run + n_variants * n_counts * n_algs * 3 * 8 * 4)
        + min(block_runs, runs) * obs_per_run * 2 * _BYTES_PER_DRAW * 2
    )
    driver = n_chunks * _BYTES_PER_CHUNK + min(runs, keep_runs) * n_counts * 3 * 8 * n_algs * 2
    return float(workers) * per_worker + driver


def check_study_memory(nbytes: float, runs: int, chunk_runs: int, block_runs: int, obs_per_run: int, workers: int) -> float:
    """Refuse a study whose working set ``nbytes`` (``study_bytes`` of these sizes) exceeds the
    memory budget (``orbits.limits``), naming the sizes that set it; returns ``nbytes``."""
    check_memory(
        f"the study (--runs {runs}, {obs_per_run} observations per run, chunks of {min(chunk_runs, runs)} runs, "
        f"blocks of {min(block_runs, runs)}, {workers} worker(s))",
        nbytes,
        hint="fewer runs, smaller --chunk-runs/--block-runs or fewer --workers",
    )
    return nbytes


#: fixed seconds of a study after its pre-flight (the chunk plan, the accumulator, predictions, the result)
SECONDS_FIXED = 0.15
#: a study measured (one worker, ``measured_seconds_per_run``) below this many seconds runs in-process when
#: ``workers`` is not given: starting the default two-worker pool costs 0.6-1.3 s CPU,
#: more than such a study's own work
POOL_THRESHOLD_S = 1.0


#: the pilot's timed stretch (s): long enough to time numpy's work rather than its call overhead
PILOT_SECONDS = 0.3
#: the speed-up per worker of a process pool on a shared machine (2 workers on 2 busy cores: 1.4×,
#: campaign-6pass and kiev2012-sensitivity, 2026-11-27)
WORKER_EFFICIENCY = 0.7
#: wall seconds to start a process pool and ship the job to it (forked workers; measured 0.2-0.5 s wall
#: on 2 shared cores, 2026-11-27)
POOL_START_SECONDS = 0.3


def measured_seconds_per_run(job, runs: int, chunk_runs: int) -> tuple[float, float]:
    """(seconds per run, seconds per chunk call) of this study's own work — its draws, every
    algorithm and case — measured on its first block (the size model was 30-300× off on a
    loaded machine: the README's 2 000-run GLS study, 3 s of work, was announced as "~12 min").

    The first call draws block 0 into ``chunks.run_chunk``'s per-process cache (which an
    in-process study reuses) and estimates one run, warming the first-call caches; its time less
    one run's is the block's draw (an upper bound: the caches are in it). Then 2, 4, 8, …
    runs (block 0's, repeated past its end) until a call takes ``PILOT_SECONDS`` or reaches the
    study's chunk size (numpy's cost per run falls with the size of the call). The cost per
    run is the least-squares slope of time against runs over those calls and the cost per call its
    intercept (numpy's per-call overhead, paid once per chunk) when they are sane, else the
    smaller time per run of the two largest calls (a busy machine's noise only adds time). The pilot's results are discarded (the study's own,
    from the same draws, are identical).

    DECISION: a measurement on the machine as it is (its load, its BLAS), not a model of the sizes;
    the price is ~0.3 s plus the first block's draw, which the study then reuses in-process."""
    from boresight.studies.montecarlo.chunks import run_chunk

    in_block = min(int(job.block_runs), int(runs))
    t0 = time.perf_counter()
    run_chunk(job, [(0, 0, 1)])  # draws block 0 (cached for the study) and warms the first-call caches
    first = time.perf_counter() - t0
    calls: list[tuple[int, float]] = []
    n = 2
    # up to a chunk's runs (the size the study calls with), block 0's runs repeated as needed
    while n <= min(int(runs), int(chunk_runs)):
        segments = [(0, 0, in_block)] * (n // in_block) + ([(0, 0, n % in_block)] if n % in_block else [])
        t0 = time.perf_counter()
        run_chunk(job, segments)
        calls.append((n, time.perf_counter() - t0))
        if calls[-1][1] >= PILOT_SECONDS:
            break
        n *= 2
    if not calls:  # a block of one or two runs: the warm-up is all there is
        return first, 0.0
    n_all = np.array([c[0] for c in calls], float)
    t_all = np.array([c[1] for c in calls], float)
    # the two largest calls' time per run, the smaller: a busy machine's noise only ever adds time
    per_run, per_call = float(np.min(t_all[-2:] / n_all[-2:])), 0.0
    if len(calls) > 2:  # t = per_call + n · per_run, least squares over the calls
        slope, intercept = np.polyfit(n_all, t_all, 1)
        if 0.0 < slope < per_run and intercept >= 0.0:
            per_run, per_call = float(slope), float(intercept)
    # the block's draw: the warm-up call less its one run (first-call caches included: an upper bound)
    draw_per_run = max(first - per_call - per_run, 0.0) / max(in_block, 1)
    if os.environ.get("BORESIGHT_PREFLIGHT_DEBUG"):
        print(
            f"pilot: first {first:.4f} s, calls {calls}, per run {per_run:.3g} s, per call {per_call:.3g} s, draw/run {draw_per_run:.3g} s"
        )
    return draw_per_run + per_run, per_call


#: checkpoints larger than this are announced with how to avoid them (``format_preflight``)
LARGE_CHECKPOINT_BYTES = 2**30


def checkpoint_bytes(runs, block_runs, n_counts, n_algs, n_variants, keep_runs, weighted: bool = False) -> float:
    """Disk of a study's block checkpoints (``checkpoint.Checkpoint.save``): per block, every
    streamed statistic (count, mean, M2, max |·| per image count and axis) and the non-converged
    counts, ~200 bytes of npz header per array; and the kept error samples."""
    n_blocks = -(-runs // block_runs)
    keys = n_algs * (1 + 2 * (n_variants - 1) + (1 if weighted else 0))
    arrays = keys * 4 + n_algs * n_variants  # moments' 4 arrays per key; one unconverged array per estimate key
    per_block = keys * 3 * n_counts * 3 * 8 + arrays * 200 + n_algs * n_variants * n_counts * 8
    return float(n_blocks * per_block + min(runs, keep_runs) * n_counts * 3 * 8 * n_algs)


#: resident memory of a study process before its arrays (python, numpy, scipy, astropy, boresight):
#: `sensitivity kiev2012-sensitivity --runs 2 --workers 1` peaks at 138 MB RSS. Not counted against
#: the budget (it is there whatever the sizes); the pre-flight line states it. Forked workers share
#: most of these pages, so "up to".
LIBRARY_BYTES_PER_PROCESS = 140 * 2**20


def format_preflight(pf: dict) -> str:
    """The pre-flight line: runs, cases, workers, estimated memory (of the budget), time and the
    disk for checkpoints."""
    from orbits.limits import memory_budget_bytes

    def size(n):
        return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MB" if n >= 2**20 else f"{n / 2**10:.0f} kB"

    def dur(t):
        return f"{t:.0f} s" if t < 120 else f"{t / 60:.0f} min" if t < 7200 else f"{t / 3600:.1f} h"

    cases = f" × {pf['cases']} cases" if pf["cases"] > 1 else ""
    procs = 1 if pf["workers"] <= 1 else pf["workers"] + 1
    measured = " (measured on its first runs)" if pf.get("measured") else ""
    large = (
        f" — over {size(LARGE_CHECKPOINT_BYTES)}: a larger --block-runs writes fewer, larger block "
        "files; or give an --out on a disk with room"
        if pf["disk_bytes"] > LARGE_CHECKPOINT_BYTES
        else ""
    )
    return (
        f"pre-flight: {pf['runs']} runs{cases}, {pf['workers']} worker(s); estimated memory {size(pf['memory_bytes'])} "
        f"(budget {size(memory_budget_bytes())}; plus up to {size(procs * LIBRARY_BYTES_PER_PROCESS)} of loaded libraries), "
        f"time ~{dur(pf['seconds'])}{measured}, disk for checkpoints {size(pf['disk_bytes'])}{large}"
    )
