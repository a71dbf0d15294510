"""A Monte Carlo of a pushbroom scenario: its strips drawn ``runs`` times and fitted by
``boresight.core.line_scan.estimate_line_scan`` (the GLS on rows with the tracker's errors on the attitude-sample
table), the reported σ compared with the scatter of the estimates about the truth.

Run k draws from ``numpy.random.default_rng([seed, k])`` (one strip: ``orbits.strip.simulate_strip`` with it; a
campaign: ``simulate_campaign``, strip j from its j-th spawned generator), so a run does not depend on how many
come before it and ``tests/studies/test_pushbroom_mc.py``'s runs are this function's at its seed. A plain loop over
runs in one process (a fit costs ~0.03 s of CPU): the chunked, checkpointed engine of ``montecarlo`` is for the
frame camera's batched kernels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.core.line_scan import estimate_line_scan
from boresight.errors import InputValueError
from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns
from orbits.rotations import ARCSEC as _ARCSEC

__all__ = [
    "LineScanMonteCarlo",
    "line_scan_montecarlo",
    "truth_vector",
    "parameters_truth",
    "strip_file_truth",
    "errors_in_sigma",
    "true_lines",
    "resimulate_lines",
    "line_scan_file_study",
]


@dataclass
class LineScanMonteCarlo:
    """``names`` of the unknowns, ``errors`` (runs, n) estimate − truth and ``sigmas`` (runs, n) the reported σ (SI)."""

    names: list[str]
    errors: np.ndarray
    sigmas: np.ndarray

    @property
    def scatter(self) -> np.ndarray:
        """(n,) the sample standard deviation of the errors."""
        out: np.ndarray = self.errors.std(axis=0, ddof=1)
        return out

    @property
    def sigma_over_scatter(self) -> np.ndarray:
        """(n,) the mean reported σ over the scatter (1 for an honest σ)."""
        out: np.ndarray = self.sigmas.mean(axis=0) / self.scatter
        return out

    @property
    def runs(self) -> int:
        """The number of runs."""
        return int(self.errors.shape[0])

    @property
    def count_within_3_sigma(self) -> np.ndarray:
        """(n,) int: the runs whose error is within 3 reported σ."""
        out: np.ndarray = np.sum(np.abs(self.errors) <= 3 * self.sigmas, axis=0)
        return out

    @property
    def within_3_sigma(self) -> np.ndarray:
        """(n,) the fraction of runs whose error is within 3 reported σ (99.73 % for an honest Gaussian σ):
        ``count_within_3_sigma / runs``."""
        out: np.ndarray = self.count_within_3_sigma / self.runs
        return out

    def within_3_sigma_interval(self, level: float = 0.95) -> np.ndarray:
        """(n, 2): the Clopper–Pearson ``level`` interval of each unknown's rate within 3σ
        (``boresight.stats.binomial_interval`` of ``count_within_3_sigma`` in ``runs``)."""
        from boresight.stats import binomial_interval

        return np.array([binomial_interval(int(k), self.runs, level) for k in self.count_within_3_sigma])


def truth_vector(sc: Any, names: list[str]) -> np.ndarray:
    """The true value of each unknown ``names`` (``LineScanUnknowns.names``) in a scenario."""
    return parameters_truth(sc.truth(), names)


def parameters_truth(truth: Any, names: list[str]) -> np.ndarray:
    """The value of each unknown ``names`` (``LineScanUnknowns.names``) in ``truth`` (``LineScanParameters``); NaN for
    a jitter term (its sinusoid's parts are not the scenario's amplitude and phase)."""
    off = truth.chip_offsets_rad
    out = []
    for nm in names:
        if nm.startswith("theta_"):
            out.append(truth.theta_rad["xyz".index(nm[6])])
        elif nm in ("line_time_offset_s", "line_period_error", "focal_scale"):
            out.append(getattr(truth, nm))
        elif nm.startswith("chip"):
            c, axis = int(nm[4 : nm.index("_")]), 0 if "_along_" in nm else 1
            out.append(0.0 if off is None else off[c, axis])
        else:
            out.append(np.nan)
    return np.array(out)


def strip_file_truth(sf: Any, names: list[str]) -> np.ndarray:
    """The true value of each unknown ``names`` in a pushbroom observation file (``observations.strip_file.StripFile``)
    that ``boresight simulate`` wrote (its meta ``theta_arcsec`` and ``effects``); all NaN for a file without them
    (flight data)."""
    if "theta_arcsec" not in sf.meta:
        return np.full(len(names), np.nan)
    from orbits.effects import line_scan_truth

    truth = line_scan_truth(
        np.radians(np.asarray(sf.meta["theta_arcsec"], float) / 3600.0),
        sf.meta.get("effects") or {},
        sf.obs.line_scan.sensor.n_chips,
        f"{sf.path}: meta 'effects'",
    )
    return parameters_truth(truth, names)


def errors_in_sigma(x: Any, sigma: Any, truth: Any) -> np.ndarray:
    """(n,) each unknown's error against its truth in units of its reported σ, (x − truth) / σ (``x``, ``sigma``,
    ``truth`` (n,) SI as ``truth_vector`` / ``strip_file_truth`` give it); NaN where the truth is unknown (a jitter
    term, a flight file) or σ is 0."""
    x, sigma, truth = (np.asarray(v, float) for v in (x, sigma, truth))
    with np.errstate(divide="ignore", invalid="ignore"):
        out: np.ndarray = np.where(np.isfinite(truth) & (sigma > 0), (x - truth) / sigma, np.nan)
    return out


def line_scan_montecarlo(sc: Any, runs: int, seed: int) -> LineScanMonteCarlo:
    """``runs`` draws of the pushbroom scenario ``sc`` (``orbits.strip.StripScenario``), each fitted with the
    scenario's noise model and ``[estimate]`` unknowns (module docstring)."""
    from orbits.strip import simulate_campaign, simulate_strip

    if runs < 2:
        raise InputValueError(f"line_scan_montecarlo: need at least 2 runs for a scatter, got {runs}")
    model, unknowns, truth = strip_noise_model(sc), strip_unknowns(sc), sc.truth()
    geos = sc.geometries()
    x_true = truth_vector(sc, unknowns.names)
    n = len(unknowns.names)
    err, sig = np.empty((runs, n)), np.empty((runs, n))
    for k in range(runs):
        rng = np.random.default_rng([seed, k])
        if len(geos) == 1:
            sims = [simulate_strip(geos[0], truth, rng, sc.layout, sc.tracker, sc.sigma_pixel_px)]
        else:
            sims = list(simulate_campaign(geos, [truth] * len(geos), rng, sc.layout, sc.tracker, sc.sigma_pixel_px))
        fit = estimate_line_scan([strip_observations(s) for s in sims], unknowns, model)
        err[k], sig[k] = fit.x - x_true, fit.sigma
    return LineScanMonteCarlo(unknowns.names, err, sig)


