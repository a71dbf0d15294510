"""Monte Carlo studies of the θ estimators: vectorised, chunked, parallel, chunk-invariant.

``montecarlo_study(scenario, algorithms, runs, seed)`` simulates ``runs`` independent passes of a scenario
(``orbits``), estimates θ with each algorithm, and streams the statistics of the error
θ̂ − θ (mean, σ, max ``|error|`` per axis, per algorithm and per number of images used).

Seeding (why the result does not depend on the chunk size or the number of workers)
-----------------------------------------------------------------------------------
Runs are grouped in fixed **blocks** of ``block_runs`` (default 1000). Block b draws all its
random numbers from its own generator ``default_rng(SeedSequence(seed, spawn_key=(b,)))`` —
the b-th child of ``SeedSequence(seed).spawn(...)`` — in the simulator's fixed draw order.
A **chunk** (the unit of work sent to a worker) is any run range; the part of a block it
covers is the block's draws sliced to those runs, so run k always sees the same numbers.
Each block's statistics are computed from its own per-run errors and merged into the total
in block order (Chan et al. parallel moments), so the floating-point sums are the same for
any chunking, worker count or engine. The numbers depend on ``seed``, ``runs`` and
``block_runs`` only.

Sample size (Kiev 2012, "Monte Carlo sample size"): ``required_runs(beta, eps)``; each
reported σ carries its χ² confidence interval and the relative precision ε it achieves.

Modules, one job each: ``sample_size`` (the 45 000-run rule, χ² intervals), ``moments``
(mergeable streamed statistics), ``seeding`` (blocks, the chunk plan), ``chunks`` (one chunk as a
worker runs it), ``engines`` (local processes, dask),
``preflight`` (observability, Kalman weights, memory, time and disk before any run),
``accumulator`` (blocks merged in order, checkpointed), ``result`` (``MonteCarloResult``),
``progress`` (the bar), ``study`` (``montecarlo_study``), ``checkpoint`` (lock, resume), ``file_study``
(``montecarlo FILE.ecsv``). Everything public is re-exported here.

Kernels (``boresight.core.algorithms.batched``, beside the algorithms they mirror; which one runs a
name is ``boresight.core.registry``'s ``montecarlo_kernel``).
Hand-written batched forms of the estimators, each tested against the module it mirrors
(``tests/studies/test_montecarlo.py``): ``image_plane_kernel`` (Algorithm 3, structure of arrays, the
θ-independent camera vectors computed once per chunk), ``ground_plane_kernel`` and
``unit_vector_kernel`` (Algorithm 2 and the unit-vector algorithm, Gauss-Newton with a batched
3 × 3 solve), and ``kalman_theta_kernel`` (the Monte Carlo study's θ-only filter, information
form with per-image R_n fixed at the nominal geometry — *not* the library's
``estimate(algorithm="kalman")``, which also carries bias and catalogue states and has no
kernel: ``kalman`` is refused here, naming the choices). ``gauss_newton`` runs any module's
``linearize`` over a batch. Rotation math comes from ``orbits.rotations``.
``weighted_kernel`` runs ``montecarlo_study(weighting="gls"|"diagonal")``: the library estimator
``boresight.estimate`` itself on a chunk of runs, with per-run convergence (``docs/montecarlo.md``,
"Weighting").

Example
-------
>>> from boresight.studies.montecarlo import montecarlo_study, required_runs
>>> r = montecarlo_study("scenarios/kiev2012-sensitivity.toml", ["image_plane"], runs=300, seed=1, workers=1)
>>> r.table()["sigma_theta_x"].unit.to_string(), r.runs
('arcsec', 300)
>>> required_runs(0.9973, 0.01)
45000
"""

import importlib

# DECISION: the public names are resolved on first use (PEP 562), so that importing
# one module of this package (``seeding`` for the defaults that ``boresight montecarlo --help``
# shows) does not load the engines, kernels and estimators. Each entry: name → its module (in this
# package, or a full module name: the batched kernels live beside the algorithms they mirror).
_EXPORTS = {
    "ALGORITHMS": "study",
    "LEAST_SQUARES": "study",
    "WEIGHTINGS": "study",
    "BLOCK_RUNS": "seeding",
    "DEFAULT_IMAGE_COUNTS": "study",
    "Moments": "moments",
    "MonteCarloResult": "result",
    "t_beta": "sample_size",
    "required_runs": "sample_size",
    "achieved_epsilon": "sample_size",
    "sigma_interval": "sample_size",
    "block_seed": "seeding",
    "plan_chunks": "seeding",
    "draw_block": "seeding",
    "camera_vectors0": "boresight.core.algorithms.batched",
    "image_plane_kernel": "boresight.core.algorithms.batched",
    "kalman_theta_kernel": "boresight.core.algorithms.batched",
    "gauss_newton": "boresight.core.algorithms.batched",
    "ground_plane_kernel": "boresight.core.algorithms.batched",
    "unit_vector_kernel": "boresight.core.algorithms.batched",
    "weighted_kernel": "boresight.core.algorithms.batched",
    "estimate_errors": "chunks",
    "scale_errors": "chunks",
    "SOURCE_ERRORS": "chunks",
    "make_engine": "engines",
    "default_chunk_runs": "study",
    "default_image_counts": "study",
    "default_workers": "engines",
    "nominal_observations": "boresight.observations.simulate",
    "resolve_algorithms": "study",
    "montecarlo_study": "study",
    "ProgressBar": "progress",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    try:
        module = _EXPORTS[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module if "." in module else f"{__name__}.{module}"), name)
    globals()[name] = value  # resolved once
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
