"""A Monte Carlo study on an observation file's own geometry: is the σ I was given right for MY pass?

``file_study(obs, model, …)`` estimates θ from the file exactly as ``boresight estimate`` would
(same algorithm, weighting, noise model, floated effects, robust loss), then resimulates the file
``runs`` times — the same images, landmarks, attitudes, positions and visibility, new errors drawn
from the noise model — and estimates each resimulated set the same way. The scatter of those
estimates is what the file's σ should be; the report is the reported σ against that scatter with
its χ² interval.

Resimulation (``resimulate``), a parametric bootstrap about the file's fit:

* truth: θ = the file's estimate θ̂, the geometry the file reports (star-tracker attitude,
  spacecraft position, catalogue landmark positions) taken as the true one, the image points
  predicted by the exact model (``boresight.core.measurement.predict``) at θ̂;
* reported: each run draws the noise model's errors (``orbits.measurements.draw_errors``: per image
  and/or per pass as the model's modes say, catalogue errors per landmark, pixel noise) and
  applies them as the simulator does (``orbits.measurements.observe``): attitude turned by the
  star-tracker error, position + GNSS error, landmarks + catalogue error, points + pixel noise.

DECISION: floated effects are floated in every refit but simulated at zero size: the σ of a fit
that is linear in the effects' parameters near the solution does not depend on their values
(to first order), and a fitted effect's estimate is itself noisy. DECISION: each block of
``BLOCK_RUNS`` runs draws from its own generator (``seeding.block_seed``), so the numbers depend
on ``seed`` and ``runs`` only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from orbits.rotations import ARCSEC

__all__ = ["FileStudy", "resimulate", "file_study", "BLOCK_RUNS"]

#: runs per random-number block (and per batch of refits)
BLOCK_RUNS = 100


@dataclass
class FileStudy:
    """θ̂ − θ̂_file (arcsec) statistics over the resimulated runs, against the file's reported σ."""

    algorithm: str
    weighting: str
    effects: tuple
    loss: str | None
    runs: int
    seed: int
    beta: float
    theta_arcsec: np.ndarray  # (3,) the file's estimate
    reported_sigma_arcsec: np.ndarray  # (3,) its σ
    errors_arcsec: np.ndarray  # (runs, 3) θ̂_run − θ̂_file
    mean_reported_sigma_arcsec: np.ndarray  # (3,) √(mean over runs of the variance each refit reports)
    unconverged: int
    elapsed_s: float = 0.0
    #: a pushbroom file's study (``line_scan.line_scan_file_study``): every unknown's ``names``, ``errors`` and
    #: ``sigma`` (runs, n) and the file's ``x``, ``reported_sigma`` (n,), SI; None for a frame camera's file
    extra: dict | None = None

    @property
    def sigma_arcsec(self) -> np.ndarray:
        """The Monte Carlo scatter σ per axis (sample standard deviation)."""
        return self.errors_arcsec.std(axis=0, ddof=1)

    @property
    def mean_error_arcsec(self) -> np.ndarray:
        """(3,) the mean of θ̂_run − θ̂_file over the runs (a bias of the refit about its own estimate)."""
        return self.errors_arcsec.mean(axis=0)

    @property
    def mean_error_se_arcsec(self) -> np.ndarray:
        """(3,) the standard error of ``mean_error_arcsec``: the scatter σ over √runs."""
        return self.sigma_arcsec / np.sqrt(self.runs)

    def interval(self):
        """(lo, hi) per axis: the χ² interval of the scatter σ at ``beta``."""
        from boresight.stats import sigma_interval

        return sigma_interval(self.sigma_arcsec, self.runs, self.beta)

    def inside(self) -> np.ndarray:
        """(3,) bool: the file's reported σ inside the scatter's interval."""
        lo, hi = self.interval()
        return (lo <= self.reported_sigma_arcsec) & (self.reported_sigma_arcsec <= hi)


def _noise_draws(model, rng, runs: int, pass_index, n_landmarks: int, theta_rad, rows, sigma_rows_m=None) -> dict:
    from orbits.measurements import draw_errors
    from orbits.sensors import GnssErrors, PixelNoise, StarTrackerErrors

    return draw_errors(
        rng,
        runs,
        pass_index,
        n_landmarks,
        rows=rows,
        theta_true_rad=theta_rad,
        star_tracker=StarTrackerErrors(tuple(model.sigma_star_tracker_rad), model.star_tracker_mode),
        gnss=GnssErrors(model.sigma_gnss_m, model.gnss_mode),
        pixel=PixelNoise(model.sigma_pixel_m),
        catalogue_sigma_m=model.sigma_catalogue_m,
        pixel_sigma_rows_m=sigma_rows_m,
    )


