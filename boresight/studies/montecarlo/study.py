"""The study: ``montecarlo_study`` resolves the scenario and algorithms, checks its sizes (``preflight``),
plans the chunks (``seeding``), runs them on an engine (``engines``, ``chunks``), accumulates the
blocks (``accumulator``, with checkpoints) and returns a ``MonteCarloResult``."""

from __future__ import annotations

import json
import time

import numpy as np

from boresight.core import registry
from boresight.errors import InputTypeError, StudyError
from boresight.observations.simulate import nominal_observations
from boresight.studies.montecarlo.accumulator import Accumulator, drive
from boresight.studies.montecarlo.chunks import SOURCE_ERRORS, Job, forget_cached_block
from boresight.studies.montecarlo.engines import default_workers, make_engine, require_dask
from boresight.studies.montecarlo.preflight import (
    POOL_START_SECONDS,
    POOL_THRESHOLD_S,
    SECONDS_FIXED,
    WEIGHTED_CHUNK_BYTES,
    WORKER_EFFICIENCY,
    check_study_memory,
    checkpoint_bytes,
    kalman_iterations_for,
    kalman_setup,
    measured_seconds_per_run,
    observable_counts,
    study_bytes,
    weighted_bytes_per_run,
)
from boresight.studies.montecarlo.result import MonteCarloResult
from boresight.studies.montecarlo.seeding import default_block_runs, plan_chunks

#: every algorithm the engine runs (those with a kernel in boresight.core.registry); "all" in the CLI means these
ALGORITHMS = registry.montecarlo_names()
#: the least-squares ones (Kiev 2012 eqs 18, 22, 31)
LEAST_SQUARES = registry.least_squares_names()
#: image counts a study reports σθ at by default (those ≤ the scenario's images, plus all of them).
# DECISION: a roughly doubling grid up to 20, the grid of the seminar's Kalman table, so the
# default study lines up with it; the seminar's own rows are defined once, in
# ``reproductions.kiev2012.published`` (SEMINAR_IMAGE_COUNTS), and a test checks the two agree.
DEFAULT_IMAGE_COUNTS = (1, 2, 4, 8, 12, 20)
#: the least-squares weightings a study can use (``boresight.estimate``'s)
WEIGHTINGS = ("unit", "diagonal", "gls")


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
        raise registry.UnknownAlgorithmError(
            f"algorithm {a!r} ({row.summary}) has no Monte Carlo kernel; expected one of {valid}"
        )
    return row.name


def resolve_algorithms(algorithms):
    if isinstance(algorithms, str):
        algorithms = [algorithms]
    if not isinstance(algorithms, (list, tuple)) or not all(isinstance(a, str) for a in algorithms):
        raise InputTypeError.expected("study", "algorithms", "an algorithm's name or a list of names", algorithms)
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
        raise StudyError("algorithms is empty: give at least one algorithm's name")
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


