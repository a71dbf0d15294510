"""The Monte Carlo engine: seeding by blocks, chunks, local and dask engines, the study ``run``."""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from boresight import registry
from boresight.error_sources import ERROR_SOURCES
from orbits.rotations import ARCSEC

from .kernels import (
    _scaled_model,
    camera_vectors0,
    ground_plane_kernel,
    image_plane_kernel,
    kalman_theta_kernel,
    nominal_observations,
    unit_vector_kernel,
)
from .moments import Moments
from .sample_size import achieved_epsilon, sigma_interval

#: every algorithm the engine runs (those with a kernel in boresight.registry); "all" in the CLI means these
ALGORITHMS = registry.montecarlo_names()
#: the least-squares ones (Kiev 2012 eqs 18, 22, 31)
LEAST_SQUARES = registry.least_squares_names()
#: runs per random-number block (part of the result's identity, like the seed)
BLOCK_RUNS = 1000
#: the seminar's Kalman table rows (digest "Kalman variant")
SEMINAR_IMAGE_COUNTS = (1, 2, 4, 8, 12, 20)


# ---------------------------------------------------------------------------- seeding and chunks

def block_seed(seed: int, block: int) -> np.random.SeedSequence:
    """The seed sequence of run block ``block``: child ``block`` of ``SeedSequence(seed)``.

    >>> block_seed(1, 3).spawn_key == np.random.SeedSequence(1).spawn(4)[3].spawn_key
    True
    """
    return np.random.SeedSequence(seed, spawn_key=(int(block),))


def plan_chunks(runs: int, chunk_runs: int, block_runs: int = BLOCK_RUNS) -> list:
    """Split runs 0..runs−1 into chunks of ``chunk_runs``; each chunk is a list of block
    segments ``(block, start, stop)`` (run offsets inside the block).

    >>> plan_chunks(5, 3, block_runs=2)
    [[(0, 0, 2), (1, 0, 1)], [(1, 1, 2), (2, 0, 1)]]
    """
    for name, v in (("runs", runs), ("chunk_runs", chunk_runs), ("block_runs", block_runs)):
        if not (isinstance(v, (int, np.integer)) and v >= 1):
            raise ValueError(f"{name} must be an integer ≥ 1, got {v!r}")
    chunks = []
    for a in range(0, runs, chunk_runs):
        b = min(a + chunk_runs, runs)
        segs, k = [], a
        while k < b:
            blk = k // block_runs
            stop = min(b, (blk + 1) * block_runs)
            segs.append((blk, k - blk * block_runs, stop - blk * block_runs))
            k = stop
        chunks.append(segs)
    return chunks


def _block_size(runs, block, block_runs):
    return min(block_runs, runs - block * block_runs)


def draw_block(scenario, arrays, seed: int, block: int, runs: int, block_runs: int = BLOCK_RUNS) -> dict:
    """All random draws of block ``block`` (θ and sensor errors, ``orbits.draw_scenario_errors``)."""
    import orbits

    rng = np.random.default_rng(block_seed(seed, block))
    return orbits.draw_scenario_errors(scenario, rng, _block_size(runs, block, block_runs), arrays)



# ---------------------------------------------------------------------------- one chunk

#: error-dict entry and axis of each disturbance source (Kiev 2012 eq 28's s; boresight.error_sources)
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


def _estimate_variant(job: _Job, errors: dict, variant: str) -> dict:
    import orbits

    from boresight.observations import from_measurements

    obs = from_measurements(orbits.observe(errors, **job.arrays))
    truth = errors["theta_rad"][:, None, :]
    out = {}
    s0 = None
    if job.algorithms:
        s0 = camera_vectors0(obs)
    F = obs.focal_length_m
    for name in job.algorithms:
        if name == "kalman_theta":
            xh, _ = kalman_theta_kernel(s0, obs.xy_m, obs.mask, F, job.kalman_W[variant], job.kalman_sigma0_rad, job.kalman_iterations)
            est = xh[:, [k - 1 for k in job.image_counts]]
        else:
            est = np.empty((obs.runs, len(job.image_counts), 3))
            for j, k in enumerate(job.image_counts):
                if name == "image_plane":
                    est[:, j] = image_plane_kernel(s0[:, :k], obs.xy_m[:, :k], obs.mask[:k], F, job.iterations)
                else:
                    sub = obs if k == obs.n_images else obs.images(slice(0, k))
                    kernel = {"ground_plane": ground_plane_kernel, "unit_vector": unit_vector_kernel}[name]
                    est[:, j] = kernel(sub, s0[:, :k], job.iterations)
        out[name] = (est - truth) / ARCSEC
    return out


