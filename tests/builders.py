"""Small scenarios and observation sets the tests share, built once here (issue 18: shared
fixtures, not a dozen local builders). Imported by name (``from builders import campaign_6pass_doc``);
``tests/conftest.py`` wraps the common ones as fixtures.

* ``wgs84_kalman20()``: the shipped ``kiev2012-kalman20`` scenario on the WGS-84 Earth (real
  Earth rotation: ITRS and GCRS differ by the sidereal angle; what flight files need);
* ``campaign_6pass_doc(n_pass, n_img)``: the first passes of ``campaign-6pass`` with fewer
  images, as a scenario dict; ``simulate_with_model(sc, seed, runs)`` a scenario's observations
  and noise model;
* ``scenario_with(path, noise_free=..., **tables)``: a shipped scenario with some tables
  overridden (``zero_noise`` / ``with_tables`` on its dict);
* ``small_campaign(...)`` and ``discrepancy_campaign(effects, ...)``: the discrepancy tests'
  campaigns (engine, catalogue and naming tests);
* ``synthetic_sky(rng, n)``: a star catalogue uniform on the sphere (the star tests' sky when
  the optional Hipparcos package is not needed);
* ``campaign_as_flown``, ``single_use``, ``tile`` (observation sets): campaigns at real sizes (issue 27;
  the simulator's inputs tiled: ``tiled_simulation.py``);
* ``shared_strip`` (a big shared-target campaign on rows) and ``traced_peak(fn)`` the peak traced allocation of a call (the "no images × targets
  array" tests).
"""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
from paths import ROOT, SCENARIOS

import boresight
import orbits
from boresight.core.disturbances import DisturbanceModel


def wgs84_kalman20() -> orbits.Scenario:
    d = tomllib.loads((SCENARIOS / "kiev2012-kalman20.toml").read_text())
    d["earth_model"] = "wgs84"
    return orbits.scenario_from_dict(d)


def campaign_6pass_doc(n_pass: int = 3, n_img: int = 4) -> dict:
    """The ``campaign-6pass`` scenario as a dict, cut to its first ``n_pass`` passes of ``n_img``
    images each (same start and step)."""
    d = tomllib.loads((SCENARIOS / "campaign-6pass.toml").read_text())
    d["passes"] = d["passes"][:n_pass]
    for p in d["passes"]:
        t = p["t_s"]
        p["t_s"] = {"start": t["start"], "stop": t["start"] + (n_img - 1) * t["step"], "step": t["step"]}
    return d


def zero_noise(d: dict) -> dict:
    """Scenario dict ``d`` with every sensor σ set to 0 (star tracker, GNSS, pixel, catalogue), in place."""
    for t in ("star_tracker", "gnss", "pixel", "catalogue"):
        d.setdefault(t, {})["sigma_arcsec" if t == "star_tracker" else "sigma_m"] = (
            [0.0, 0.0, 0.0] if t == "star_tracker" else 0.0
        )
    return d


def with_tables(d: dict, **tables: dict) -> dict:
    """Scenario dict ``d`` with ``tables`` merged into its own, in place. [misalignment] takes
    true_arcsec or sigma0_arcsec, not both: a given misalignment table replaces it."""
    for k, v in tables.items():
        d[k] = dict(v) if k == "misalignment" else {**d.get(k, {}), **v}
    return d


def scenario_with(path: str, noise_free: bool = False, **tables: dict) -> orbits.Scenario:
    """The scenario file ``path`` (repository-relative) with ``tables`` merged in, noise-free on request."""
    d = tomllib.loads((ROOT / path).read_text())
    return orbits.scenario_from_dict(with_tables(zero_noise(d) if noise_free else d, **tables))


def simulate_with_model(sc: orbits.Scenario, seed: int = 0, runs: int = 1) -> tuple[boresight.ObservationSet, DisturbanceModel]:
    """``runs`` simulated runs of ``sc`` (``default_rng(seed)``) and the scenario's noise model."""
    return boresight.simulate(sc, np.random.default_rng(seed), runs=runs), DisturbanceModel.from_scenario(sc)


def _small_pass(lat, lon, direction, law, k):
    """One pass of the small spherical campaigns: nadir (10 images, 24 landmarks) or site tracking
    (10 images over 90 s, 10 landmarks); the landmark field's seed is 10 + k."""
    if law == "nadir":
        t_s, n, half = {"start": -4.5, "stop": 4.5, "step": 1.0}, 24, 18.0
    else:
        t_s, n, half = {"start": -45.0, "stop": 45.0, "step": 10.0}, 10, 15.0
    return dict(
        site_lat_deg=lat,
        site_lon_deg=lon,
        direction=direction,
        attitude="nadir" if law == "nadir" else "site_tracking",
        t_s=t_s,
        landmarks=dict(layout="random", n=n, half_width_km=half, height_sigma_m=300.0, seed=10 + k, placement="sphere"),
    )


