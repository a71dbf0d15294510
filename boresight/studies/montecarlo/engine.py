"""The Monte Carlo engine: seeding by blocks, chunks, local and dask engines, the study ``run``."""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from boresight.core import registry
from boresight.core.error_sources import ERROR_SOURCES
from boresight.errors import ObservabilityError, StudyError
from orbits.limits import BYTES_PER_OBSERVATION, check_memory
from orbits.rotations import ARCSEC

from boresight.studies.montecarlo.kernels import (
    _scaled_model, camera_vectors0, ground_plane_kernel, image_plane_kernel, kalman_theta_kernel,
    nominal_observations, unit_vector_kernel, weighted_kernel,
)
from boresight.studies.montecarlo.lifetime import die_with_parent
from boresight.studies.montecarlo.moments import Moments
from boresight.studies.montecarlo.sample_size import achieved_epsilon, sigma_interval

#: every algorithm the engine runs (those with a kernel in boresight.core.registry); "all" in the CLI means these
ALGORITHMS = registry.montecarlo_names()
#: the least-squares ones (Kiev 2012 eqs 18, 22, 31)
LEAST_SQUARES = registry.least_squares_names()
#: runs per random-number block (part of the result's identity, like the seed)
BLOCK_RUNS = 1000
#: image counts a study reports σθ at by default (those ≤ the scenario's images, plus all of them).
# DECISION: a roughly doubling grid up to 20, the grid of the seminar's Kalman table, so the
# default study lines up with it; the seminar's own rows are defined once, in
# ``reproductions.kiev2012.published`` (SEMINAR_IMAGE_COUNTS), and a test checks the two agree.
DEFAULT_IMAGE_COUNTS = (1, 2, 4, 8, 12, 20)
#: the least-squares weightings a study can use (``boresight.estimate``'s)
WEIGHTINGS = ("unit", "diagonal", "gls")


# ---------------------------------------------------------------------------- seeding and chunks

def block_seed(seed: int, block: int) -> np.random.SeedSequence:
    """The seed sequence of run block ``block``: child ``block`` of ``SeedSequence(seed)``.

    >>> block_seed(1, 3).spawn_key == np.random.SeedSequence(1).spawn(4)[3].spawn_key
    True
    """
    return np.random.SeedSequence(seed, spawn_key=(int(block),))


def plan_chunks(runs: int, chunk_runs: int, block_runs: int = BLOCK_RUNS, start_block: int = 0) -> list:
    """Split runs ``start_block·block_runs``..runs−1 into chunks of ``chunk_runs``; each chunk is
    a list of block segments ``(block, start, stop)`` (run offsets inside the block).

    >>> plan_chunks(5, 3, block_runs=2)
    [[(0, 0, 2), (1, 0, 1)], [(1, 1, 2), (2, 0, 1)]]
    >>> plan_chunks(5, 3, block_runs=2, start_block=1)
    [[(1, 0, 2), (2, 0, 1)]]
    """
    for name, v in (("runs", runs), ("chunk_runs", chunk_runs), ("block_runs", block_runs)):
        if not (isinstance(v, (int, np.integer)) and v >= 1):
            raise ValueError(f"{name} must be an integer ≥ 1, got {v!r}")
    chunks = []
    for a in range(int(start_block) * block_runs, runs, chunk_runs):
        b = min(a + chunk_runs, runs)
        segs, k = [], a
        while k < b:
            blk = k // block_runs
            stop = min(b, (blk + 1) * block_runs)
            segs.append((blk, k - blk * block_runs, stop - blk * block_runs))
            k = stop
        chunks.append(segs)
    return chunks


#: a block's draws hold at most about this many landmark observations (see ``default_block_runs``)
BLOCK_OBSERVATIONS = 2_000_000


