"""Scenario → ObservationSet: the simulator's output in the estimator's data model."""

from __future__ import annotations

import numpy as np

import orbits
from boresight.observations.model import ObservationSet, from_measurements

__all__ = ["simulate", "scenario_noise", "nominal_observations", "star_frames_observations"]


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
    InputTypeError
        ``scenario`` is not a scenario, a path or a shipped scenario's name; ``rng`` is not a
        ``numpy.random.Generator``.

    Examples
    --------
    >>> import numpy as np
    >>> obs = simulate("scenarios/kiev2012-sensitivity.toml", np.random.default_rng(1), runs=4)
    >>> obs.xy_m.shape  # rows: 1 image × 4 landmarks
    (4, 4, 2)
    """
    if not isinstance(scenario, orbits.Scenario):
        scenario = orbits.load_scenario(scenario)
    if not scenario.star_frames:
        return from_measurements(
            orbits.simulate_passes(scenario, rng, runs=runs, arrays=arrays), noise=scenario_noise(scenario), detector_edge=True
        )
    stars = star_frames_observations(scenario, rng, runs) if not scenario.passes else None
    if stars is not None:
        return stars
    from dataclasses import replace

    from boresight.observations.stars import join_observations

    passes_only = replace(scenario, star_frames=(), stars=None)  # orbits.simulate_passes: the landmark passes
    landmarks = from_measurements(
        orbits.simulate_passes(passes_only, rng, runs=runs, arrays=arrays), noise=scenario_noise(scenario), detector_edge=True
    )
    return join_observations(landmarks, star_frames_observations(scenario, rng, runs))


def star_frames_observations(scenario, rng: np.random.Generator, runs: int = 1, catalogue=None) -> ObservationSet:
    """The scenario's ``[[star_frames]]`` as star rows (``orbits.star_campaign.simulate_star_rows``,
    ``boresight.observations.stars.star_observations``), with the scenario's noise model.
    ``boresight.simulate`` joins them after the landmark passes (one image table, one GLS)."""
    from boresight.observations.stars import star_observations
    from orbits.star_campaign import simulate_star_rows

    sim = simulate_star_rows(scenario, rng, runs, catalogue=catalogue)
    cam = scenario.camera
    calibration = getattr(cam, "calibration", None)
    # the field check only when every point is on the detector (a θ drawn per run can push one off:
    # then no fov_deg, as from_measurements does for the Monte Carlo's idealised sets)
    from boresight.observations.model import FIELD_MARGIN, field_half_width_m

    fov = (
        cam.fov_deg if np.all(np.abs(sim["xy_m"]) <= FIELD_MARGIN * field_half_width_m(cam.focal_length_m, cam.fov_deg)) else None
    )
    return star_observations(
        **sim,  # the catalogue, the rows, the image table and the truth: simulate_star_rows returns star_observations' arguments
        focal_length_m=cam.focal_length_m,
        epoch_utc=scenario.epoch_utc,
        C_SK_nominal=scenario.C_ES.T,
        fov_deg=fov,
        pixel_pitch_m=cam.pixel_pitch_m,
        noise=scenario_noise(scenario),
        camera=calibration() if callable(calibration) else calibration,
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