def estimate_errors(job: _Job, errors: dict) -> dict:
    """θ̂ − θ (arcsec) for one batch of drawn errors: {key: (R, len(image_counts), ...)}.

    Keys: the algorithm name for the base case; with variants (sources scaled, common random
    numbers) also ``"alg@variant"`` and ``"alg@variant:dsq"`` = e_variant² − e_base² (whose mean
    is the variance difference, and whose spread gives its Monte Carlo standard error).
    """
    out, base = {}, None
    for vname, factors in job.variants:
        res = _estimate_variant(job, scale_errors(errors, dict(factors)) if factors else errors, vname)
        if base is None:
            base = res
            out.update(res)
            continue
        for alg, x in res.items():
            out[f"{alg}@{vname}"] = x
            out[f"{alg}@{vname}:dsq"] = x * x - base[alg] * base[alg]
    return out


def _run_chunk(job: _Job, segments) -> tuple:
    """Worker entry: draw each block segment of the chunk, estimate, return per-run errors."""
    parts = [draw_block(job.scenario, job.arrays, job.seed, b, job.runs, job.block_runs) for b, _, _ in segments]
    errors = {
        key: np.concatenate([p[key][a:z] for p, (_, a, z) in zip(parts, segments)]) for key in parts[0]
    }
    return segments, estimate_errors(job, errors)


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
            self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)

    def submit(self, fn, *args):
        if self.pool is None:
            return _Done(fn(*args))
        return self.pool.submit(fn, *args)

    def close(self):
        if self.pool is not None:
            self.pool.shutdown(wait=True)


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
        self.workers = workers

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def close(self):
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

    def sigma_arcsec(self, algorithm: str) -> np.ndarray:
        return self.moments[algorithm].std

    def table(self, beta: float | None = None):
        """One row per (algorithm, number of images): mean, σ with its χ² interval, max |θ error|."""
        from astropy import units as u
        from astropy.table import Table

        beta = self.beta if beta is None else beta
        rows = []
        for name in self.algorithms:
            mo = self.moments[name]
            sd = mo.std
            lo, hi = sigma_interval(sd, mo.count, beta)
            for j, k in enumerate(self.image_counts):
                rows.append((name, k, mo.count, *mo.mean[j], *sd[j], *lo[j], *hi[j], *mo.max_abs[j], float(np.sqrt((sd[j] ** 2).sum()))))
        names = ["algorithm", "n_images", "runs"]
        for stem in ("mean_theta", "sigma_theta", "sigma_theta_lo", "sigma_theta_hi", "max_abs_theta"):
            names += [f"{stem}_{ax}" for ax in "xyz"]
        names.append("sigma_theta_total")
        t = Table(rows=rows, names=names)
        for c in names[3:]:
            t[c].unit = u.arcsec
        t.meta.update(
            scenario=self.scenario_name,
            runs=int(self.runs),
            seed=int(self.seed),
            block_runs=int(self.block_runs),
            beta=float(beta),
            epsilon_achieved=achieved_epsilon(self.runs, beta) if self.runs >= 2 else None,
            note="θ̂ − θ in arcsec; sigma_theta_lo/hi: χ² confidence interval at beta",
        )
        return t


def _resolve_scenario(scenario):
    import orbits

    if isinstance(scenario, orbits.Scenario):
        return scenario
    return orbits.load_scenario(scenario)


def _montecarlo_name(a: str) -> str:
    """The Monte Carlo name of ``a`` (a name or alias in boresight.registry, or a renamed one)."""
    import warnings

    if a in registry.MONTECARLO_RENAMED:
        new, why = registry.MONTECARLO_RENAMED[a]
        warnings.warn(f"algorithm {a!r}: {why}; running {new!r}", FutureWarning, stacklevel=4)
        return new
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
    """The seminar's 1, 2, 4, 8, 12, 20 images (those ≤ n_images) plus n_images itself.

    >>> default_image_counts(1), default_image_counts(10)
    ((1,), (1, 2, 4, 8, 10))
    """
    return tuple(sorted({k for k in SEMINAR_IMAGE_COUNTS if k <= n_images} | {n_images}))


