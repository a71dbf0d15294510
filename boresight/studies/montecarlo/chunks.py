"""One chunk of a study, as a worker runs it: draw its block segments (``seeding``), apply the
variants' scale factors (common random numbers), estimate θ with every algorithm and image count
(``core.algorithms.batched``), return the per-run errors."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from boresight.core.algorithms.batched import (
    camera_vectors0,
    ground_plane_kernel,
    image_plane_kernel,
    kalman_theta_kernel,
    unit_vector_kernel,
    weighted_kernel,
)
from boresight.core.error_sources import ERROR_SOURCES
from boresight.errors import InputValueError, ObservabilityError, StudyError
from boresight.studies.montecarlo.seeding import draw_block
from orbits.rotations import ARCSEC

#: error-dict entry and axis of each disturbance source (Kiev 2012 eq 28's s; boresight.core.error_sources)
SOURCE_ERRORS = {s.symbol: (s.errors_key, s.axis) for s in ERROR_SOURCES.values()}


def scale_errors(errors: dict, factors: dict) -> dict:
    """Drawn errors with source s multiplied by ``factors[s]`` (common random numbers).

    Sources: ``beta1..beta3`` (star-tracker axes), ``P`` (catalogue), ``R`` (GNSS), ``K`` (pixel).
    Scaling the drawn N(0, σ²) errors by f is drawing with σ f from the same normals.

    >>> e = {"delta_rad": np.ones((1, 1, 3)), "pixel_noise_m": np.ones((1, 1, 2))}
    >>> scale_errors(e, {"beta2": 2.0, "K": 0.5})["delta_rad"].tolist(), float(scale_errors(e, {"K": 0.5})["pixel_noise_m"].max())
    ([[[1.0, 2.0, 1.0]]], 0.5)
    """
    out = dict(errors)
    for src, f in factors.items():
        if src not in SOURCE_ERRORS:
            raise InputValueError(f"unknown disturbance source {src!r}; expected one of {list(SOURCE_ERRORS)}")
        key, axis = SOURCE_ERRORS[src]
        a = out[key].copy() if out[key] is errors[key] else out[key]
        if axis is None:
            a *= f
        else:
            a[..., axis] *= f
        out[key] = a
    return out


def scaled_model(model, factors: dict):
    """The ``DisturbanceModel`` with sources scaled as ``scale_errors`` scales the draws."""
    from boresight.core.error_sources import source

    st = np.asarray(model.sigma_star_tracker_rad, float).copy()
    kw = {}
    for symbol, f in factors.items():
        src = source(symbol)
        if src.axis is not None:
            st[src.axis] *= f
        else:
            kw[src.model_field] = getattr(model, src.model_field) * f
    return replace(model, sigma_star_tracker_rad=tuple(st), **kw)


def scaled_rows(obs, factors: dict):
    """``obs`` with its rows' own pixel σ (``sigma_xy_m``) scaled as ``scale_errors`` scales the pixel draws
    (``scaled_model`` scales the model's σK): a variant's weights match its draws."""
    if obs.sigma_xy_m is None:
        return obs
    f = float(np.prod([v for k, v in factors.items() if SOURCE_ERRORS[k][0] == "pixel_noise_m"]))
    return obs if f == 1.0 else obs.with_sigma_xy(obs.sigma_xy_m * f)


@dataclass(frozen=True)
class Job:
    """Everything a worker needs for any chunk (pickled once per task; a few kB)."""

    scenario: Any  # an orbits.Scenario
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


def _estimate_variant(job: Job, errors: dict, variant: str) -> dict:
    import orbits
    from boresight.observations.model import from_measurements

    obs = from_measurements(orbits.observe(errors, **job.arrays))  # rows (the kernels', ``core.algorithms.batched``)
    truth = errors["theta_rad"][:, None, :]
    out: dict[str, np.ndarray] = {}
    weighted = job.weighting != "unit"
    s0: Any = None
    if job.algorithms:
        s0 = camera_vectors0(obs)  # (R, K, 3)
    F = obs.focal_length_m
    xy = obs.xy_m
    first = {k: int(obs.row_start[k]) for k in job.image_counts}  # the first k images' rows: [:first[k]]
    model = scaled_model(job.model, dict(dict(job.variants)[variant])) if weighted and variant else job.model
    if weighted and variant:
        obs = scaled_rows(obs, dict(dict(job.variants)[variant]))
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
                start = image_plane_kernel(s0[:, : first[k]], xy[:, : first[k]], F, job.iterations, max_iterations=30)[0]
                start = np.where(np.isfinite(start).all(axis=-1, keepdims=True), start, 0.0)  # a failed start: θ = 0
                th, var[:, j], conv = weighted_kernel(
                    sub,
                    name,
                    job.weighting,
                    model,
                    job.iterations,
                    max_iterations=job.max_iterations,
                    theta0_arcsec=start / ARCSEC,
                )
                err[:, j] = th - truth[:, 0] / ARCSEC
                nc[:, j] = ~conv
            out[name] = err
            out[name + REPORTED_VARIANCE] = var
            out[name + UNCONVERGED] = nc
            continue
        if name == "kalman_theta":
            xh, _ = kalman_theta_kernel(
                s0, xy, obs.row_start, F, job.kalman_W[variant], job.kalman_sigma0_rad, job.kalman_iterations
            )
            est = xh[:, [k - 1 for k in job.image_counts]]
        else:
            est = np.empty((obs.runs, len(job.image_counts), 3))
            for j, k in enumerate(job.image_counts):
                if name == "image_plane":
                    res = image_plane_kernel(
                        s0[:, : first[k]], xy[:, : first[k]], F, job.iterations, max_iterations=job.max_iterations
                    )
                else:
                    sub = obs if k == obs.n_images else obs.images(slice(0, k))
                    kernel = {"ground_plane": ground_plane_kernel, "unit_vector": unit_vector_kernel}[name]
                    res = kernel(sub, s0[:, : first[k]], job.iterations, max_iterations=job.max_iterations)
                if job.max_iterations is None:
                    est[:, j] = res
                else:
                    est[:, j], conv = res
                    nc[:, j] = ~conv
        out[name] = (est - truth) / ARCSEC
        out[name + UNCONVERGED] = nc
    return out


def estimate_errors(job: Job, errors: dict) -> dict:
    """θ̂ − θ (arcsec) for one batch of drawn errors: {key: (R, len(image_counts), ...)}.

    Keys: the algorithm name for the base case; with variants (sources scaled, common random
    numbers) also ``"alg@variant"`` and ``"alg@variant:dsq"`` = e_variant² − e_base² (whose mean
    is the variance difference, and whose spread gives its Monte Carlo standard error). Each
    estimate key ``k`` also has ``k + "#nc"`` (R, len(image_counts)) bool: the runs whose
    Gauss-Newton iteration did not converge (``core.algorithms.batched.step_converged``; always False for the
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
_LAST_BLOCK: list = [None, None]


def _cached_block(job: Job, b: int) -> dict:
    """``draw_block`` of block ``b``, reusing this process's last draw when it is the same block
    of the same study. DECISION: a chunk smaller than a block used to redraw the whole block
    (a 13-run chunk of a 130-run block drew 10× its runs); the draws are identical either way,
    so the cache changes no number. One block per process: its memory is already counted
    (``preflight.study_bytes``)."""
    import hashlib
    import pickle

    key = (hashlib.sha256(pickle.dumps((job.scenario, job.seed, job.runs, job.block_runs))).hexdigest(), b)
    if _LAST_BLOCK[0] != key:
        _LAST_BLOCK[0], _LAST_BLOCK[1] = None, None  # free the old draws before drawing
        _LAST_BLOCK[1] = draw_block(job.scenario, job.arrays, job.seed, b, job.runs, job.block_runs)
        _LAST_BLOCK[0] = key
    return _LAST_BLOCK[1]


def forget_cached_block() -> None:
    """Drop this process's cached block draws (an in-process study does not keep them after it)."""
    _LAST_BLOCK[:] = [None, None]


def run_chunk(job: Job, segments) -> tuple:
    """Worker entry: draw each block segment of the chunk, estimate, return per-run errors."""
    parts = [_cached_block(job, b) for b, _, _ in segments]
    errors = {key: np.concatenate([p[key][a:z] for p, (_, a, z) in zip(parts, segments)]) for key in parts[0]}
    try:
        return segments, estimate_errors(job, errors)
    except ObservabilityError as exc:
        first = segments[0][0] * job.block_runs + segments[0][1]
        last = segments[-1][0] * job.block_runs + segments[-1][2] - 1
        raise StudyError(
            f"{job.weighting} weighting: θ is not determined in one of runs {first}..{last} (its draws make the normal "
            f"matrix singular; no NaN is written): {' '.join(str(exc).split())}"
        ) from None