# ---------------------------------------------------------------------------- a study on a pushbroom file's own strip


def true_lines(obs: Any, params: Any) -> tuple[np.ndarray, np.ndarray]:
    """(line, pixel) (K,) of each row's ground-control point on the row's own chip under ``params``
    (``LineScanParameters``), the trajectory of ``obs`` taken as the truth (``orbits.pushbroom.locate_on_chips``: the
    forward model the simulator detects with); a row whose point that chip does not see under ``params`` keeps its
    measured (line, pixel)."""
    from orbits.pushbroom import SightCorrections, locate_on_chips

    ls = obs.line_scan
    img = np.asarray(obs.image_index)
    L_meas, p_meas = np.asarray(ls.line, float)[img], np.asarray(ls.pixel, float)[img]
    L, p = locate_on_chips(
        ls.sensor,
        ls.datation,
        ls.trajectory,
        obs.landmark_g_m[0, obs.target_index],
        np.asarray(ls.chip)[img],
        params,
        start_line=float(np.median(L_meas)),
        corrections=SightCorrections(ls.light_time, ls.aberration),
    )
    ok = np.isfinite(L) & np.isfinite(p)
    return np.where(ok, L, L_meas), np.where(ok, p, p_meas)


def resimulate_lines(obs: Any, line: np.ndarray, pixel: np.ndarray, model: Any, rng: np.random.Generator) -> Any:
    """One resimulation of a strip's rows about a truth: the star tracker's samples turned by the model's errors per
    sample, white and Gauss–Markov (``orbits.strip.TrackerNoise``, ``measured_trajectory``), the rows' true ``line``, ``pixel``
    (K,) plus the model's pixel noise on each (draws in the simulator's order: tracker, then pixels); the lines built
    as the simulator and the reader build them (``orbits.strip.line_records``)."""
    from boresight.observations.model import ObservationSet
    from orbits.strip import TrackerNoise, line_records, measured_trajectory

    ls = obs.line_scan
    tr = ls.trajectory
    sigma_px = model.sigma_pixel_m / ls.sensor.pixel_pitch_m
    tracker = TrackerNoise(
        float(model.sigma_star_tracker_rad[0] / _ARCSEC),
        float(model.sigma_star_tracker_correlated_rad[0] / _ARCSEC),
        model.star_tracker_correlation_time_s,
    )
    delta = tracker.draw_rad(rng, tr.tracker_t_s)
    noise = rng.standard_normal((line.size, 2)) * sigma_px
    img = np.asarray(obs.image_index)
    rec = line_records(
        ls.sensor,
        ls.datation,
        measured_trajectory(tr, delta),
        line + noise[:, 0],
        np.asarray(ls.chip)[img],
        pixel + noise[:, 1],
        obs.target_index,
        obs.landmark_ids,
        obs.landmark_g_m[0],
        obs.epoch_utc,
        light_time=ls.light_time,
        aberration=ls.aberration,
    )
    return ObservationSet(**rec, noise=obs.noise)