def default_block_runs(observations_per_run: int) -> int:
    """Runs per random-number block: ``BLOCK_RUNS``, fewer when a block's draws would hold more
    than ``BLOCK_OBSERVATIONS`` landmark observations.

    DECISION: a worker draws a whole block to use any part of it (the draws are sequential), so
    a block of a 120-image campaign (15 360 observations per run) at 1000 runs is ~0.5 GB of
    draws per worker; capped at 2·10⁶ observations (≤ 64 MB of pixel noise) it is 130 runs. The
    Kiev scenarios (≤ 80 observations per run) keep 1000, so their numbers are unchanged.

    >>> default_block_runs(4), default_block_runs(15360)
    (1000, 130)
    """
    return int(max(1, min(BLOCK_RUNS, BLOCK_OBSERVATIONS // max(1, int(observations_per_run)))))


def _block_size(runs, block, block_runs):
    return min(block_runs, runs - block * block_runs)


def draw_block(scenario, arrays, seed: int, block: int, runs: int, block_runs: int = BLOCK_RUNS) -> dict:
    """All random draws of block ``block`` (θ and sensor errors, ``orbits.draw_scenario_errors``)."""
    import orbits

    rng = np.random.default_rng(block_seed(seed, block))
    return orbits.draw_scenario_errors(scenario, rng, _block_size(runs, block, block_runs), arrays)



# ---------------------------------------------------------------------------- one chunk

#: error-dict entry and axis of each disturbance source (Kiev 2012 eq 28's s; boresight.core.error_sources)
SOURCE_ERRORS = {s.symbol: (s.errors_key, s.axis) for s in ERROR_SOURCES.values()}


def scale_errors(errors: dict, factors: dict) -> dict:
    """Drawn errors with source s multiplied by ``factors[s]`` (common random numbers).

    Sources: ``beta1..beta3`` (star-tracker axes), ``P`` (catalogue), ``R`` (GNSS), ``K`` (pixel).
    Scaling the drawn N(0, σ²) errors by f is drawing with σ f from the same normals.

    >>> e = {"delta_rad": np.ones((1, 1, 3)), "pixel_noise_m": np.ones((1, 1, 1, 2))}
    >>> scale_errors(e, {"beta2": 2.0, "K": 0.5})["delta_rad"].tolist(), float(scale_errors(e, {"K": 0.5})["pixel_noise_m"].max())
    ([[[1.0, 2.0, 1.0]]], 0.5)
    """
    out = dict(errors)
    for src, f in factors.items():
        if src not in SOURCE_ERRORS:
            raise ValueError(f"unknown disturbance source {src!r}; expected one of {list(SOURCE_ERRORS)}")
        key, axis = SOURCE_ERRORS[src]
        a = out[key].copy() if out[key] is errors[key] else out[key]
        if axis is None:
            a *= f
        else:
            a[..., axis] *= f
        out[key] = a
    return out


@dataclass(frozen=True)
class _Job:
    """Everything a worker needs for any chunk (pickled once per task; a few kB)."""

    scenario: object
    arrays: dict
    algorithms: tuple
    image_counts: tuple
    seed: int
    runs: int
    block_runs: int
    iterations: int
    kalman_iterations: int
    kalman_W: dict
    kalman_sigma0_rad: float
    variants: tuple = (("", ()),)
    max_iterations: int | None = None
    #: least-squares weighting; not "unit": every run through ``boresight.estimate`` with ``model``
    weighting: str = "unit"
    model: object = None


#: suffix of the per-run variance the estimator reports (arcsec², weighted studies only)
REPORTED_VARIANCE = "#var"


#: suffix of the per-run "did not converge" flags in ``estimate_errors``' output
UNCONVERGED = "#nc"


def _estimate_variant(job: _Job, errors: dict, variant: str) -> dict:
    import orbits

    from boresight.observations.model import from_measurements

    obs = from_measurements(orbits.observe(errors, **job.arrays))
    truth = errors["theta_rad"][:, None, :]
    out = {}
    weighted = job.weighting != "unit"
    s0 = None
    if job.algorithms:
        s0 = camera_vectors0(obs)
    F = obs.focal_length_m
    model = _scaled_model(job.model, dict(dict(job.variants)[variant])) if weighted and variant else job.model
    for name in job.algorithms:
        nc = np.zeros((obs.runs, len(job.image_counts)), bool)
        if weighted and name != "kalman_theta":
            err = np.empty((obs.runs, len(job.image_counts), 3))
            var = np.empty_like(err)
            for j, k in enumerate(job.image_counts):
                sub = obs if k == obs.n_images else obs.images(slice(0, k))
                # DECISION: each weighted fit starts from the run's unit-weight estimate (Algorithm 3's fast
                # kernel, iterated to 1e-4″), not from θ = 0: the same fixed point to the estimator's 1e-6″
                # tolerance, reached in 2 library steps instead of 3-4 (the GLS dominates the cost)
                start = image_plane_kernel(s0[:, :k], obs.xy_m[:, :k], obs.mask[:k], F, job.iterations, max_iterations=30)[0]
                start = np.where(np.isfinite(start).all(axis=-1, keepdims=True), start, 0.0)  # a failed start: θ = 0
                th, var[:, j], conv = weighted_kernel(sub, name, job.weighting, model, job.iterations, max_iterations=job.max_iterations,
                                                      theta0_arcsec=start / ARCSEC)
                err[:, j] = th - truth[:, 0] / ARCSEC
                nc[:, j] = ~conv
            out[name] = err
            out[name + REPORTED_VARIANCE] = var
            out[name + UNCONVERGED] = nc
            continue
        if name == "kalman_theta":
            xh, _ = kalman_theta_kernel(s0, obs.xy_m, obs.mask, F, job.kalman_W[variant], job.kalman_sigma0_rad, job.kalman_iterations)
            est = xh[:, [k - 1 for k in job.image_counts]]
        else:
            est = np.empty((obs.runs, len(job.image_counts), 3))
            for j, k in enumerate(job.image_counts):
                if name == "image_plane":
                    res = image_plane_kernel(s0[:, :k], obs.xy_m[:, :k], obs.mask[:k], F, job.iterations, max_iterations=job.max_iterations)
                else:
                    sub = obs if k == obs.n_images else obs.images(slice(0, k))
                    kernel = {"ground_plane": ground_plane_kernel, "unit_vector": unit_vector_kernel}[name]
                    res = kernel(sub, s0[:, :k], job.iterations, max_iterations=job.max_iterations)
                if job.max_iterations is None:
                    est[:, j] = res
                else:
                    est[:, j], conv = res
                    nc[:, j] = ~conv
        out[name] = (est - truth) / ARCSEC
        out[name + UNCONVERGED] = nc
    return out


def estimate_errors(job: _Job, errors: dict) -> dict:
    """θ̂ − θ (arcsec) for one batch of drawn errors: {key: (R, len(image_counts), ...)}.

    Keys: the algorithm name for the base case; with variants (sources scaled, common random
    numbers) also ``"alg@variant"`` and ``"alg@variant:dsq"`` = e_variant² − e_base² (whose mean
    is the variance difference, and whose spread gives its Monte Carlo standard error). Each
    estimate key ``k`` also has ``k + "#nc"`` (R, len(image_counts)) bool: the runs whose
    Gauss-Newton iteration did not converge (``kernels.step_converged``; always False for the
    Kalman filter, whose iterations per image are fixed).
    """
    out, base = {}, None
    for vname, factors in job.variants:
        res = _estimate_variant(job, scale_errors(errors, dict(factors)) if factors else errors, vname)
        if base is None:
            base = res
            out.update(res)
            continue
        for alg in job.algorithms:
            x = res[alg]
            out[f"{alg}@{vname}"] = x
            out[f"{alg}@{vname}:dsq"] = x * x - base[alg] * base[alg]
            out[f"{alg}@{vname}{UNCONVERGED}"] = res[alg + UNCONVERGED]
    return out


#: the last block drawn in this process: (key, draws) — consecutive chunks of one block reuse it
_LAST_BLOCK = [None, None]


def _cached_block(job: _Job, b: int) -> dict:
    """``draw_block`` of block ``b``, reusing this process's last draw when it is the same block
    of the same study. DECISION: a chunk smaller than a block used to redraw the whole block
    (a 13-run chunk of a 130-run block drew 10× its runs); the draws are identical either way,
    so the cache changes no number. One block per process: its memory is already counted
    (``_study_bytes``)."""
    import hashlib
    import pickle

    key = (hashlib.sha256(pickle.dumps((job.scenario, job.seed, job.runs, job.block_runs))).hexdigest(), b)
    if _LAST_BLOCK[0] != key:
        _LAST_BLOCK[0], _LAST_BLOCK[1] = None, None  # free the old draws before drawing
        _LAST_BLOCK[1] = draw_block(job.scenario, job.arrays, job.seed, b, job.runs, job.block_runs)
        _LAST_BLOCK[0] = key
    return _LAST_BLOCK[1]


def _run_chunk(job: _Job, segments) -> tuple:
    """Worker entry: draw each block segment of the chunk, estimate, return per-run errors."""
    parts = [_cached_block(job, b) for b, _, _ in segments]
    errors = {
        key: np.concatenate([p[key][a:z] for p, (_, a, z) in zip(parts, segments)]) for key in parts[0]
    }
    try:
        return segments, estimate_errors(job, errors)
    except ObservabilityError as exc:
        first = segments[0][0] * job.block_runs + segments[0][1]
        last = segments[-1][0] * job.block_runs + segments[-1][2] - 1
        raise StudyError(
            f"{job.weighting} weighting: θ is not determined in one of runs {first}..{last} (its draws make the normal "
            f"matrix singular; no NaN is written): {' '.join(str(exc).split())}"
        ) from None


# ---------------------------------------------------------------------------- engines

class _LocalEngine:
    def __init__(self, workers):
        self.workers = workers
        self.pool = None
        if workers > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            # DECISION: fork where available — workers inherit the imported numpy/scipy/astropy
            # (a spawned worker spends ~1 s importing them, a fifth of the eq-28 study budget).
            methods = multiprocessing.get_all_start_methods()
            ctx = multiprocessing.get_context("fork" if "fork" in methods else None)
            self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),))

    def submit(self, fn, *args):
        if self.pool is None:
            return _Done(fn(*args))
        return self.pool.submit(fn, *args)

    def close(self, abort: bool = False):
        """Shut the pool down; ``abort`` (an error or Ctrl-C in the driver) cancels queued
        chunks and terminates the workers instead of waiting for them."""
        if self.pool is None:
            return
        if abort:
            procs = list(getattr(self.pool, "_processes", {}).values())  # private, but the only handle
            self.pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(timeout=5)
        else:
            self.pool.shutdown(wait=True)


