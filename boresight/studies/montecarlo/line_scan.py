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
from boresight.observations.strip import strip_noise_model, strip_observations, strip_unknowns

__all__ = ["LineScanMonteCarlo", "line_scan_montecarlo", "truth_vector", "parameters_truth"]


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
    def within_3_sigma(self) -> np.ndarray:
        """(n,) the fraction of runs whose error is within 3 reported σ (99.73 % for an honest Gaussian σ)."""
        out: np.ndarray = np.mean(np.abs(self.errors) <= 3 * self.sigmas, axis=0)
        return out


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


def line_scan_montecarlo(sc: Any, runs: int, seed: int) -> LineScanMonteCarlo:
    """``runs`` draws of the pushbroom scenario ``sc`` (``orbits.strip.StripScenario``), each fitted with the
    scenario's noise model and ``[estimate]`` unknowns (module docstring)."""
    from orbits.strip import simulate_campaign, simulate_strip

    if runs < 2:
        raise ValueError(f"line_scan_montecarlo: need at least 2 runs for a scatter, got {runs}")
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