def montecarlo_study(
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
    """Monte Carlo of θ̂ − θ for ``algorithms`` over ``runs`` simulated runs of ``scenario``.

    The result is identical for any ``chunk_runs``, ``workers`` and engine, and for an interrupted
    and resumed study: it depends on ``seed``, ``runs`` and ``block_runs`` only.

    Parameters
    ----------
    scenario : orbits.Scenario or str or path
        The scenario or its TOML file.
    algorithms : sequence of str or "all"
        Names from ``ALGORITHMS`` (``boresight.core.registry``), or ``"all"``.
    runs, seed : int
        The number of runs and the random seed.
    chunk_runs : int, optional
        Runs per task (memory ∝ ``chunk_runs`` × workers; default ``default_chunk_runs``). One chunk
        runs on one worker.
    block_runs : int, optional
        Runs per random-number block (part of the result's identity; default ``seeding.BLOCK_RUNS``).
    workers : int, optional
        Local worker processes (``workers=1`` runs in this process); with a dask ``scheduler``, the
        number of chunks in flight (default: the CPUs available).
    engine : str or engine
        ``"local"`` (processes), ``"dask"`` (a ``LocalCluster`` of ``workers``, or the cluster at
        ``scheduler``), or an engine from ``make_engine`` (kept open).
    scheduler : str, optional
        A dask scheduler address (``tcp://host:8786``) for ``engine="dask"``.
    image_counts : sequence of int, optional
        Numbers of images (the first k of the scenario's) to estimate with; default
        ``default_image_counts`` minus the counts whose geometry does not determine θ (named in
        ``result.notes``).
    iterations : int
        Gauss-Newton steps every least-squares run takes from θ0 = 0.
    max_iterations : int or None
        Then iterate each run until ``core.algorithms.batched.step_converged`` (1e-4″), up to this many steps, and
        count the runs that did not converge; None: exactly ``iterations`` steps.
    kalman_iterations : int, optional
        IEKF steps per image (default ``kalman_iterations_for`` the prior σ; 3 for the seminar's).
    keep_runs : int
        The errors of this many runs are kept (``result.samples``, for histograms).
    progress : callable, optional
        ``progress(done_runs, runs)``, called as chunks finish.
    beta : float
        Confidence level of the σ intervals.
    variants : dict, optional
        {name: {source: factor}}: extra cases on the same draws (common random numbers), for
        ``sensitivity_study``.
    checkpoint : path or checkpoint.Checkpoint, optional
        A folder for block checkpoints; with ``resume=True`` the interrupted study there continues.
    resume : bool
        Continue the study in ``checkpoint`` (refused, naming what changed, if its inputs differ).
    weighting : str
        ``"unit"`` (the batched unit-weight kernels, eqs 18/22/31), or ``"diagonal"``/``"gls"``:
        each run estimated exactly as ``boresight.estimate(obs, algorithm, weighting=weighting,
        model=DisturbanceModel.from_scenario(sc))``, and the σ it reports kept
        (``result.reported_sigma_arcsec``). ``kalman_theta`` uses the noise model under every choice.
    preflight : callable, optional
        ``preflight(dict)``, called once the sizes are checked and before any run, with ``runs``,
        ``cases``, ``workers``, ``memory_bytes``, estimated ``seconds`` and checkpoint ``disk_bytes``
        (``format_preflight`` makes the line the commands print).

    Returns
    -------
    MonteCarloResult
        σθ and max abs(θ̂ − θ) per algorithm and image count (``result.table()``), with χ² intervals.

    Raises
    ------
    ObservabilityError
        A requested image count whose geometry does not determine θ.
    MemoryBudgetError
        A study over the memory budget (refused up front).
    StudyError
        A Kalman study whose per-image noise covariance is singular (with ``"all"`` the Kalman
        filter is skipped with a note instead), or a non-finite estimate (naming the run: never a
        NaN in the result); a ``seed`` that is not an integer ≥ 0, ``image_counts`` outside the
        scenario's images.
    UnknownAlgorithmError
        A name in ``algorithms`` that is not a study algorithm (the message lists them).
    ResumeError
        A resume whose inputs (scenario, seed, sizes, …) differ from the checkpoint's.
    """
    t0 = time.perf_counter()
    sc = _resolve_scenario(scenario)
    algs = resolve_algorithms(algorithms)
    model = _study_model(sc, weighting)
    explicit_kalman = bool({"kalman", "kalman_theta"} & set([algorithms] if isinstance(algorithms, str) else list(algorithms)))
    _check_counts(runs=runs, seed=seed, iterations=iterations, keep_runs=keep_runs, max_iterations=max_iterations)
    variants = _check_variants(variants)
    if sc.theta_true_arcsec is None and sc.theta_sigma0_arcsec <= 0 and "kalman_theta" in algs:
        raise StudyError(f"{sc.source}: the Kalman filter needs a prior: [misalignment] sigma0_arcsec must be > 0")
    import orbits
    from orbits.measurements import pixel_draws_per_run

    arrays = orbits.campaign_arrays(sc)
    n_img = arrays["t_s"].size
    obs_per_run = int(arrays["rows"][0].size)  # the observations (rows) of one run
    notes: list[str] = []
    counts = _requested_counts(image_counts, n_img)
    # DECISION: a block's size follows the pixel-noise pairs a run draws (the grid's N·M while its
    # draw order is kept, ``orbits.measurements``), so every study keeps the blocks — and the
    # numbers — it had before the row model; memory and chunks follow the rows
    draws = pixel_draws_per_run(n_img, arrays["landmarks_g_m"].shape[0], obs_per_run)
    block_runs = _checked_size("block_runs", default_block_runs(draws) if block_runs is None else block_runs)
    nom = nominal_observations(sc, arrays)
    algs = _star_algorithms(sc, nom, algs, algorithms, notes)
    counts = observable_counts(
        sc, nom, algs, counts, explicit=image_counts is not None, notes=notes, weighting=weighting, model=model
    )
    algs, W, sigma0 = kalman_setup(sc, nom, algs, variants, explicit_kalman, notes)
    if kalman_iterations is None:
        kalman_iterations = kalman_iterations_for(sigma0)
    _check_counts(kalman_iterations=kalman_iterations)
    per_run, _ = weighted_bytes_per_run(nom, algs, counts, weighting, model) if weighting != "unit" else (0.0, 0.0)
    chunk_runs = _checked_size(
        "chunk_runs", _default_chunk_runs(obs_per_run, algs, per_run) if chunk_runs is None else chunk_runs
    )
    n_workers = workers or getattr(engine, "workers", None) or default_workers()
    nbytes = study_bytes(
        runs,
        int(chunk_runs),
        int(block_runs),
        obs_per_run,
        len(counts),
        len(algs),
        len(variants),
        keep_runs,
        n_workers,
        weighted_bytes_per_run=per_run,
    )
    mem = check_study_memory(nbytes, runs, int(chunk_runs), int(block_runs), obs_per_run, n_workers)
    job = Job(
        sc,
        arrays,
        algs,
        counts,
        int(seed),
        int(runs),
        int(block_runs),
        int(iterations),
        int(kalman_iterations),
        W,
        sigma0,
        variants,
        None if max_iterations is None else int(max_iterations),
        weighting,
        model,
    )
    used = min(n_workers, -(-runs // int(chunk_runs)))
    if preflight is not None or (workers is None and engine == "local"):
        # measured on the study's first runs, not modelled (preflight.measured_seconds_per_run)
        per_run_s, per_call_s = measured_seconds_per_run(job, int(runs), int(chunk_runs))
        seconds = SECONDS_FIXED + int(runs) * per_run_s + -(-int(runs) // int(chunk_runs)) * per_call_s
        if workers is None and engine == "local" and seconds < POOL_THRESHOLD_S:
            workers = used = (
                1  # DECISION: no process pool for sub-second work (see POOL_THRESHOLD_S); the numbers do not depend on it
            )
    if preflight is not None:
        preflight(
            {
                "runs": int(runs),
                "cases": len(variants),
                "workers": int(used),
                "memory_bytes": mem,
                "seconds": SECONDS_FIXED
                + (seconds - SECONDS_FIXED) / (1.0 if used <= 1 else used * WORKER_EFFICIENCY)
                + (POOL_START_SECONDS if used > 1 else 0.0),
                "measured": True,
                "disk_bytes": checkpoint_bytes(
                    int(runs), int(block_runs), len(counts), len(algs), len(variants), keep_runs, weighting != "unit"
                )
                if checkpoint is not None
                else 0.0,
            }
        )
    if engine == "dask":
        require_dask()  # before the checkpoint folder is made
    acc = _accumulator(job, keep_runs, checkpoint, resume)
    chunks = plan_chunks(int(runs), int(chunk_runs), int(block_runs), start_block=acc.next_block)
    if progress is not None and acc.done_runs:
        progress(acc.done_runs, runs)
    resumed = acc.next_block
    if chunks:
        _run_chunks(job, chunks, acc, progress, engine, workers, scheduler)
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
        predicted=_predictions(sc, nom, algs, counts, model, weighting),
    )


#: the algorithms that need every target's position (a ground plane): none on a star row
NEEDS_POSITIONS = ("ground_plane",)


def _star_algorithms(sc, nom, algs: tuple, asked, notes: list) -> tuple:
    """``algs`` without those of ``NEEDS_POSITIONS`` when the campaign has star rows (a direction at
    infinity, ``docs/stars.md``) or landmark rows with light time and aberration (``landmark_sight``: the ground plane
    is geometric): dropped with a note under "all"/"least_squares", refused by name."""
    if np.any(nom.target_kinds() == "star"):
        why = "this campaign's star frames see targets at infinity", "star rows have none"
    elif nom.landmark_sight != "geometric":
        why = (
            f"this campaign's landmark rows carry {nom.landmark_sight}",
            f"landmark rows with {nom.landmark_sight} have no geometric one",
        )
    else:
        return algs
    named = {registry.lookup(a).name for a in ([asked] if isinstance(asked, str) else asked) if a not in ("all", "least_squares")}
    for a in NEEDS_POSITIONS:
        if a in named:
            raise StudyError(
                f"{sc.source}: {a} needs each target's position (Kiev 2012's ground plane, geometric), and {why[0]}: "
                "use image_plane, unit_vector or kalman_theta"
            )
    dropped = [a for a in algs if a in NEEDS_POSITIONS]
    if dropped:
        notes.append(f"{', '.join(dropped)} skipped: it needs each target's position, and {why[1]} (docs/stars.md)")
    return tuple(a for a in algs if a not in NEEDS_POSITIONS)


def _requested_counts(image_counts, n_img: int) -> tuple:
    """The image counts asked for (default ``default_image_counts``), each in 1..n_img."""
    try:
        counts = default_image_counts(n_img) if image_counts is None else tuple(int(k) for k in image_counts)
    except (TypeError, ValueError):
        counts = ()
    if not counts or min(counts) < 1 or max(counts) > n_img:
        raise StudyError(f"image_counts must lie in 1..{n_img} (the scenario's images), got {image_counts!r}")
    return counts


def _checked_size(name: str, v):
    """``block_runs`` / ``chunk_runs``: an integer ≥ 1, or a ``StudyError`` naming it."""
    if not (isinstance(v, (int, np.integer)) and v >= 1):
        raise StudyError(f"{name} must be an integer ≥ 1, got {v!r}")
    return v


def _default_chunk_runs(obs_per_run: int, algs, weighted_bytes_per_run: float) -> int:
    """``default_chunk_runs``, capped for a weighted study by ``WEIGHTED_CHUNK_BYTES``."""
    chunk_runs = default_chunk_runs(obs_per_run, algs)
    if weighted_bytes_per_run:
        chunk_runs = int(max(1, min(chunk_runs, WEIGHTED_CHUNK_BYTES // weighted_bytes_per_run)))
    return chunk_runs


def _accumulator(job: Job, keep_runs: int, checkpoint, resume: bool) -> Accumulator:
    """The study's accumulator, with the checkpoint attached and its finished blocks merged."""
    acc = Accumulator(job.algorithms, job.runs, job.block_runs, int(keep_runs))
    if checkpoint is None:
        return acc
    from boresight.studies.montecarlo.checkpoint import Checkpoint

    ckpt = checkpoint if isinstance(checkpoint, Checkpoint) else Checkpoint(checkpoint)
    done = ckpt.open(_identity(job, keep_runs), resume)
    for b in range(min(done, acc.n_blocks)):
        acc.merge_block(b, *ckpt.load(b))
    acc.checkpoint = ckpt
    return acc


def _run_chunks(job: Job, chunks, acc: Accumulator, progress, engine, workers, scheduler) -> None:
    """Run the chunks on ``engine`` (a name: started here and closed, aborted on an error; an
    engine object: kept open)."""
    own = not hasattr(engine, "submit")
    eng = (
        make_engine(engine, workers if workers is not None else min(default_workers(), len(chunks)), scheduler) if own else engine
    )
    ok = False
    try:
        drive(eng, job, chunks, acc, progress)
        ok = True
    except BaseException:  # interrupted or failed: the finished blocks stay for a resume, flushed to disk
        if acc.checkpoint is not None:
            acc.checkpoint.sync()
        raise
    finally:
        forget_cached_block()  # an in-process study's cached draws are not kept after it
        if own:
            eng.close(abort=not ok)


def _predictions(sc, nom, algs, counts, model, weighting: str) -> dict:
    """A unit-weighted study's linear σ predictions (``_unit_predictions``) under the scenario's noise model; {} when weighted."""
    if weighting != "unit":
        return {}
    return _unit_predictions(nom, algs, counts, model if model is not None else _study_model(sc, "diagonal", quiet=True))


def _check_counts(**values):
    for name, v in values.items():
        if name == "max_iterations" and v is None:
            continue
        lo = 0 if name in ("keep_runs", "seed") else (2 if name == "runs" else 1)
        if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= lo):
            raise StudyError(f"{name} must be an integer ≥ {lo}, got {v!r}")


def _check_variants(variants) -> tuple:
    out = (("", ()),) + tuple((str(k), tuple(sorted(dict(v).items()))) for k, v in (variants or {}).items())
    for vname, factors in out[1:]:
        if not vname or "@" in vname or ":" in vname or "#" in vname:
            raise StudyError(f"variant names must be non-empty without '@', ':' or '#', got {vname!r}")
        for src, f in factors:
            if src not in SOURCE_ERRORS:
                raise StudyError(
                    f"variants[{vname!r}]: unknown disturbance source {src!r}; expected one of {list(SOURCE_ERRORS)}"
                )
            # DECISION: factors up to 10⁶: beyond, σ·f overflows the squares of the estimators
            if isinstance(f, bool) or not (np.isfinite(f) and 0 <= f <= 1e6):
                raise StudyError(f"variants[{vname!r}][{src!r}] must be a finite factor in [0, 1e6], got {f!r}")
    return out


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


def _identity(job: Job, keep_runs: int) -> dict:
    """Everything a study's numbers depend on (the checkpoint's identity): not the chunking,
    the workers or the engine, which do not change them."""
    from dataclasses import asdict

    scen = asdict(job.scenario)
    scen.pop("source", None)
    for key in ("stars", "star_frames"):  # absent from a landmark scenario's identity (as before star frames)
        if not scen.get(key):
            scen.pop(key, None)
    if scen.get("landmark_sight") == "geometric":  # the default: absent, so a checkpoint from before the key resumes
        scen.pop("landmark_sight")
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