# DECISION: workers die with their parent, whatever kills it (``lifetime``: PR_SET_PDEATHSIG).
_worker_init = die_with_parent


class _Done:
    def __init__(self, value):
        self._value = value

    def result(self):
        return self._value


class _DaskEngine:
    def __init__(self, workers, scheduler=None, processes=True):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:  # pragma: no cover - depends on the environment
            raise ImportError(
                "the dask engine needs dask.distributed: pip install 'boresight[dask]' (or use --engine local)"
            ) from None
        self.cluster = None
        if scheduler:
            self.client = Client(scheduler)
        else:
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes, dashboard_address=None)
            self.client = Client(self.cluster)
            from boresight.studies.montecarlo.dask_plugin import DieWithParent

            self.client.register_plugin(DieWithParent(os.getpid()))  # our cluster's workers die with the study
        self.workers = workers

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def close(self, abort: bool = False):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_engine(engine: str = "local", workers: int | None = None, scheduler: str | None = None, processes: bool = True):
    """A reusable engine (``close()`` it), to share one worker pool among several ``run`` calls."""
    workers = default_workers() if workers is None else workers
    if not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise ValueError(f"workers must be an integer ≥ 1, got {workers!r}")
    if engine == "local":
        return _LocalEngine(int(workers))
    if engine == "dask":
        return _DaskEngine(int(workers), scheduler, processes)
    raise ValueError(f"engine must be 'local' or 'dask', got {engine!r}")


def default_workers() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


# ---------------------------------------------------------------------------- the study

@dataclass
class MonteCarloResult:
    """Streamed statistics of θ̂ − θ (arcsec) per algorithm; shapes (len(image_counts), 3).

    ``moments[algorithm]``: a ``Moments`` over the runs; ``samples[algorithm]``: the errors of
    the first ``keep_runs`` runs (for histograms), (K, len(image_counts), 3).
    """

    scenario_name: str
    algorithms: tuple
    image_counts: tuple
    runs: int
    seed: int
    block_runs: int
    chunk_runs: int
    moments: dict
    samples: dict
    inputs: dict = field(default_factory=dict)
    elapsed_s: float = 0.0
    beta: float = 0.9973
    #: per algorithm, (len(image_counts),) number of runs whose Gauss-Newton did not converge
    unconverged: dict = field(default_factory=dict)
    #: what the study changed or skipped and why (printed by the command)
    notes: tuple = ()
    #: blocks loaded from a checkpoint (``resume``), 0 for a fresh study
    resumed_blocks: int = 0
    #: the least-squares weighting (``"unit"``, ``"diagonal"``, ``"gls"``; kalman_theta always uses the noise model)
    weighting: str = "unit"
    #: per least-squares algorithm, (len(image_counts), 3) arcsec: the σ the estimator itself
    #: predicts — √(mean over runs of its reported variance) under diagonal/GLS weighting
    predicted: dict = field(default_factory=dict)

    @property
    def any_unconverged(self) -> bool:
        return any(int(np.sum(v)) > 0 for v in self.unconverged.values())

    def sigma_arcsec(self, algorithm: str) -> np.ndarray:
        return self.moments[algorithm].std

    def reported_sigma_arcsec(self, algorithm: str):
        """√(mean over runs of the variance the estimator reported), (len(image_counts), 3) arcsec, or
        None (unit weighting and kalman_theta report none). What the analyst quotes from one run; the
        sample σ of ``sigma_arcsec`` is what it should be."""
        mo = self.moments.get(algorithm + REPORTED_VARIANCE)
        return None if mo is None else np.sqrt(mo.mean)

    def table(self, beta: float | None = None):
        """One row per (algorithm, number of images): mean, σ with its χ² interval, the largest abs(θ error)."""
        from astropy import units as u
        from astropy.table import Table

        beta = self.beta if beta is None else beta
        weighted = self.weighting != "unit"
        rows = []
        for name in self.algorithms:
            mo = self.moments[name]
            sd = mo.std
            lo, hi = sigma_interval(sd, mo.count, beta)
            nc = self.unconverged.get(name, np.zeros(len(self.image_counts), int))
            rep = self.reported_sigma_arcsec(name) if weighted else None
            for j, k in enumerate(self.image_counts):
                more = () if not weighted else tuple(rep[j]) if rep is not None else (np.nan,) * 3
                rows.append((name, k, mo.count, *mo.mean[j], *sd[j], *lo[j], *hi[j], *mo.max_abs[j], float(np.sqrt((sd[j] ** 2).sum())), int(nc[j]))
                            + more)
        names = ["algorithm", "n_images", "runs"]
        for stem in ("mean_theta", "sigma_theta", "sigma_theta_lo", "sigma_theta_hi", "max_abs_theta"):
            names += [f"{stem}_{ax}" for ax in "xyz"]
        names += ["sigma_theta_total", "unconverged_runs"]
        # DECISION: a unit-weighted study's table keeps its former columns and metadata byte for byte
        # (tests/project/test_public_outputs.py); a weighted one adds the estimator's reported σ and says so
        if weighted:
            names += [f"sigma_reported_{ax}" for ax in "xyz"]
        t = Table(rows=rows, names=names)
        for c in names[3:]:
            if c != "unconverged_runs":
                t[c].unit = u.arcsec
        t.meta.update(
            scenario=self.scenario_name,
            runs=int(self.runs),
            seed=int(self.seed),
            block_runs=int(self.block_runs),
            beta=float(beta),
            epsilon_achieved=achieved_epsilon(self.runs, beta) if self.runs >= 2 else None,
            note="θ̂ − θ in arcsec; sigma_theta_lo/hi: χ² confidence interval at beta; unconverged_runs: runs whose "
            "Gauss-Newton iteration did not converge (included in the statistics)",
        )
        if weighted:
            t.meta["weighting"] = self.weighting
            t.meta["note"] += (
                f"; {self.weighting} weighting: every run estimated as boresight.estimate(obs, weighting="
                f"{self.weighting!r}, model=the scenario's noise model); sigma_reported: the σ the estimator reports, "
                "√(mean over runs of its variance) — sigma_theta is what it should be (kalman_theta: none, nan)"
            )
        return t


