"""Scenario → ObservationSet: the simulator's output in the estimator's data model."""

from __future__ import annotations

import numpy as np

import orbits
from boresight.observations.model import ObservationSet, from_measurements

__all__ = ["simulate", "scenario_noise", "nominal_observations"]


def simulate(scenario, rng: np.random.Generator, runs: int = 1, arrays: dict | None = None) -> ObservationSet:
    """Simulate ``runs`` noisy observation sets of a scenario (images of ground landmarks).

    Parameters
    ----------
    scenario : orbits.Scenario or str or path
        The scenario, or its TOML file (a path, or a shipped scenario's file).
    rng : numpy.random.Generator
        The source of every random draw (the same generator state gives the same observations).
    runs : int
        Independent repetitions of the whole campaign (the leading axis R of the arrays).
    arrays : dict, optional
        ``orbits.campaign_arrays(scenario)``, precomputed: lets a Monte Carlo loop skip the geometry.

    Returns
    -------
    ObservationSet
        One row per observation — measured focal-plane points ``xy_m`` (R, K, 2) m —, the star-tracker
        attitudes, GNSS positions and the scenario's noise model (the file format's ``noise`` block),
        and the true θ in ``truth``.

    Raises
    ------
    ScenarioError
        The TOML file is missing or invalid (a ``BoresightError``, naming the file and key).

    Examples
    --------
    >>> import numpy as np
    >>> obs = simulate("scenarios/kiev2012-sensitivity.toml", np.random.default_rng(1), runs=4)
    >>> obs.xy_m.shape  # rows: 1 image × 4 landmarks
    (4, 4, 2)
    """
    if not isinstance(scenario, orbits.Scenario):
        scenario = orbits.load_scenario(scenario)
    return from_measurements(
        orbits.simulate(scenario, rng, runs=runs, arrays=arrays), noise=scenario_noise(scenario), detector_edge=True
    )


def scenario_noise(scenario) -> dict:
    """The scenario's sensor noise as the observation file's ``noise`` mapping (same tables and keys)."""
    return {
        "pixel": {"sigma_m": float(scenario.sigma_pixel_m)},
        "star_tracker": {
            "sigma_arcsec": [float(v) for v in scenario.sigma_star_tracker_arcsec],
            "error_mode": scenario.star_tracker_error_mode,
        },
        "gnss": {"sigma_m": float(scenario.sigma_gnss_m), "error_mode": scenario.gnss_error_mode},
        "catalogue": {"sigma_m": float(scenario.sigma_catalogue_m)},
    }


def nominal_observations(scenario, arrays: dict | None = None) -> ObservationSet:
    """The scenario's noise-free ``ObservationSet`` (1 run, θ = 0, every drawn error zero).

    The geometry at which linear propagation (``boresight.studies.sensitivity``), the Monte Carlo
    Kalman kernel's R_n and a planner's Fisher information are evaluated. ``arrays``:
    ``orbits.campaign_arrays(scenario)`` if already computed.

    >>> obs = nominal_observations(orbits.load_scenario("scenarios/kiev2012-sensitivity.toml"))
    >>> obs.runs, bool(abs(obs.truth["theta_rad"]).max() == 0)
    (1, True)
    """
    arrays = arrays or orbits.campaign_arrays(scenario)
    n = arrays["t_s"].size
    m = arrays["landmarks_g_m"].shape[0]
    k = arrays["rows"][0].size
    zeros = {
        "theta_rad": np.zeros((1, 3)),
        "delta_rad": np.zeros((1, n, 3)),
        "gnss_error_m": np.zeros((1, n, 3)),
        "catalogue_error_m": np.zeros((1, m, 3)),
        "pixel_noise_m": np.zeros((1, k, 2)),
    }
    return from_measurements(orbits.observe(zeros, **arrays))