def resimulate(obs, theta_rad, model, rng: np.random.Generator, runs: int):
    """``runs`` resimulations of run 0 of ``obs`` at θ = ``theta_rad`` (3,) under ``model``: an
    ``ObservationSet`` with ``runs`` runs (same images, targets, rows and noise block).

    On rows: the predicted points of the file's rows (``core.measurement.predict_rows``) and the
    pixel noise of those rows (``orbits.measurements.draw_errors``: the numbers drawn before the row
    model while the file's images × targets grid holds at most ``GRID_STREAM_MAX_FILL`` cells per
    row, one pair per row beyond), so memory and CPU are linear in the file's observations whatever
    its targets (single-use ground-control points included)."""
    from boresight.core.measurement import predict_rows
    from orbits.rotations import quat_from_dcm, star_tracker_error_dcm

    base = obs.run(0)
    theta = np.asarray(theta_rad, float).reshape(3)
    rows = (base.image_index, base.target_index)
    xy_true = predict_rows(base, theta, rows)[0]  # (K, 2)
    e = _noise_draws(model, rng, runs, base.pass_index, base.n_landmarks, theta, rows, base.sigma_xy_m)  # a row's own σ
    A_rep = star_tracker_error_dcm(e["delta_rad"]) @ base.attitude_st()[0][None]
    v = None if base.v_sc_i_m_s is None else np.broadcast_to(base.v_sc_i_m_s[0], (runs,) + base.v_sc_i_m_s.shape[1:]).copy()
    return replace(  # validated as the file was
        base,
        q_is=quat_from_dcm(A_rep),
        r_sc_i_m=base.r_sc_i_m[0][None] + e["gnss_error_m"],
        landmark_g_m=base.landmark_g_m[0][None] + e["catalogue_error_m"],
        xy_m=xy_true[None] + e["pixel_noise_m"],
        truth={"theta_rad": np.broadcast_to(theta, (runs, 3)).copy()},
        v_sc_i_m_s=v,
    )


def _fit(obs, algorithm, weighting, model, effects, loss):
    from boresight import estimate

    kw = {}
    if effects:
        kw["effects"] = ",".join(effects)
    if loss:
        kw["loss"] = loss
    return estimate(obs, algorithm=algorithm, weighting=weighting, model=model, iterate=True, **kw)


