"""The Kiev 2012 eq 32 table (Kalman variant), ours: σθ and max |θ error| versus the number of images.

Runs the library's filter (``boresight.core.algorithms.kalman.kalman_filter``) over the seminar's
eq 32 scenario (``kiev2012.scenarios.kalman_scenario``); the seminar's own numbers are
``kiev2012.published.seminar_kalman_table``.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

import boresight
from boresight.core.algorithms.kalman import kalman_filter
from boresight.core.disturbances import DisturbanceModel
from boresight.errors import InputValueError
from boresight.reproductions.kiev2012.published import SEMINAR_IMAGE_COUNTS
from boresight.reproductions.kiev2012.scenarios import kalman_scenario
from orbits.rotations import ARCSEC

__all__ = ["kalman_table"]


def kalman_table(
    scenario=None,
    *,
    runs: int = 2000,
    seed: int = 2012,
    n_images=SEMINAR_IMAGE_COUNTS,
    sigma0_arcsec: float | None = None,
    model: DisturbanceModel | None = None,
    chunk_runs: int = 5000,
    **options,
):
    """The Kiev 2012 eq 32 table: σθ and max|θ| error (arcsec) vs number of images, as an astropy Table.

    ``scenario``: an ``orbits.Scenario`` or TOML path (default ``kalman_scenario()``); its true θ
    must be random (``misalignment.sigma0_arcsec``) — the filter prior σ is ``sigma0_arcsec``
    (default: the scenario's). ``model``: the filter's disturbance model (default: the
    scenario's). The filter runs over the scenario's images in order; the row for n images is its
    estimate after the first n. Runs are simulated in chunks of ``chunk_runs`` from one
    ``SeedSequence(seed)`` generator (the numbers depend on seed, runs and chunk_runs).
    ``options`` go to ``kalman_filter``.

    Columns: ``n_images``; ``sigma_theta_{x,y,z}`` (sample standard deviation of the error,
    ddof = 1); ``max_abs_theta_{x,y,z}``; ``filter_sigma_theta_{x,y,z}`` (RMS of the filter's
    own σ); ``nees_mean`` with its 99 % χ² bounds ``nees_lo``, ``nees_hi``; ``rejected_fraction``.

    >>> t = kalman_table(runs=200, seed=1, n_images=(1, 20))
    >>> [int(n) for n in t["n_images"]], t["sigma_theta_x"].unit.to_string()
    ([1, 20], 'arcsec')
    """
    from astropy import units as u
    from astropy.table import Table

    import orbits

    if scenario is None:
        scenario = kalman_scenario(10.0 if sigma0_arcsec is None else sigma0_arcsec)
    elif not isinstance(scenario, orbits.Scenario):
        scenario = orbits.load_scenario(scenario)
    if scenario.theta_true_arcsec is not None or scenario.theta_sigma0_arcsec <= 0:
        raise InputValueError(
            f"scenario.theta_sigma0_arcsec must be > 0 with no fixed true_arcsec for a Kalman table, got "
            f"sigma0={scenario.theta_sigma0_arcsec!r}, true={scenario.theta_true_arcsec!r}"
        )
    if sigma0_arcsec is None:
        sigma0_arcsec = scenario.theta_sigma0_arcsec
    if not (isinstance(runs, (int, np.integer)) and runs >= 2):
        raise InputValueError(f"runs must be an integer ≥ 2, got {runs!r}")
    if not (isinstance(chunk_runs, (int, np.integer)) and chunk_runs >= 1):
        raise InputValueError(f"chunk_runs must be an integer ≥ 1, got {chunk_runs!r}")
    n_total = sum(len(p.t_s) for p in scenario.passes)
    n_images = tuple(int(k) for k in n_images)
    if not n_images or min(n_images) < 1 or max(n_images) > n_total:
        raise InputValueError(f"n_images must lie in 1..{n_total} (the scenario's images), got {n_images!r}")
    model = DisturbanceModel.from_scenario(scenario) if model is None else model
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    idx = np.asarray(n_images) - 1
    errs, var, nee, rej = [], [], [], []
    for start in range(0, runs, chunk_runs):
        obs = boresight.simulate(scenario, rng, runs=min(chunk_runs, runs - start))
        res = kalman_filter(obs, model, sigma0_rad=sigma0_arcsec * ARCSEC, **options)
        truth = obs.truth["theta_rad"]
        errs.append((res.theta_history_rad[:, idx] - truth[:, None]) / ARCSEC)
        var.append(np.diagonal(res.P_history[:, idx, :3, :3], axis1=-2, axis2=-1) / ARCSEC**2)
        nee.append(res.nees(truth)[:, idx])
        rej.append(np.cumsum(res.rejected, axis=1)[:, idx] / (idx + 1))
    e, v, k, j = (np.concatenate(a) for a in (errs, var, nee, rej))
    K = e.shape[0]
    t = Table()
    t["n_images"] = np.asarray(n_images)
    for i, ax in enumerate("xyz"):
        t[f"sigma_theta_{ax}"] = e[..., i].std(axis=0, ddof=1) * u.arcsec
    for i, ax in enumerate("xyz"):
        t[f"max_abs_theta_{ax}"] = np.abs(e[..., i]).max(axis=0) * u.arcsec
    for i, ax in enumerate("xyz"):
        t[f"filter_sigma_theta_{ax}"] = np.sqrt(v[..., i].mean(axis=0)) * u.arcsec
    t["nees_mean"] = k.mean(axis=0)
    t["nees_lo"] = np.full(len(n_images), chi2.ppf(0.005, 3 * K) / K)
    t["nees_hi"] = np.full(len(n_images), chi2.ppf(0.995, 3 * K) / K)
    t["rejected_fraction"] = j.mean(axis=0)
    t.meta.update(
        reference="Kiev 2012 eq 32 (Kalman variant) table",
        scenario=scenario.name,
        runs=int(K),
        seed=int(seed),
        chunk_runs=int(chunk_runs),
        sigma0_arcsec=float(sigma0_arcsec),
        filter_options={key: (list(val) if isinstance(val, tuple) else val) for key, val in options.items()},
    )
    return t