def run(
    scenario,
    algorithms=("image_plane",),
    runs: int = 45000,
    seed: int = 1,
    *,
    chunk_runs: int | None = None,
    block_runs: int = BLOCK_RUNS,
    workers: int | None = None,
    engine="local",
    scheduler: str | None = None,
    image_counts=None,
    iterations: int = 2,
    kalman_iterations: int = 3,
    keep_runs: int = 100_000,
    progress=None,
    beta: float = 0.9973,
    variants=None,
) -> MonteCarloResult:
    """Monte Carlo of θ̂ − θ for ``algorithms`` over ``runs`` runs of ``scenario``.

    ``scenario``: an ``orbits.Scenario`` or TOML path. ``algorithms``: names from
    ``ALGORITHMS``, or ``"all"``. ``chunk_runs``: runs per task (memory ∝ chunk_runs × workers;
    default ``default_chunk_runs``).
    ``engine``: ``"local"`` (processes; ``workers=1`` runs in this process), ``"dask"`` (a
    ``LocalCluster`` of ``workers``, or the cluster at ``scheduler``), or an engine from
    ``make_engine`` (kept open). ``image_counts``: numbers of images (first k of the
    scenario's) to estimate with; default ``default_image_counts``. ``iterations``:
    Gauss-Newton steps from θ0 = 0 for the least-squares algorithms (2 converge to < 1e-6″ from
    a 10′ θ). ``kalman_iterations``: IEKF steps per image. ``progress(done_runs, runs)`` is called
    as chunks finish. ``variants``: {name: {source: factor}} extra cases computed on the same
    draws (common random numbers, ``scale_errors``), for ``boresight.sensitivity``. The result
    is identical for any ``chunk_runs``, ``workers`` and engine.
    """
    import orbits

    t0 = time.perf_counter()
    sc = _resolve_scenario(scenario)
    algs = resolve_algorithms(algorithms)
    for name, v in (("iterations", iterations), ("kalman_iterations", kalman_iterations), ("keep_runs", keep_runs + 1)):
        if not (isinstance(v, (int, np.integer)) and v >= 1):
            raise ValueError(f"{name} must be an integer ≥ 1, got {v!r}")
    if not (isinstance(runs, (int, np.integer)) and runs >= 2):
        raise ValueError(f"runs must be an integer ≥ 2, got {runs!r}")
    if sc.theta_true_arcsec is None and sc.theta_sigma0_arcsec <= 0 and "kalman_theta" in algs:
        raise ValueError("scenario.theta_sigma0_arcsec must be > 0 for the Kalman filter's prior (misalignment.sigma0_arcsec)")
    arrays = orbits.campaign_arrays(sc)
    n_img = arrays["t_s"].size
    if chunk_runs is None:
        chunk_runs = default_chunk_runs(n_img * arrays["landmarks_g_m"].shape[0], algs)
    chunks = plan_chunks(int(runs), int(chunk_runs), int(block_runs))
    counts = default_image_counts(n_img) if image_counts is None else tuple(int(k) for k in image_counts)
    if not counts or min(counts) < 1 or max(counts) > n_img:
        raise ValueError(f"image_counts must lie in 1..{n_img} (the scenario's images), got {image_counts!r}")
    variants = (("", ()),) + tuple((str(k), tuple(sorted(dict(v).items()))) for k, v in (variants or {}).items())
    for vname, factors in variants[1:]:
        if not vname or "@" in vname or ":" in vname:
            raise ValueError(f"variant names must be non-empty without '@' or ':', got {vname!r}")
        for src, f in factors:
            if src not in SOURCE_ERRORS:
                raise ValueError(f"variants[{vname!r}]: unknown disturbance source {src!r}; expected one of {list(SOURCE_ERRORS)}")
            if not (np.isfinite(f) and f >= 0):
                raise ValueError(f"variants[{vname!r}][{src!r}] must be a finite factor ≥ 0, got {f!r}")
    W, sigma0 = {}, 0.0
    if "kalman_theta" in algs:
        from boresight.disturbances import DisturbanceModel, image_covariance

        nom = nominal_observations(sc, arrays)
        # DECISION: R_n from the nominal geometry, once, for all runs. The module's filter
        # re-evaluates it about each run's estimate; R_n moves by O(|θ|): the estimates agree
        # to 1e-4 of σθ with a 10″ prior and ~1 % of σθ with a 10′ prior
        # (tests/test_montecarlo.py), and it turns 45 000 × 20-image runs from minutes into seconds.
        base_model = DisturbanceModel.from_scenario(sc)
        for vname, factors in variants:
            W[vname] = np.linalg.inv(image_covariance(nom, np.zeros(3), _scaled_model(base_model, dict(factors)))[0])
        sigma0 = (sc.theta_sigma0_arcsec if sc.theta_true_arcsec is None else max(np.abs(sc.theta_true_arcsec).max(), 1.0)) * ARCSEC
    job = _Job(sc, arrays, algs, counts, int(seed), int(runs), int(block_runs), int(iterations), int(kalman_iterations), W, sigma0, variants)

    own = not hasattr(engine, "submit")
    eng = make_engine(engine, workers if workers is not None else min(default_workers(), len(chunks)), scheduler) if own else engine
    n_blocks = -(-runs // block_runs)
    totals = {}
    samples = {a: [] for a in algs}
    kept = 0
    pending_blocks = {}  # block -> list of (start, errors dict)
    next_block = 0
    done_runs = 0
    window = 2 * max(1, getattr(eng, "workers", 1))
    try:
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
            off = 0
            for b, a, z in segments:
                pending_blocks.setdefault(b, []).append((a, {k: v[off : off + z - a] for k, v in errs.items()}))
                off += z - a
            # merge every complete block, in block order
            while next_block < n_blocks:
                parts = pending_blocks.get(next_block, [])
                size = _block_size(runs, next_block, block_runs)
                if sum(len(p[1][algs[0]]) for p in parts) < size:
                    break
                parts.sort(key=lambda p: p[0])
                for name in parts[0][1]:
                    x = np.concatenate([p[1][name] for p in parts])
                    mo = Moments.from_samples(x)
                    totals[name] = mo if name not in totals else totals[name].merge(mo)
                    if kept < keep_runs and name in samples:
                        samples[name].append(x[: keep_runs - kept])
                kept += min(size, keep_runs - kept) if kept < keep_runs else 0
                del pending_blocks[next_block]
                next_block += 1
            done_runs += off
            if progress is not None:
                progress(done_runs, runs)
    finally:
        if own:
            eng.close()
    inputs = {
        "scenario_source": sc.source,
        "seed": int(seed),
        "runs": int(runs),
        "chunk_runs": int(chunk_runs),
        "block_runs": int(block_runs),
        "algorithms": list(algs),
        "image_counts": list(counts),
        "iterations": int(iterations),
        "kalman_iterations": int(kalman_iterations),
        "engine": engine if isinstance(engine, str) else type(engine).__name__,
        "variants": {k: dict(v) for k, v in variants[1:]},
    }
    return MonteCarloResult(
        scenario_name=sc.name,
        algorithms=algs,
        image_counts=counts,
        runs=int(runs),
        seed=int(seed),
        block_runs=int(block_runs),
        chunk_runs=int(chunk_runs),
        moments=totals,
        samples={a: np.concatenate(v) for a, v in samples.items()},
        inputs=inputs,
        elapsed_s=time.perf_counter() - t0,
        beta=beta,
    )


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

    def __call__(self, done, total):
        el = time.perf_counter() - self.t0
        frac = done / total if total else 1.0
        eta = el * (1 - frac) / frac if frac > 0 else float("nan")
        n = int(round(self.width * frac))
        msg = f"[{'#' * n}{'.' * (self.width - n)}] {100 * frac:3.0f}% {done}/{total} runs {self.label} elapsed {el:.1f} s ETA {eta:.1f} s"
        end = "\n" if done >= total else ""
        self.stream.write("\r" + msg + end)
        self.stream.flush()