def file_study(
    obs,
    model,
    *,
    algorithm: str = "image_plane",
    weighting: str | None = None,
    effects=(),
    loss: str | None = None,
    runs: int = 1000,
    seed: int = 1,
    beta: float = 0.9973,
    progress=None,
    preflight=None,
    where: str = "the file",
    unknowns=None,
) -> FileStudy:
    """The study (module docstring). ``model``: the ``DisturbanceModel`` the file is estimated with
    (needed: the resimulation draws from it); ``weighting`` default ``"gls"``. ``progress(done,
    runs)`` after each block; ``preflight(dict)`` once the sizes are checked (as ``montecarlo.montecarlo_study``).
    Refused up front (``StudyError``/``MemoryBudgetError``): no noise model, no pixel noise, fewer
    than 2 runs, a working set over the memory budget. A set of pushbroom lines (``obs.line_scan``) goes to
    ``line_scan.line_scan_file_study`` (θ and ``unknowns``, a ``LineScanUnknowns``; ``algorithm``, ``weighting``,
    ``effects`` and ``loss`` do not apply: the line-scan GLS)."""
    from boresight.core.gls.structure import has_pixel_noise
    from boresight.errors import StudyError
    from boresight.studies.montecarlo.preflight import WEIGHTED_CHUNK_BYTES, weighted_bytes_per_run
    from boresight.studies.montecarlo.seeding import block_seed
    from orbits.limits import check_memory, memory_budget_bytes

    if isinstance(obs, (list, tuple)) or getattr(obs, "line_scan", None) is not None:  # pushbroom lines (or strips)
        from boresight.core.line_scan import LineScanUnknowns
        from boresight.studies.montecarlo.line_scan import line_scan_file_study

        return FileStudy(**line_scan_file_study(obs, model, unknowns or LineScanUnknowns(), runs, seed, where), beta=beta)
    if model is None:
        raise StudyError(
            f"{where}: a Monte Carlo on the file's geometry draws its errors from a noise model; the file has none: "
            "pass --sigma-pixel-m, --sigma-star-tracker-arcsec, --sigma-gnss-m (and --sigma-catalogue-m)"
        )
    if not has_pixel_noise(obs, model):
        raise StudyError(f"{where}: the noise model has no pixel noise (σK = 0): the refits would be exact; pass --sigma-pixel-m")
    if not (isinstance(runs, (int, np.integer)) and runs >= 2):
        raise StudyError(f"--runs must be an integer ≥ 2, got {runs!r}")
    weighting = weighting or "gls"
    effects = tuple(effects or ())
    t0 = time.perf_counter()
    base = obs.run(0)
    est = _fit(base, algorithm, weighting, model, effects, loss)
    # DECISION: the time model is fed by a second, timed fit: the first one in a process pays the
    # library's lazy imports (flight tutorial: 3.2 s first vs 0.05 s after, and the pre-flight line
    # said ~5 min for a 4 s study). One more fit is ≤ 1/50 of a study (a run's refit costs ≥ ¼ fit).
    t_fit = time.perf_counter()
    _fit(base, algorithm, weighting, model, effects, loss)
    t_fit = time.perf_counter() - t_fit
    theta_rad = est.theta.to_value("rad").reshape(3)
    rep_sigma = est.sigma.to_value("arcsec").reshape(3)
    per_run_bytes, _ = weighted_bytes_per_run(base, [algorithm], [base.n_images], weighting, model)
    block = min(BLOCK_RUNS, runs)
    # DECISION: 1.5× the measured one-step working set per run of a block, plus its draws and
    # resimulated set (the flight tutorial's file: 210 MB estimated for 100-run blocks, 96 MB traced).
    # The draws stay in blocks of BLOCK_RUNS (they fix the random numbers of each run); the refits of
    # a block go in sub-blocks of ``fit_runs`` small enough for the memory budget, so a large file is
    # studied in bounded memory instead of being refused. A sub-block is used only when a whole block
    # would not fit, so every study that fitted before gives the same numbers.
    # DECISION: a sub-block's refits hold at most WEIGHTED_CHUNK_BYTES (256 MiB) of the estimator's
    # working set, as a weighted scenario study's chunk does: a large file (the ×10 single-use
    # campaign: 42 MB per refit) is refitted a few runs at a time in bounded memory instead of filling
    # the budget (1.8 GB RSS for its 100 runs); a file whose whole block fits keeps its numbers.
    draws = 1.5 * block * base.n_observations * 400.0
    per_fit = 1.5 * per_run_bytes
    room = min(memory_budget_bytes() - draws, WEIGHTED_CHUNK_BYTES)
    fit_runs = int(min(block, max(1, room // per_fit))) if per_fit > 0 else block
    mem = draws + fit_runs * per_fit
    check_memory(
        f"{where}: the Monte Carlo (--runs {runs}, blocks of {block} runs refitted {fit_runs} at a time, "
        f"{base.n_observations} observations per run)",
        mem,
        hint="a file with fewer observations",
    )
    # time: a batched refit costs ¼ to 1 of the file's single fit per run (flight tutorial 0.13 s → 30 ms
    # per run; a 40-image campaign with two floated effects 0.6 s → 0.6 s): half of it, within 2×
    if preflight is not None:
        preflight(
            {
                "runs": int(runs),
                "cases": 1,
                "workers": 1,
                "memory_bytes": mem,
                "seconds": 0.5 + runs * t_fit / 2,
                "disk_bytes": 0.0,
            }
        )
    errs, var, nc = [], [], 0
    for b in range(-(-runs // BLOCK_RUNS)):
        n = min(BLOCK_RUNS, runs - b * BLOCK_RUNS)
        sim = resimulate(base, theta_rad, model, np.random.default_rng(block_seed(seed, b)), n)
        for s0 in range(0, n, fit_runs):
            k = min(fit_runs, n - s0)
            e = _fit(sim if k == n else sim.run(slice(s0, s0 + k)), algorithm, weighting, model, effects, loss)
            th = e.theta.to_value("arcsec").reshape(k, 3)
            if not np.all(np.isfinite(th)):
                r = int(np.argwhere(~np.isfinite(th))[0][0])
                raise StudyError(f"{where}: a non-finite refit in Monte Carlo run {b * BLOCK_RUNS + s0 + r}; no NaN is written")
            errs.append(th - theta_rad / ARCSEC)
            var.append(np.diagonal(e.covariance.to_value("arcsec2").reshape(k, 3, 3), axis1=-2, axis2=-1))
            nc += int(np.sum(~np.asarray(e.converged, bool).reshape(-1)))
        if progress is not None:
            progress(b * BLOCK_RUNS + n, runs)
    errors = np.concatenate(errs)
    return FileStudy(
        algorithm=str(est.algorithm),
        weighting=str(est.weighting),
        effects=effects,
        loss=loss,
        runs=int(runs),
        seed=int(seed),
        beta=float(beta),
        theta_arcsec=theta_rad / ARCSEC,
        reported_sigma_arcsec=rep_sigma,
        errors_arcsec=errors,
        mean_reported_sigma_arcsec=np.sqrt(np.concatenate(var).mean(axis=0)),
        unconverged=nc,
        elapsed_s=time.perf_counter() - t0,
    )