#: sites of the small campaigns' passes (latitude, longitude, direction): ``small_campaign`` flies the
#: first four, ``drift_campaign`` one a day
SMALL_CAMPAIGN_SITES = [
    (44.45, 9.1, "ascending"),
    (-33.9, 18.4, "descending"),
    (0.5, 32.6, "ascending"),
    (64.1, -21.9, "ascending"),
    (20.0, -60.0, "descending"),
    (-10.0, 120.0, "ascending"),
    (50.0, 80.0, "descending"),
    (-45.0, -70.0, "ascending"),
]


def _small_campaign_doc(name: str, laws, sigma_star_tracker_arcsec: float, st_mode: str, sigma_gnss_m: float, gnss_mode: str):
    """The small campaigns' scenario dict: pass k (attitude law ``laws[k]``) over ``SMALL_CAMPAIGN_SITES[k]``,
    a spherical Earth, 680 km at 98°, the 2.2 m / 3.4° camera, the star tracker mounted at (59, 19, 132.2)°
    with the given σ and error mode, the given GNSS σ and mode, 3 µm pixels, a 0.1 m catalogue and
    θ = (20, −15, 40)″."""
    return {
        "name": name,
        "earth_model": "spherical",
        "orbit": {"altitude_km": 680.0, "inclination_deg": 98.0},
        "camera": {"focal_length_m": 2.2, "fov_deg": 3.4},
        "star_tracker": {
            "mount_deg": [59.0, 19.0, 132.2],
            "sigma_arcsec": [sigma_star_tracker_arcsec] * 3,
            "error_mode": st_mode,
        },
        "gnss": {"sigma_m": sigma_gnss_m, "error_mode": gnss_mode},
        "pixel": {"sigma_m": 3e-6},
        "catalogue": {"sigma_m": 0.1},
        "misalignment": {"true_arcsec": [20.0, -15.0, 40.0]},
        "passes": [_small_pass(*SMALL_CAMPAIGN_SITES[k], law, k) for k, law in enumerate(laws)],
    }


def small_campaign(
    st_mode: str = "per_image",
    gnss_mode: str = "per_image",
    passes: tuple[str, ...] = ("site_tracking", "site_tracking", "nadir"),
) -> orbits.Scenario:
    """The discrepancy tests' campaign: one pass per attitude law in ``passes`` over four fixed sites
    (site-tracking: 10 images, 10 random landmarks; nadir: 10 images, 24), Kiev noise with the
    given star-tracker and GNSS error modes, θ = (20, −15, 40)″."""
    return orbits.scenario_from_dict(_small_campaign_doc("small", passes, 4.0, st_mode, 15.0, gnss_mode))


def discrepancy_campaign(
    effects: dict | None = None, unmodelled: tuple | None = None, low_star_tracker_noise: bool = False
) -> orbits.Scenario:
    """4 passes (3 site-tracking, 1 nadir), 40 images, ~440 observations, Kiev noise per image."""
    sc = small_campaign(passes=("site_tracking", "site_tracking", "nadir", "site_tracking"))
    if low_star_tracker_noise:
        # aberration is a rotation that changes slowly along a pass: it separates from θ only
        # with site-tracking passes at different yaws and a 1″ star tracker (docs/discrepancy.md)
        sc = dataclasses.replace(
            sc,
            sigma_star_tracker_arcsec=(1.0, 1.0, 1.0),
            passes=tuple(
                dataclasses.replace(p, t_s=tuple(np.arange(-90.0, 91.0, 10.0)), yaw_deg=40.0 * k)
                if p.attitude == "site_tracking"
                else p
                for k, p in enumerate(sc.passes)
            ),
        )
    kw = {}
    if effects:
        kw["effects"] = orbits.effects.effect_sizes(effects)
    if unmodelled:
        kw["unmodelled"] = unmodelled
    return dataclasses.replace(sc, **kw)


def synthetic_sky(rng: np.random.Generator, n: int = 60000, parallax_mas: tuple = (0.5, 50.0), pm_sigma_mas_yr: float = 50.0):
    """The star tests' sky: ``orbits.star_catalogue.synthetic_catalogue`` (n stars uniform on the sphere,
    Hp uniform in [1, 8.5], HIP ids 1..n)."""
    from orbits.star_catalogue import synthetic_catalogue

    return synthetic_catalogue(rng, n, parallax_mas, pm_sigma_mas_yr, source="arrays")