def line_scan_file_study(obs: Any, model: Any, unknowns: Any, runs: int, seed: int, where: str = "the file") -> dict[str, Any]:
    """``montecarlo FILE`` on a pushbroom file (``boresight.studies.montecarlo.file_study``'s line-scan branch, which
    makes the ``FileStudy`` of these fields): the file's lines (``obs``; or a list of strips, a campaign) fitted
    (``estimate_line_scan``: θ and ``unknowns``, the noise model ``model``), then ``runs`` resimulations about that fit
    (``true_lines`` at the fitted parameters, the files' trajectories as the truth, ``resimulate_lines``; run k from
    ``default_rng([seed, k])``, of strip j of a campaign from ``default_rng([seed, j, k])``) each refitted the same way.
    θ's fields in arcseconds; ``extra`` every unknown's names, errors (runs, n), σ (runs, n), SI."""
    import time

    from boresight.errors import StudyError

    if model is None or not model.sigma_pixel_m > 0:
        raise StudyError(
            f"{where}: a Monte Carlo on a pushbroom file draws pixel noise: give --sigma-pixel-px (or a file with it)"
        )
    if not (isinstance(runs, (int, np.integer)) and runs >= 2):
        raise StudyError(f"--runs must be an integer ≥ 2, got {runs!r}")
    t0 = time.perf_counter()
    strips = list(obs) if isinstance(obs, (list, tuple)) else [obs]
    base = estimate_line_scan(strips, unknowns, model)
    params = unknowns.parameters(base.x, strips[0].line_scan.sensor.n_chips)
    truth = [true_lines(o, params) for o in strips]
    n = len(unknowns.names)
    err, var = np.empty((runs, n)), np.empty((runs, n))
    unconverged = 0
    for k in range(runs):
        sims = [
            resimulate_lines(o, L, p, model, np.random.default_rng([seed, k] if len(strips) == 1 else [seed, j, k]))
            for j, (o, (L, p)) in enumerate(zip(strips, truth))
        ]
        fit = estimate_line_scan(sims, unknowns, model)
        err[k], var[k] = fit.x - base.x, fit.sigma**2
        unconverged += int(not fit.converged)
    return dict(
        algorithm="line_scan",
        weighting="gls",
        effects=tuple(unknowns.names[3:]),
        loss=None,
        runs=runs,
        seed=seed,
        theta_arcsec=base.theta_arcsec,
        reported_sigma_arcsec=base.sigma[:3] / _ARCSEC,
        errors_arcsec=err[:, :3] / _ARCSEC,
        mean_reported_sigma_arcsec=np.sqrt(var[:, :3].mean(axis=0)) / _ARCSEC,
        unconverged=unconverged,
        elapsed_s=time.perf_counter() - t0,
        extra=dict(names=unknowns.names, errors=err, sigma=np.sqrt(var), x=base.x, reported_sigma=base.sigma),
    )
