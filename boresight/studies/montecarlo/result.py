"""The result of a Monte Carlo study: streamed moments per algorithm and its table."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from boresight.studies.montecarlo.chunks import REPORTED_VARIANCE
from boresight.studies.montecarlo.sample_size import achieved_epsilon, sigma_interval


@dataclass
class MonteCarloResult:
    """What ``boresight.montecarlo_study`` returns: streamed statistics of θ̂ − θ per algorithm.

    ``sigma(algorithm)`` gives σθ (len(image_counts), 3) as a Quantity in arcsec (``sigma_arcsec`` as floats); ``table(beta)`` the whole
    summary as an astropy ``Table`` with units and χ² intervals.

    Attributes
    ----------
    scenario_name : str
        The scenario's name.
    algorithms, image_counts : tuple
        The algorithms run, and the numbers of images (the first k of the scenario's) estimated with.
    runs, seed, block_runs, chunk_runs : int
        The study's size and identity (the numbers depend on ``seed``, ``runs`` and ``block_runs`` only).
    moments : dict
        Per algorithm, a ``Moments`` of θ̂ − θ (arcsec) over the runs, shapes (len(image_counts), 3).
    samples : dict
        Per algorithm, the errors of the first ``keep_runs`` runs (K, len(image_counts), 3) arcsec.
    unconverged : dict
        Per algorithm, (len(image_counts),) the number of runs whose Gauss-Newton did not converge.
    weighting : str
        The least-squares weighting: ``"unit"``, ``"diagonal"`` or ``"gls"``.
    predicted : dict
        Per least-squares algorithm, (len(image_counts), 3) arcsec: the σ the estimator predicts.
    notes : tuple
        What the study changed or skipped, and why.
    inputs : dict
        The study's inputs as its checkpoint and JSON record them (scenario source, seed, runs, chunk and
        block sizes, algorithms, image counts, iterations, engine, variants, notes; ``weighting`` unless unit).
    elapsed_s : float
        Wall-clock seconds of the study.
    beta : float
        The confidence level of the intervals ``table()`` gives when given none (the study's ``beta``).
    resumed_blocks : int
        Blocks of runs loaded from a checkpoint (``resume``), 0 for a fresh study.
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
        """σθ, the sample σ of θ̂ − θ over the runs, (len(image_counts), 3) in arcsec (plain floats)."""
        return self.moments[algorithm].std

    def sigma(self, algorithm: str):
        """σθ as an astropy ``Quantity`` in arcsec, (len(image_counts), 3): the unit style of
        ``Estimate.theta``/``Estimate.sigma`` (``sigma_arcsec`` gives the same numbers as floats)."""
        from astropy import units as u

        return self.sigma_arcsec(algorithm) * u.arcsec

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
                rows.append(
                    (
                        name,
                        k,
                        mo.count,
                        *mo.mean[j],
                        *sd[j],
                        *lo[j],
                        *hi[j],
                        *mo.max_abs[j],
                        float(np.sqrt((sd[j] ** 2).sum())),
                        int(nc[j]),
                    )
                    + more
                )
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