def drift_campaign(effects=None, n_passes=5, st_mode="per_image"):
    """``n_passes`` passes one day apart (spherical Earth: pass k on day k), pass 2 nadir, the
    others site-tracking; θ = (20, −15, 40)″."""
    laws = ["nadir" if k == 2 else "site_tracking" for k in range(n_passes)]
    doc = _small_campaign_doc("drift", laws, 1.5, st_mode, 3.0, "per_image")
    if effects:
        doc["effects"] = effects
    return orbits.scenario_from_dict(doc)


# ---------------------------------------------------------------------------- campaigns at real sizes (issue 27)

#: the share of detections kept in ``campaign_as_flown`` (1 286 of ~3 900 simulated points)
AS_FLOWN_KEEP = 1286 / 3916


def campaign_as_flown(seed: int = 0, runs: int = 1) -> tuple[boresight.ObservationSet, DisturbanceModel]:
    """A 6-pass campaign as flown: ``campaign-6pass`` with three times the landmarks at each site
    (same fields), each detection kept with probability ``AS_FLOWN_KEEP`` (a chip is not found in
    every image that sees it; ``default_rng(seed + 1)``), then the landmarks never detected dropped:
    120 images, ~255 landmarks each seen ~5 times, ~1 300 observations (seed 0: 253 and 1 310)."""
    d = tomllib.loads((SCENARIOS / "campaign-6pass.toml").read_text())
    for p in d["passes"]:
        p["landmarks"] = dict(p["landmarks"], n=3 * int(p["landmarks"]["n"]))
    sc = orbits.scenario_from_dict(d)
    obs, model = simulate_with_model(sc, seed, runs)
    keep = np.random.default_rng(seed + 1).uniform(size=obs.n_observations) < AS_FLOWN_KEEP
    return obs.rows(keep).observed_targets(), model


def single_use(obs: boresight.ObservationSet) -> boresight.ObservationSet:
    """The same observations with every one its own ground-control point: a target per row (id
    ``<landmark>#<row>``, the row's catalogue position), nothing else changed."""
    k = np.arange(obs.n_observations)
    ids = np.char.add(np.char.add(obs.landmark_ids[obs.target_index].astype(str), "#"), k.astype(str))
    return dataclasses.replace(
        obs,
        landmark_ids=ids,
        landmark_g_m=obs.landmark_g_m[:, obs.target_index],
        target_kind=None,
        target_index=k,
        truth=None,
    )


def tile(obs: boresight.ObservationSet, copies: int) -> boresight.ObservationSet:
    """``copies`` copies of a campaign in one set: new images (times shifted by 10⁶ s a copy, passes
    renumbered), new targets (ids suffixed ``@copy``), the same values — θ̂ equals the single
    campaign's and σ scales as 1/√copies."""
    n, t = obs.n_images, obs.n_targets
    c = np.arange(copies)
    span = float(np.ptp(obs.t_s)) + 1.0
    return dataclasses.replace(
        obs,
        t_s=(obs.t_s[None] + (c * max(span, 1e6))[:, None]).ravel(),
        pass_index=(obs.pass_index[None] + (c * (int(obs.pass_index.max()) + 1))[:, None]).ravel(),
        q_is=np.tile(obs.q_is, (1, copies, 1)),
        r_sc_i_m=np.tile(obs.r_sc_i_m, (1, copies, 1)),
        v_sc_i_m_s=None if obs.v_sc_i_m_s is None else np.tile(obs.v_sc_i_m_s, (1, copies, 1)),
        C_GI=np.tile(obs.C_GI, (copies, 1, 1)),
        landmark_ids=np.char.add(np.tile(obs.landmark_ids.astype(str), copies), np.repeat([f"@{k}" for k in c], t)),
        landmark_g_m=np.tile(obs.landmark_g_m, (1, copies, 1)),
        target_kind=None,
        image_index=(obs.image_index[None] + (c * n)[:, None]).ravel(),
        target_index=(obs.target_index[None] + (c * t)[:, None]).ravel(),
        xy_m=np.tile(obs.xy_m, (1, copies, 1)),
        truth=None if obs.truth is None else {"theta_rad": obs.truth["theta_rad"]},
    )