def _resolve_scenario(scenario):
    import orbits

    if isinstance(scenario, orbits.Scenario):
        return scenario
    return orbits.load_scenario(scenario)


def _montecarlo_name(a: str) -> str:
    """The Monte Carlo name of ``a`` (a name or alias in boresight.core.registry)."""
    valid = list(ALGORITHMS) + ["all", "least_squares"]
    try:
        row = registry.lookup(a)
    except registry.UnknownAlgorithmError:
        raise registry.UnknownAlgorithmError(f"algorithm must be one of {valid}, got {a!r}") from None
    if row.montecarlo_kernel is None:
        raise registry.UnknownAlgorithmError(f"algorithm {a!r} ({row.summary}) has no Monte Carlo kernel; expected one of {valid}")
    return row.name


def resolve_algorithms(algorithms):
    if isinstance(algorithms, str):
        algorithms = [algorithms]
    out = []
    for a in algorithms:
        if a == "all":
            out += [x for x in ALGORITHMS if x not in out]
        elif a == "least_squares":
            out += [x for x in LEAST_SQUARES if x not in out]
        else:
            name = _montecarlo_name(a)
            if name not in out:
                out.append(name)
    if not out:
        raise ValueError("algorithms is empty")
    return tuple(out)


def default_chunk_runs(observations_per_run: int, algorithms=ALGORITHMS) -> int:
    """Runs per chunk: ~200 000 landmark observations (400 000 when only the structure-of-arrays
    kernels, ``image_plane`` and ``kalman_theta``, run), at most 5000 runs.

    DECISION: a chunk's working set is a few hundred bytes per landmark observation (the
    simulation's arrays; the kernels work on structure-of-arrays copies), so 200 000
    observations keep a worker below ~150 MB whatever the scenario (PSS of 2 workers + driver:
    ~140 MB for the one-image case, ~390 MB for all algorithms on 20 images), while a chunk stays
    large enough to amortise numpy's per-call overhead (the Kalman kernel makes ~6000 calls per
    chunk for 20 images: 1250-run chunks run at 14 000 runs/s, 5000-run chunks at 23 000).

    >>> default_chunk_runs(4), default_chunk_runs(80), default_chunk_runs(80, ("kalman_theta",))
    (5000, 2500, 5000)
    """
    budget = 400_000 if set(algorithms) <= {"image_plane", "kalman_theta"} else 200_000
    return int(max(1, min(5000, budget // max(1, observations_per_run))))


def default_image_counts(n_images: int) -> tuple:
    """``DEFAULT_IMAGE_COUNTS`` (those ≤ n_images) plus n_images itself.

    >>> default_image_counts(1), default_image_counts(10)
    ((1,), (1, 2, 4, 8, 10))
    """
    return tuple(sorted({k for k in DEFAULT_IMAGE_COUNTS if k <= n_images} | {n_images}))


def run(
    scenario,
    algorithms=("image_plane",),
    runs: int = 45000,
    seed: int = 1,
    *,
    chunk_runs: int | None = None,
    block_runs: int | None = None,
    workers: int | None = None,
    engine="local",
    scheduler: str | None = None,
    image_counts=None,
    iterations: int = 2,
    max_iterations: int | None = 30,
    kalman_iterations: int | None = None,
    keep_runs: int = 100_000,
    progress=None,
    beta: float = 0.9973,
    variants=None,
    checkpoint=None,
    resume: bool = False,
    weighting: str = "unit",
    preflight=None,
) -> MonteCarloResult:
    """Monte Carlo of θ̂ − θ for ``algorithms`` over ``runs`` runs of ``scenario``.

    ``scenario``: an ``orbits.Scenario`` or TOML path. ``algorithms``: names from
    ``ALGORITHMS``, or ``"all"``. ``chunk_runs``: runs per task (memory ∝ chunk_runs × workers;
    default ``default_chunk_runs``).
    ``engine``: ``"local"`` (processes; ``workers=1`` runs in this process), ``"dask"`` (a
    ``LocalCluster`` of ``workers``, or the cluster at ``scheduler``), or an engine from
    ``make_engine`` (kept open). ``image_counts``: numbers of images (first k of the
    scenario's) to estimate with; default ``default_image_counts`` minus the counts whose
    geometry does not determine θ (named in ``result.notes``); a given count that does not
    raises ``ObservabilityError``. ``iterations``: Gauss-Newton steps every run takes from θ0 = 0
    for the least-squares algorithms; ``max_iterations``: then iterate each run until
    ``kernels.step_converged`` (1e-4″) up to this many steps and count the runs that did not
    (``result.unconverged``; ``None`` = exactly ``iterations`` steps, the old behaviour).
    ``kalman_iterations``: IEKF steps per image (default ``kalman_iterations_for(prior σ)``,
    3 for the seminar's priors). ``progress(done_runs, runs)`` is called
    as chunks finish. ``variants``: {name: {source: factor}} extra cases computed on the same
    draws (common random numbers, ``scale_errors``), for ``boresight.studies.sensitivity``.
    ``checkpoint``: a folder for block checkpoints, or a ``checkpoint.Checkpoint`` (``resume``
    continues the interrupted study there). The result is identical for any ``chunk_runs``,
    ``workers``, engine, and for an interrupted-and-resumed study.
    ``weighting``: ``"unit"`` (default: the batched unit-weight kernels, eqs 18/22/31), or
    ``"diagonal"``/``"gls"``: each least-squares run estimated exactly as
    ``boresight.estimate(obs, algorithm, weighting=weighting, model=DisturbanceModel.from_scenario(sc))``
    (batched per chunk, ``kernels.weighted_kernel``), and the σ it reports kept
    (``result.reported_sigma_arcsec``). ``kalman_theta`` weights by the noise model under every choice.
    ``preflight(dict)``: called once the sizes are checked and before any run, with the study's
    ``runs``, ``cases``, ``workers``, ``memory_bytes``, estimated ``seconds`` and checkpoint
    ``disk_bytes`` (``format_preflight`` makes the line the commands print).

    Refused up front (``BoresightError``): a geometry that does not determine θ
    (``ObservabilityError``), a size over the memory budget (``MemoryBudgetError``), a Kalman
    study whose per-image noise covariance is singular (``StudyError``; with ``"all"`` the
    Kalman filter is skipped with a note instead). A non-finite estimate raises ``StudyError``
    naming the run, never a NaN in the result.
    """
    t0 = time.perf_counter()
    sc = _resolve_scenario(scenario)
    algs = resolve_algorithms(algorithms)
    model = _study_model(sc, weighting)
    explicit_kalman = bool({"kalman", "kalman_theta"} & set([algorithms] if isinstance(algorithms, str) else list(algorithms)))
    _check_counts(runs=runs, iterations=iterations, keep_runs=keep_runs, max_iterations=max_iterations)
    variants = _check_variants(variants)
    if sc.theta_true_arcsec is None and sc.theta_sigma0_arcsec <= 0 and "kalman_theta" in algs:
        raise StudyError(f"{sc.source}: the Kalman filter needs a prior: [misalignment] sigma0_arcsec must be > 0")
    import orbits

    arrays = orbits.campaign_arrays(sc)
    n_img = arrays["t_s"].size
    obs_per_run = n_img * arrays["landmarks_g_m"].shape[0]
    notes = []
    counts = default_image_counts(n_img) if image_counts is None else tuple(int(k) for k in image_counts)
    if not counts or min(counts) < 1 or max(counts) > n_img:
        raise StudyError(f"image_counts must lie in 1..{n_img} (the scenario's images), got {image_counts!r}")
    if block_runs is None:
        block_runs = default_block_runs(obs_per_run)
    if not (isinstance(block_runs, (int, np.integer)) and block_runs >= 1):
        raise StudyError(f"block_runs must be an integer ≥ 1, got {block_runs!r}")
    nom = nominal_observations(sc, arrays)
    counts = _observable_counts(sc, nom, algs, counts, explicit=image_counts is not None, notes=notes, weighting=weighting, model=model)
    algs, W, sigma0 = _kalman_setup(sc, nom, algs, variants, explicit_kalman, notes)
    if kalman_iterations is None:
        kalman_iterations = kalman_iterations_for(sigma0)
    _check_counts(kalman_iterations=kalman_iterations)
    per_run, per_run_s = _weighted_bytes_per_run(nom, algs, counts, weighting, model) if weighting != "unit" else (0.0, 0.0)
    if chunk_runs is None:
        chunk_runs = default_chunk_runs(obs_per_run, algs)
        if per_run:
            chunk_runs = int(max(1, min(chunk_runs, WEIGHTED_CHUNK_BYTES // per_run)))
    if not (isinstance(chunk_runs, (int, np.integer)) and chunk_runs >= 1):
        raise StudyError(f"chunk_runs must be an integer ≥ 1, got {chunk_runs!r}")
    n_workers = workers or getattr(engine, "workers", None) or default_workers()
    mem = _check_study_memory(runs, int(chunk_runs), int(block_runs), obs_per_run, len(counts), len(algs), len(variants), keep_runs,
                              n_workers, weighted_bytes_per_run=per_run)
    used = min(n_workers, -(-runs // int(chunk_runs)))
    seconds = estimate_seconds(nom, algs, counts, len(variants), int(runs), 1, kalman_iterations, per_run_s)
    if workers is None and engine == "local" and seconds < POOL_THRESHOLD_S:
        used = 1
    if preflight is not None:
        preflight({
            "runs": int(runs), "cases": len(variants), "workers": int(used), "memory_bytes": mem,
            "seconds": SECONDS_FIXED + (seconds - SECONDS_FIXED) / used,
            "disk_bytes": checkpoint_bytes(int(runs), int(block_runs), len(counts), len(algs), len(variants), keep_runs, weighting != "unit")
            if checkpoint is not None else 0.0,
        })
    job = _Job(sc, arrays, algs, counts, int(seed), int(runs), int(block_runs), int(iterations), int(kalman_iterations), W, sigma0, variants,
               None if max_iterations is None else int(max_iterations), weighting, model)

    acc = _Accumulator(algs, int(runs), int(block_runs), int(keep_runs))
    ckpt = None
    if checkpoint is not None:
        from boresight.studies.montecarlo.checkpoint import Checkpoint

        ckpt = checkpoint if isinstance(checkpoint, Checkpoint) else Checkpoint(checkpoint)
        done = ckpt.open(_identity(job, keep_runs), resume)
        for b in range(min(done, acc.n_blocks)):
            acc.merge_block(b, *ckpt.load(b))
        acc.checkpoint = ckpt
    chunks = plan_chunks(int(runs), int(chunk_runs), int(block_runs), start_block=acc.next_block)
    if progress is not None and acc.done_runs:
        progress(acc.done_runs, runs)
    resumed = acc.next_block
    if chunks:
        own = not hasattr(engine, "submit")
        if workers is None and engine == "local" and seconds < POOL_THRESHOLD_S:
            workers = 1  # DECISION: no process pool for sub-second work (see POOL_THRESHOLD_S); the numbers do not depend on it
        eng = make_engine(engine, workers if workers is not None else min(default_workers(), len(chunks)), scheduler) if own else engine
        ok = False
        try:
            _drive(eng, job, chunks, acc, progress)
            ok = True
        finally:
            _LAST_BLOCK[:] = [None, None]  # an in-process study's cached draws are not kept after it
            if own:
                eng.close(abort=not ok)
    inputs = {
        "scenario_source": sc.source,
        "seed": int(seed),
        "runs": int(runs),
        "chunk_runs": int(chunk_runs),
        "block_runs": int(block_runs),
        "algorithms": list(algs),
        "image_counts": list(counts),
        "iterations": int(iterations),
        "max_iterations": None if max_iterations is None else int(max_iterations),
        "kalman_iterations": int(kalman_iterations),
        "engine": engine if isinstance(engine, str) else type(engine).__name__,
        "variants": {k: dict(v) for k, v in variants[1:]},
        "notes": list(notes),
    }
    if weighting != "unit":  # absent = unit, so a unit study's JSON is unchanged (tests/project/test_public_outputs.py)
        inputs["weighting"] = weighting
    return MonteCarloResult(
        scenario_name=sc.name,
        algorithms=algs,
        image_counts=counts,
        runs=int(runs),
        seed=int(seed),
        block_runs=int(block_runs),
        chunk_runs=int(chunk_runs),
        moments=acc.totals,
        samples={a: np.concatenate(v) for a, v in acc.samples.items()},
        inputs=inputs,
        elapsed_s=time.perf_counter() - t0,
        beta=beta,
        unconverged={a: acc.unconverged.get(a, np.zeros(len(counts), int)) for a in algs},
        notes=tuple(notes),
        resumed_blocks=resumed,
        weighting=weighting,
        predicted=_unit_predictions(nom, algs, counts, model if model is not None else _study_model(sc, "diagonal", quiet=True))
        if weighting == "unit" else {},
    )


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


def _check_counts(**values):
    for name, v in values.items():
        if name == "max_iterations" and v is None:
            continue
        lo = 0 if name == "keep_runs" else (2 if name == "runs" else 1)
        if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= lo):
            raise StudyError(f"{name} must be an integer ≥ {lo}, got {v!r}")


def _check_variants(variants) -> tuple:
    out = (("", ()),) + tuple((str(k), tuple(sorted(dict(v).items()))) for k, v in (variants or {}).items())
    for vname, factors in out[1:]:
        if not vname or "@" in vname or ":" in vname or "#" in vname:
            raise StudyError(f"variant names must be non-empty without '@', ':' or '#', got {vname!r}")
        for src, f in factors:
            if src not in SOURCE_ERRORS:
                raise StudyError(f"variants[{vname!r}]: unknown disturbance source {src!r}; expected one of {list(SOURCE_ERRORS)}")
            # DECISION: factors up to 10⁶: beyond, σ·f overflows the squares of the estimators
            if isinstance(f, bool) or not (np.isfinite(f) and 0 <= f <= 1e6):
                raise StudyError(f"variants[{vname!r}][{src!r}] must be a finite factor in [0, 1e6], got {f!r}")
    return out


def _observable_counts(sc, nom, algs, counts, *, explicit: bool, notes: list, weighting: str = "unit", model=None) -> tuple:
    """The image counts whose nominal (noise-free) geometry determines θ for every
    least-squares algorithm of the study — the same ``ObservabilityError`` check as
    ``boresight.estimate``. A Kalman-only study checks its largest count (with fewer images the
    filter legitimately returns its prior)."""
    from boresight import estimate

    ls = [a for a in algs if a != "kalman_theta"]
    check = list(counts) if ls else [max(counts)]
    keep, first_error = [], None
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
                    weak_axis=exc.weak_axis, condition_number=exc.condition_number,
                ) from None
            first_error = first_error or (msg, exc)
            notes.append(f"{k} image(s) skipped: θ is not observable from them ({a}: {' '.join(str(exc).split())})")
            continue
        keep.append(k)
    if not keep:
        msg, exc = first_error
        raise ObservabilityError(msg, weak_axis=exc.weak_axis, condition_number=exc.condition_number)
    return tuple(keep)


def _kalman_setup(sc, nom, algs, variants, explicit: bool, notes: list):
    """R_n⁻¹ per image and variant and the prior σ for the Kalman kernel; drops "kalman" (with a
    note) when the noise model gives a singular R_n and the filter was not asked for by name."""
    if "kalman_theta" not in algs:
        return algs, {}, 0.0
    from boresight.core.disturbances import DisturbanceModel
    from boresight.core.error_structure import image_covariance

    # DECISION: R_n from the nominal geometry, once, for all runs. The module's filter
    # re-evaluates it about each run's estimate; R_n moves by O(|θ|): the estimates agree
    # to 1e-4 of σθ with a 10″ prior and ~1 % of σθ with a 10′ prior
    # (tests/studies/test_montecarlo.py), and it turns 45 000 × 20-image runs from minutes into seconds.
    base_model = DisturbanceModel.from_scenario(sc)
    W = {}
    for vname, factors in variants:
        model = _scaled_model(base_model, dict(factors))
        Rn = image_covariance(nom, np.zeros(3), model)[0]
        # R_n = σK² E + (PSD terms): positive definite whenever σK > 0; only without pixel noise
        # can it be singular, and only then are its eigenvalues worth their cost (a 6-pass
        # campaign's 120 images × 2M × 2M would take seconds)
        singular = not np.all(np.isfinite(Rn))
        if not singular and not model.sigma_pixel_m > 0:
            ev = np.linalg.eigvalsh(Rn)
            singular = not np.all(ev[:, 0] > 1e-12 * np.maximum(ev[:, -1], 1e-300))
        if singular:
            msg = (
                f"{sc.source}: the Kalman filter needs an invertible per-image noise covariance R_n, and this scenario's "
                f"noise model{' (variant ' + vname + ')' if vname else ''} gives a singular one "
                f"(pixel σ = {sc.sigma_pixel_m:g} m): set [pixel] sigma_m > 0"
            )
            if explicit:
                raise StudyError(msg)
            notes.append("kalman_theta skipped: " + msg.split(": ", 1)[1])
            return tuple(a for a in algs if a != "kalman_theta"), {}, 0.0
        W[vname] = np.linalg.inv(Rn)
    sigma0 = (sc.theta_sigma0_arcsec if sc.theta_true_arcsec is None else max(np.abs(sc.theta_true_arcsec).max(), 1.0)) * ARCSEC
    return algs, W, sigma0


def _study_model(sc, weighting: str, quiet: bool = False):
    """The scenario's noise model for a ``weighting`` study (None for ``"unit"``, which needs none);
    ``quiet``: None instead of an error when the model cannot weight (no pixel noise)."""
    from boresight.core.disturbances import DisturbanceModel

    if weighting not in WEIGHTINGS:
        raise StudyError(f"weighting must be one of {list(WEIGHTINGS)}, got {weighting!r}")
    if weighting == "unit" and not quiet:
        return None
    model = DisturbanceModel.from_scenario(sc)
    if not model.sigma_pixel_m > 0:
        if quiet:
            return None
        raise StudyError(
            f"{sc.source}: --weighting {weighting} weights each residual by the scenario's noise model, which needs pixel noise "
            f"([pixel] sigma_m > 0, got {sc.sigma_pixel_m:g} m); use --weighting unit"
        )
    return model


#: a weighted study's chunk holds at most this much of the library estimator's working set per worker
WEIGHTED_CHUNK_BYTES = 256 * 2**20


def _weighted_bytes_per_run(nom, algs, counts, weighting, model) -> float:
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


def _unit_predictions(nom, algs, counts, model) -> dict:
    """Per least-squares algorithm, (len(counts), 3) arcsec: the σ of a unit-weighted estimate by
    linear propagation at the noise-free nominal geometry — the estimator's own sandwich covariance
    A (Gᵀ Σ G) A under the scenario's noise model (``boresight.estimate``). Empty without pixel noise."""
    from boresight import estimate

    if model is None:
        return {}
    out = {}
    for a in algs:
        if a == "kalman_theta":
            continue
        rows = []
        for k in counts:
            sub = nom if k == nom.n_images else nom.images(slice(0, k))
            rows.append(estimate(sub, a, weighting="unit", model=model, iterate=1).sigma.to_value("arcsec"))
        out[a] = np.array(rows)
    return out


#: bookkeeping bytes per planned chunk (a list of block segments)
_BYTES_PER_CHUNK = 200
#: bytes per drawn error component in a block (θ, δ, GNSS, catalogue, pixel noise: float64)
_BYTES_PER_DRAW = 8


def _study_bytes(runs, chunk_runs, block_runs, obs_per_run, n_counts, n_algs, n_variants, keep_runs, workers,
                 weighted_bytes_per_run: float = 0.0) -> float:
    """The study's working set (bytes): each worker holds its chunk's simulation and estimator
    arrays and the blocks it draws (and, under diagonal/GLS weighting, the library estimator's
    working set: ``weighted_bytes_per_run``); the driver holds the chunk plan and the kept samples."""
    # DECISION: the cases (base and scaled variants) are estimated one after the other on the same
    # draws, so the working set is one case's plus every case's per-run errors — not n_variants
    # times it (traced peak of a 13-run campaign-6pass chunk: 25 MB with 1 case, 28 MB with 7;
    # 130-270 bytes per observation per run, under BYTES_PER_OBSERVATION)
    n_chunks = -(-runs // chunk_runs)
    per_worker = (
        min(chunk_runs, runs) * (obs_per_run * BYTES_PER_OBSERVATION + weighted_bytes_per_run + n_variants * n_counts * n_algs * 3 * 8 * 4)
        + min(block_runs, runs) * obs_per_run * 2 * _BYTES_PER_DRAW * 2
    )
    driver = n_chunks * _BYTES_PER_CHUNK + min(runs, keep_runs) * n_counts * 3 * 8 * n_algs * 2
    return float(workers) * per_worker + driver


def _check_study_memory(runs, chunk_runs, block_runs, obs_per_run, n_counts, n_algs, n_variants, keep_runs, workers,
                        weighted_bytes_per_run: float = 0.0) -> float:
    """Refuse a study whose working set (``_study_bytes``) exceeds the memory budget
    (``orbits.limits``); returns the estimate."""
    nbytes = _study_bytes(runs, chunk_runs, block_runs, obs_per_run, n_counts, n_algs, n_variants, keep_runs, workers,
                          weighted_bytes_per_run)
    check_memory(
        f"the study (--runs {runs}, {obs_per_run} observations per run, chunks of {min(chunk_runs, runs)} runs, "
        f"blocks of {min(block_runs, runs)}, {workers} worker(s))",
        nbytes,
        hint="fewer runs, smaller --chunk-runs/--block-runs or fewer --workers",
    )
    return nbytes


# ---------------------------------------------------------------------------- pre-flight

#: CPU seconds per run and case (base or scaled variant) of the unit-weight study, by size.
#: DECISION: a model of the problem's sizes, not a pilot run (a few runs time numpy's call
#: overhead, not the work): the simulation per landmark slot of the dense (image × landmark)
#: layout; each kernel per valid observation of each image count (ground_plane/unit_vector also
#: copy each count's images: per slot); the Kalman filter per element of each image's 2M × 2M
#: weight per IEKF step. Fitted on kiev2012-kalman20 and campaign-6pass (one worker, numpy 2,
#: 2 shared cores); within a factor 2 there, ~3× for the one-image eq-28 case (fixed costs).
SECONDS_PER_SLOT = 0.45e-6
SECONDS_PER_OBSERVATION = {"image_plane": 0.35e-6, "unit_vector": 0.22e-6, "ground_plane": 1.0e-6}
SECONDS_PER_COUNT_SLOT = 0.19e-6
SECONDS_PER_KALMAN_ELEMENT = 30e-9
#: fixed seconds of a study (nominal geometry, observability checks, predictions)
SECONDS_FIXED = 0.5
#: a study estimated (one worker, ``estimate_seconds``) below this many seconds runs in-process when
#: ``workers`` is not given: starting the default two-worker pool costs 0.6-1.3 s CPU (issue 19),
#: more than such a study's own work
POOL_THRESHOLD_S = 1.0


def estimate_seconds(nom, algs, counts, n_variants: int, runs: int, workers: int, kalman_iterations: int = 3,
                     weighted_seconds_per_run: float = 0.0) -> float:
    """Wall seconds the study will take, from its sizes (``SECONDS_PER_*``): runs × cases ×
    (simulation + each algorithm's kernels), shared among ``workers``; plus ``SECONDS_FIXED``.
    ``weighted_seconds_per_run``: measured cost of one library estimate per run (diagonal/GLS)."""
    slots = nom.n_images * nom.n_landmarks
    per_count = [(int(nom.mask[:k].sum()), k * nom.n_landmarks) for k in counts]
    t = SECONDS_PER_SLOT * slots
    for a in algs:
        if a == "kalman_theta":
            t += SECONDS_PER_KALMAN_ELEMENT * kalman_iterations * float(((2 * nom.mask.sum(axis=1)) ** 2).sum())
        elif weighted_seconds_per_run:
            t += weighted_seconds_per_run
        else:
            t += sum(SECONDS_PER_OBSERVATION.get(a, 1e-6) * v + (SECONDS_PER_COUNT_SLOT * sl if a != "image_plane" else 0.0)
                     for v, sl in per_count)
    return SECONDS_FIXED + runs * n_variants * t / max(1, workers)


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
    return (f"pre-flight: {pf['runs']} runs{cases}, {pf['workers']} worker(s); estimated memory {size(pf['memory_bytes'])} "
            f"(budget {size(memory_budget_bytes())}; plus up to {size(procs * LIBRARY_BYTES_PER_PROCESS)} of loaded libraries), "
            f"time ~{dur(pf['seconds'])}, disk for checkpoints {size(pf['disk_bytes'])}")


def _identity(job: _Job, keep_runs: int) -> dict:
    """Everything a study's numbers depend on (the checkpoint's identity): not the chunking,
    the workers or the engine, which do not change them."""
    from dataclasses import asdict

    scen = asdict(job.scenario)
    scen.pop("source", None)
    return {
        "scenario": json.loads(json.dumps(scen, default=str)),
        "seed": job.seed,
        "runs": job.runs,
        "block_runs": job.block_runs,
        "algorithms": list(job.algorithms),
        "image_counts": list(job.image_counts),
        "iterations": job.iterations,
        "max_iterations": job.max_iterations,
        "kalman_iterations": job.kalman_iterations,
        "variants": [[k, [list(f) for f in v]] for k, v in job.variants],
        "keep_runs": int(keep_runs),
        "weighting": job.weighting,
    }


class _Accumulator:
    """Collects chunk results, completes blocks, merges them into the totals in block order
    (and checkpoints each block before merging it, when a ``Checkpoint`` is attached)."""

    def __init__(self, algs, runs, block_runs, keep_runs):
        self.algs, self.runs, self.block_runs, self.keep_runs = algs, runs, block_runs, keep_runs
        self.n_blocks = -(-runs // block_runs)
        self.totals, self.unconverged = {}, {}
        self.samples = {a: [] for a in algs}
        self.kept = 0
        self.next_block = 0
        self.done_runs = 0
        self.pending = {}  # block -> list of (start, {key: rows})
        self.checkpoint = None

    def add(self, segments, errs) -> int:
        off = 0
        for b, a, z in segments:
            self.pending.setdefault(b, []).append((a, {k: v[off : off + z - a] for k, v in errs.items()}))
            off += z - a
        while self.next_block < self.n_blocks:
            parts = self.pending.get(self.next_block, [])
            size = _block_size(self.runs, self.next_block, self.block_runs)
            if sum(len(p[1][self.algs[0]]) for p in parts) < size:
                break
            parts.sort(key=lambda p: p[0])
            block = {name: np.concatenate([p[1][name] for p in parts]) for name in parts[0][1]}
            del self.pending[self.next_block]
            self._complete(self.next_block, block)
        return off

    def _complete(self, b, block):
        moments, unconverged, samples = {}, {}, {}
        for name, x in block.items():
            if name.endswith(UNCONVERGED):
                unconverged[name[: -len(UNCONVERGED)]] = x.sum(axis=0).astype(np.int64)
                continue
            if not np.all(np.isfinite(x)):
                row = int(np.argwhere(~np.isfinite(x))[0][0])
                raise StudyError(
                    f"{name}: a non-finite θ̂ in run {b * self.block_runs + row} (block {b}); its geometry or draws make the "
                    "estimate singular — no NaN is written. Check the scenario's noise levels and landmarks"
                )
            moments[name] = Moments.from_samples(x)
            if name in self.samples and self.kept < self.keep_runs:
                samples[name] = x[: self.keep_runs - self.kept]
        if self.checkpoint is not None:
            self.checkpoint.save(b, moments, unconverged, samples)
        self.merge_block(b, moments, unconverged, samples)

    def merge_block(self, b, moments, unconverged, samples):
        if b != self.next_block:
            raise StudyError(f"internal: block {b} merged out of order (expected {self.next_block})")
        for name, mo in moments.items():
            self.totals[name] = mo if name not in self.totals else self.totals[name].merge(mo)
        for name, n in unconverged.items():
            self.unconverged[name] = n if name not in self.unconverged else self.unconverged[name] + n
        size = _block_size(self.runs, b, self.block_runs)
        if self.kept < self.keep_runs:
            for name, x in samples.items():
                self.samples[name].append(x)
            self.kept += min(size, self.keep_runs - self.kept)
        self.next_block += 1
        self.done_runs += size


def _drive(eng, job, chunks, acc, progress):
    """Submit the chunks with a bounded window of tasks in flight; feed results, in
    completion-of-submission order, to the accumulator."""
    window = 2 * max(1, getattr(eng, "workers", 1))
    done = acc.done_runs
    futures = []
    it = iter(chunks)
    for c in it:
        futures.append(eng.submit(_run_chunk, job, c))
        if len(futures) >= window:
            break
    while futures:
        segments, errs = futures.pop(0).result()
        nxt = next(it, None)
        if nxt is not None:
            futures.append(eng.submit(_run_chunk, job, nxt))
        done += acc.add(segments, errs)
        if progress is not None:
            progress(done, job.runs)


# ---------------------------------------------------------------------------- progress

class ProgressBar:
    """A plain-text progress bar with ETA on stderr: ``progress(done, total)``.

    >>> import io
    >>> buf = io.StringIO()
    >>> bar = ProgressBar(stream=buf, width=10)
    >>> bar(50, 100); bar(100, 100)
    >>> buf.getvalue().splitlines()[-1].startswith("[##########] 100%")
    True
    """

    def __init__(self, stream=None, width: int = 30, label: str = ""):
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.label = label
        self.t0 = time.perf_counter()

    def preflight(self, pf: dict):
        """Print the study's pre-flight line (``format_preflight``; ``run(preflight=…)``) before the bar."""
        self.stream.write(format_preflight(pf) + "\n")
        self.stream.flush()
        self.t0 = time.perf_counter()

    def __call__(self, done, total):
        el = time.perf_counter() - self.t0
        frac = done / total if total else 1.0
        eta = el * (1 - frac) / frac if frac > 0 else float("nan")
        n = int(round(self.width * frac))
        head = f"[{'#' * n}{'.' * (self.width - n)}] {100 * frac:3.0f}% {done}/{total} runs "
        tail = f" elapsed {el:.1f} s ETA {eta:.1f} s"
        room = max(0, 100 - len(head) - len(tail))  # the line stays ≤ 100 columns: a long label is shortened
        label = self.label if len(self.label) <= room else self.label[: max(0, room - 1)] + "…"
        msg = head + label + tail
        end = "\n" if done >= total else ""
        self.stream.write("\r" + msg + end)
        self.stream.flush()