def shared_strip(
    n_images: int = 10_000, per_image: int = 100, seen: int = 10, passes: int = 20, seed: int = 0
) -> tuple[boresight.ObservationSet, DisturbanceModel]:
    """A big shared-target campaign as a bundle adjustment sees it, built on rows (the simulator's
    images × landmarks grid could not hold it): ``n_images`` nadir images 1 km apart along a
    meridian at 680 km (spherical Earth, C_GI = E), split into ``passes`` consecutive passes;
    ground-control chips in along-track slots 1 km apart, ``per_image // seen`` across the track in
    each slot; image n sees the ``seen`` slots n … n + seen − 1, so ``n_images · per_image`` rows and
    every target (bar the first and last seen − 1 slots) seen ``seen`` times. Defaults: 10⁶ rows,
    100 090 targets, 10⁴ images. Errors drawn as the noise model says (``default_rng(seed)``): θ =
    (20, −15, 40)″, per-image star-tracker 5″ per axis and GNSS 10 m, catalogue 5 m, pixel 1.5 µm;
    the file's noise model is that one."""
    from orbits.camera import project
    from orbits.rotations import ARCSEC, misalignment_dcm, quat_from_dcm, star_tracker_error_dcm

    rng = np.random.default_rng(seed)
    RE, H, F, step_m = 6371e3, 680e3, 0.5, 1000.0
    across = per_image // seen
    n_slots = n_images + seen - 1
    u_img = np.arange(n_images) * step_m / RE  # along-track angle of each image
    r = (RE + H) * np.stack([np.cos(u_img), np.zeros(n_images), np.sin(u_img)], axis=-1)
    up = r / np.linalg.norm(r, axis=-1, keepdims=True)
    along = np.stack([-np.sin(u_img), np.zeros(n_images), np.cos(u_img)], axis=-1)
    # nadir camera: x_K along track, z_K up (the camera looks along −z_K), y_K = z_K × x_K
    A = np.stack([along, np.cross(up, along), up], axis=-2)  # (N, 3, 3): rows are the K axes in I
    u_slot = (np.arange(n_slots) - 0.5 * (seen - 1)) * step_m / RE  # image n's slots centred under it
    off = (np.arange(across) - 0.5 * (across - 1)) * (8e3 / max(across, 1))  # cross-track, ±4 km
    lat = np.repeat(u_slot, across)
    lon = np.tile(off / RE, n_slots)
    lm = RE * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)
    img = np.repeat(np.arange(n_images), per_image)
    tgt = (np.arange(n_images)[:, None] * across + np.arange(per_image)[None, :]).ravel()
    model = DisturbanceModel(
        sigma_pixel_m=1.5e-6,
        sigma_star_tracker_rad=(5 * ARCSEC,) * 3,
        star_tracker_mode="per_image",
        sigma_gnss_m=10.0,
        gnss_mode="per_image",
        sigma_catalogue_m=5.0,
    )
    theta = np.array([20.0, -15.0, 40.0]) * ARCSEC
    delta = rng.normal(0.0, 5 * ARCSEC, (n_images, 3))
    xi = rng.normal(0.0, 10.0, (n_images, 3))
    eps = rng.normal(0.0, 5.0, lm.shape)
    A_true = star_tracker_error_dcm(-delta) @ A  # the reported attitude A = exp(Φ(δ)) A_true
    s = np.einsum("kij,kj->ki", misalignment_dcm(theta) @ A_true[img], (lm + eps)[tgt] - r[img])
    xy = project(s, F) + rng.normal(0.0, model.sigma_pixel_m, (img.size, 2))
    obs = boresight.ObservationSet(
        t_s=np.arange(n_images) * 0.15,
        pass_index=np.arange(n_images) * passes // n_images,
        q_is=quat_from_dcm(A)[None],
        r_sc_i_m=(r + xi)[None],
        C_GI=np.broadcast_to(np.eye(3), (n_images, 3, 3)).copy(),
        landmark_ids=np.char.add("chip", np.arange(lm.shape[0]).astype(str)),
        landmark_g_m=lm[None],
        image_index=img,
        target_index=tgt,
        xy_m=xy[None],
        focal_length_m=F,
        noise=model.to_noise(),
        truth={"theta_rad": theta[None]},
    )
    return obs, model


def traced_peak(fn) -> int:
    """Peak traced allocation (bytes) while ``fn()`` runs (numpy's buffers included)."""
    import gc
    import tracemalloc

    gc.collect()
    tracemalloc.start()
    try:
        fn()
        return int(tracemalloc.get_traced_memory()[1])
    finally:
        tracemalloc.stop()
