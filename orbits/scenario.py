"""Scenarios: TOML files in ``scenarios/`` loaded into frozen, validated dataclasses.

A scenario is a campaign of one or more passes over ground sites, a camera, sensors with
their error models, landmark layouts and the true misalignment. ``simulate_passes(scenario, rng,
runs=N)`` returns ``orbits.measurements.Measurements`` with a leading run axis.

Example
-------
>>> import numpy as np
>>> sc = load_scenario("scenarios/kiev2012-algorithm1.toml")
>>> meas = simulate_passes(sc, np.random.default_rng(1), runs=3)
>>> meas.xy_m.shape, meas.n_images, meas.n_landmarks  # one row per observation: 10 images × 4 landmarks
((3, 40, 2), 10, 4)

Every key is documented in ``docs/data-format.md`` (section Scenario files); an unknown key
is an error naming it, so a typo never silently falls back to a default.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from . import effects as fx
from . import landmarks as lm
from .camera import DETECTOR_KEYS, CalibratedCamera, Camera
from .earth import R_EARTH_M
from .errors import InputTypeError, did_you_mean, unknown_keys_message
from .geometry import PassGeometry, attitude_law, spherical_pass, wgs84_pass
from .limits import BYTES_PER_IMAGE, BYTES_PER_OBSERVATION, check_memory
from .measurements import Measurements, draw_errors, observe, visible_rows
from .orbit import CircularOrbit
from .rotations import ARCSEC
from .scenario_schema import ScenarioError, check_document
from .sensors import GnssErrors, PixelNoise, StarTrackerErrors

__all__ = [
    "Scenario",
    "OrbitSpec",
    "LandmarkSpec",
    "PassSpec",
    "ScenarioError",
    "load_scenario",
    "scenario_from_dict",
    "campaign_geometry",
    "campaign_arrays",
    "draw_scenario_errors",
    "simulate_passes",
]


@dataclass(frozen=True)
class OrbitSpec:
    altitude_km: float
    inclination_deg: float
    raan_deg: float = 0.0

    def orbit(self) -> CircularOrbit:
        return CircularOrbit(self.altitude_km * 1e3, np.radians(self.inclination_deg), np.radians(self.raan_deg), R_EARTH_M)


@dataclass(frozen=True)
class LandmarkSpec:
    """How a pass's landmarks are laid out in the site's topocentric frame."""

    layout: str = "kiev_m1_m4"  # kiev_m1_m4 | grid | random | explicit
    n: int = 4  # grid: n×n points; random: n points
    half_width_km: float = 10.0
    height_m: float = 0.0  # grid height
    height_sigma_m: float = 0.0  # random heights
    seed: int = 0  # random layout seed (the layout is part of the scenario, not of a run)
    enu_km: tuple[Any, ...] = ()  # explicit: ((east, north, up), ...) in km
    placement: str = "tangent_plane"  # tangent_plane | sphere

    def __post_init__(self) -> None:
        # a whole number written 4.0 in TOML is accepted (scenario_schema checked it is whole);
        # numpy's generators and the layouts need the int
        for name in ("n", "seed"):
            v = getattr(self, name)
            if isinstance(v, float) and v.is_integer():
                object.__setattr__(self, name, int(v))

    def positions_t_m(self) -> np.ndarray:
        if self.layout == "kiev_m1_m4":
            return lm.kiev_m1_m4()
        if self.layout == "grid":
            return lm.grid(self.n, self.half_width_km * 1e3, self.height_m)
        if self.layout == "random":
            return lm.random_field(np.random.default_rng(self.seed), self.n, self.half_width_km * 1e3, self.height_sigma_m)
        if self.layout == "explicit":
            a = np.asarray(self.enu_km, float) * 1e3
            if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] < 1:
                raise ScenarioError(f"landmarks.enu_km must be a list of [east, north, up] triples, got {self.enu_km!r}")
            return a
        raise ScenarioError(f"landmarks.layout must be kiev_m1_m4, grid, random or explicit, got {self.layout!r}")


@dataclass(frozen=True)
class PassSpec:
    site_lat_deg: float
    site_lon_deg: float
    t_s: tuple[Any, ...]
    site_height_m: float = 0.0
    direction: str = "ascending"
    attitude: str = "site_tracking"
    yaw_deg: float = 0.0
    epoch_utc: str | None = None  # wgs84 mode: the passage epoch (defaults to the scenario's)
    landmarks: LandmarkSpec | None = None  # defaults to the scenario's


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (units in the field names; angles in degrees or arcseconds)."""

    name: str
    orbit: OrbitSpec
    camera: Camera
    passes: tuple[PassSpec, ...]
    earth_model: str = "spherical"  # spherical | wgs84
    epoch_utc: str = "2012-01-31T00:00:00"
    description: str = ""
    star_tracker_mount_deg: tuple[Any, ...] = (0.0, 0.0, 0.0)  # C_ES as intrinsic Z-Y-X Euler angles
    sigma_star_tracker_arcsec: tuple[Any, ...] = (0.0, 0.0, 0.0)
    star_tracker_error_mode: str = "per_image"
    sigma_gnss_m: float = 0.0
    gnss_error_mode: str = "per_image"
    sigma_pixel_m: float = 0.0
    sigma_catalogue_m: float = 0.0
    theta_true_arcsec: tuple[Any, ...] | None = None
    theta_sigma0_arcsec: float = 0.0
    landmarks: LandmarkSpec = field(default_factory=LandmarkSpec)
    source: str = ""
    effects: fx.EffectSizes = field(default_factory=fx.EffectSizes)  # [effects]: hidden catalogue effects
    unmodelled: tuple[Any, ...] = ()  # [unmodelled]: ((name, {key: value}), ...) out-of-catalogue test perturbations
    stars: Any = None  # [stars]: orbits.star_campaign.StarSpec (star frames' catalogue and detector)
    star_frames: tuple[Any, ...] = ()  # [[star_frames]]: orbits.star_campaign.StarFrameSpec segments
    # the landmark rows' line of sight: "geometric" | "light_time+aberration" (orbits.measurements.observe)
    landmark_sight: str = "geometric"

    @property
    def C_ES(self) -> np.ndarray:
        """Body → star-tracker DCM from the mount angles (frame rotation, scipy's intrinsic 'ZYX')."""
        from scipy.spatial.transform import Rotation

        result: np.ndarray = Rotation.from_euler("ZYX", self.star_tracker_mount_deg, degrees=True).as_matrix().T
        return result

    def errors(self) -> dict[str, Any]:
        return dict(
            star_tracker=StarTrackerErrors(
                tuple(np.asarray(self.sigma_star_tracker_arcsec, float) * ARCSEC), self.star_tracker_error_mode
            ),
            gnss=GnssErrors(self.sigma_gnss_m, self.gnss_error_mode),
            pixel=PixelNoise(self.sigma_pixel_m),
            catalogue_sigma_m=self.sigma_catalogue_m,
        )


#: the scenario file's [table] key → the Scenario field (quantity_source_unit, see boresight.core.error_sources)
_FIELD_OF = {
    "pixel_sigma_m": "sigma_pixel_m",
    "gnss_sigma_m": "sigma_gnss_m",
    "catalogue_sigma_m": "sigma_catalogue_m",
    "star_tracker_sigma_arcsec": "sigma_star_tracker_arcsec",
}


# ---------------------------------------------------------------------------- loading


def _build(cls: Any, data: dict[str, Any], where: str) -> Any:
    known = {f.name for f in fields(cls)}
    unknown = set(data) - known
    if unknown:
        raise ScenarioError(unknown_keys_message(where, unknown, known))
    try:
        return cls(**data)
    except TypeError as exc:
        import re

        missing = re.findall(r"'(\w+)'", str(exc)) if "required" in str(exc) else []
        if missing:  # named as a key of the file, not as the dataclass's argument
            raise ScenarioError(f"{where}: missing required key {', '.join(repr(m) for m in missing)}") from None
        raise ScenarioError(f"{where}: {exc}") from None


def _times(spec: Any, where: str) -> Any:
    if isinstance(spec, dict):
        try:
            start, stop, step = float(spec["start"]), float(spec["stop"]), float(spec["step"])
        except KeyError as exc:
            raise ScenarioError(f"{where}.t_s needs start, stop and step, missing {exc}") from None
        if step <= 0 or stop < start:
            raise ScenarioError(f"{where}.t_s must have step > 0 and stop ≥ start, got {spec!r}")
        return tuple(np.round(np.arange(start, stop + 0.5 * step, step), 12))
    t = tuple(float(x) for x in spec)
    if not t:
        raise ScenarioError(f"{where}.t_s is empty")
    return t


def scenario_from_dict(data: dict[str, Any], source: str = "<dict>") -> Scenario:
    """Validate a parsed TOML document and build the ``Scenario``.

    Types, ranges and sizes are checked first (``orbits.scenario_schema.check_document``), so
    every message names ``source``, the key as written in the file and the value.
    """
    d = dict(data) if isinstance(data, dict) else data
    star_tables = (d.pop("stars", None), d.pop("star_frames", None)) if isinstance(d, dict) else (None, None)
    star_only = star_tables[1] is not None and isinstance(d, dict) and "passes" not in d
    check_document(d, source, passes_required=not star_only)
    from .star_campaign import star_tables as parse_star_tables

    stars, star_frames = parse_star_tables(*star_tables, source)
    try:
        orbit = _build(OrbitSpec, d.pop("orbit"), f"{source}: orbit")
        cam = d.pop("camera")
        camera = _build(CalibratedCamera if set(cam) & set(DETECTOR_KEYS) else Camera, cam, f"{source}: camera")
        raw_passes = d.pop("passes") if not star_only else []
    except ScenarioError:
        raise
    except KeyError as exc:
        raise ScenarioError(f"{source}: missing required table {exc}") from None
    except ValueError as exc:
        raise ScenarioError(f"{source}: {exc}") from None
    landmarks = _build(LandmarkSpec, d.pop("landmarks", {}), f"{source}: landmarks")
    st = d.pop("star_tracker", {})
    gnss = d.pop("gnss", {})
    pix = d.pop("pixel", {})
    cat = d.pop("catalogue", {})
    mis = d.pop("misalignment", {})
    try:
        effects = fx.effect_sizes(d.pop("effects", None), "effects", ScenarioError)
        unmodelled = _unmodelled_table(d.pop("unmodelled", None))
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: {exc}") from None
    unknown = sorted(set(d) - {"name", "description", "earth_model", "epoch_utc", "landmark_sight"})
    if unknown:  # named as the user wrote them, not as the flattened dataclass fields
        tables = [
            "name",
            "description",
            "earth_model",
            "epoch_utc",
            "landmark_sight",
            "orbit",
            "camera",
            "landmarks",
            "star_tracker",
            "gnss",
            "pixel",
            "catalogue",
            "misalignment",
            "effects",
            "unmodelled",
            "passes",
            "stars",
            "star_frames",
        ]
        hints = "".join(did_you_mean(k, tables) for k in unknown)
        raise ScenarioError(
            f"{source}: unknown key(s) or table(s) {unknown}{hints}; a scenario has name, description, earth_model, epoch_utc, "
            "landmark_sight, "
            "[orbit], [camera], [landmarks], [star_tracker], [gnss], [pixel], [catalogue], [misalignment], [effects], "
            "[unmodelled], [[passes]], [stars] and [[star_frames]] (docs/data-format.md)"
        )
    flat = dict(d, effects=effects, unmodelled=unmodelled)
    for prefix, table, keys, table_name in (
        ("star_tracker_", st, ("mount_deg", "sigma_arcsec", "error_mode"), "star_tracker"),
        ("gnss_", gnss, ("sigma_m", "error_mode"), "gnss"),
        ("pixel_", pix, ("sigma_m",), "pixel"),
        ("catalogue_", cat, ("sigma_m",), "catalogue"),
        ("theta_", mis, ("true_arcsec", "sigma0_arcsec"), "misalignment"),
    ):
        unknown_keys = set(table) - set(keys)
        if unknown_keys:  # named as the user wrote the table ([misalignment]), not the field prefix
            raise ScenarioError(unknown_keys_message(f"{source}: [{table_name}]", unknown_keys, keys))
        for k, v in table.items():
            key = prefix + k
            flat[_FIELD_OF.get(key, key)] = tuple(v) if isinstance(v, list) else v
    if not isinstance(raw_passes, list) or (not raw_passes and not star_only):
        raise ScenarioError(f"{source}: [[passes]] must list at least one pass")
    passes = []
    for k, p in enumerate(raw_passes):
        p = dict(p)
        where = f"{source}: passes[{k}]"
        if "t_s" not in p:
            raise ScenarioError(f"{source}: {where} is missing t_s")
        p["t_s"] = _times(p["t_s"], where)
        if "landmarks" in p:
            p["landmarks"] = _build(LandmarkSpec, p["landmarks"], f"{where}.landmarks")
        passes.append(_build(PassSpec, p, where))
    sc = _build(
        Scenario,
        dict(
            flat,
            orbit=orbit,
            camera=camera,
            passes=tuple(passes),
            landmarks=landmarks,
            source=source,
            stars=stars,
            star_frames=star_frames,
        ),
        source,
    )
    _validate(sc)
    result: "Scenario" = sc
    return result


#: keys of each [unmodelled] perturbation (all numbers; defaults in brackets)
_UNMODELLED_KEYS: dict[str, dict[str, Any]] = {
    "tangential_distortion": {"p1": None, "p2": None},
    "landmark_shift": {"pass": 0, "east_km": 0.0, "north_km": 0.0, "radius_km": None, "east_m": 0.0, "north_m": 0.0, "up_m": 0.0},
}


def _unmodelled_table(table: Any) -> tuple[Any, ...]:
    """Validate ``[unmodelled]``: out-of-catalogue perturbations a simulation can hide (for tests).

    ``tangential_distortion = { p1 = …, p2 = … }`` (Brown–Conrady, OpenCV convention, normalised
    coordinates); ``landmark_shift = { pass = k, east_km, north_km, radius_km, east_m, north_m,
    up_m }``: catalogue landmarks of pass k within ``radius_km`` of the point (east_km, north_km)
    of the site's topocentric frame are moved by (east_m, north_m, up_m) in the catalogue.
    """
    if table is None:
        return ()
    if not isinstance(table, dict):
        raise ScenarioError(f"[unmodelled] must be a table, got {table!r}")
    out = []
    for name, spec in table.items():
        if name in fx.EFFECTS:
            raise ScenarioError(f"unmodelled.{name}: {name!r} is a catalogue effect; put it in [effects]")
        if name not in _UNMODELLED_KEYS:
            raise ScenarioError(f"unmodelled.{name}: unknown perturbation; expected one of {sorted(_UNMODELLED_KEYS)}")
        keys = _UNMODELLED_KEYS[name]
        if not isinstance(spec, dict):
            raise ScenarioError(f"unmodelled.{name} must be a table with keys {sorted(keys)}, got {spec!r}")
        bad = sorted(set(spec) - set(keys))
        if bad:
            raise ScenarioError(unknown_keys_message(f"unmodelled.{name}", bad, keys))
        vals = {}
        for k, default in keys.items():
            v = spec.get(k, default)
            if v is None:
                raise ScenarioError(f"unmodelled.{name} is missing {k}")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise ScenarioError(f"unmodelled.{name}.{k} must be a finite number, got {v!r}")
            vals[k] = v
        if name == "landmark_shift" and not vals["radius_km"] > 0:
            raise ScenarioError(f"unmodelled.landmark_shift.radius_km must be > 0, got {vals['radius_km']!r}")
        out.append((name, tuple(sorted(vals.items()))))
    return tuple(out)


def _validate(sc: Scenario) -> None:
    if sc.earth_model not in ("spherical", "wgs84"):
        raise ScenarioError(f"earth_model must be 'spherical' or 'wgs84', got {sc.earth_model!r}")
    for name in ("star_tracker_mount_deg", "sigma_star_tracker_arcsec"):
        v = np.asarray(getattr(sc, name), float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ScenarioError(f"{name} must be three finite numbers, got {getattr(sc, name)!r}")
    if sc.theta_true_arcsec is not None:
        v = np.asarray(sc.theta_true_arcsec, float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ScenarioError(f"misalignment.true_arcsec must be three finite numbers, got {sc.theta_true_arcsec!r}")
    for name in ("sigma_gnss_m", "sigma_pixel_m", "sigma_catalogue_m", "theta_sigma0_arcsec"):
        v = getattr(sc, name)
        if not (np.isfinite(v) and v >= 0):
            raise ScenarioError(f"{name} must be a finite number ≥ 0, got {v!r}")
    try:
        sc.orbit.orbit()
        sc.errors()
    except ValueError as exc:
        raise ScenarioError(f"{sc.source}: {exc}") from None
    for k, p in enumerate(sc.passes):
        if p.attitude not in ("nadir", "site_tracking"):
            raise ScenarioError(f"passes[{k}].attitude must be 'nadir' or 'site_tracking', got {p.attitude!r}")
        if p.direction not in ("ascending", "descending"):
            raise ScenarioError(f"passes[{k}].direction must be 'ascending' or 'descending', got {p.direction!r}")
        (p.landmarks or sc.landmarks).positions_t_m()
    for name, vals in sc.unmodelled:
        k = dict(vals).get("pass", 0)
        if name == "landmark_shift" and not (int(k) == k and 0 <= k < len(sc.passes)):
            raise ScenarioError(f"unmodelled.landmark_shift.pass must be a pass index in [0, {len(sc.passes) - 1}], got {k!r}")


#: the shipped scenarios (a symlink to the repository's scenarios/ in a checkout; package data in a wheel)
SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (``orbits.load_scenario(name)`` loads them)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def scenario_path(name_or_path: Any) -> Path:
    """THE lookup rule for scenarios: an existing file path is used as given; otherwise a bare
    name (``"kiev2012-sensitivity"``, with or without ``.toml``) is a shipped scenario
    (``SCENARIO_DIR``). Anything else is a ``ScenarioError`` listing the shipped names.

    >>> scenario_path("kiev2012-sensitivity").name
    'kiev2012-sensitivity.toml'
    """
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise InputTypeError.expected(
            "load_scenario", "scenario", "an orbits.Scenario, a scenario file's path or a shipped scenario's name", name_or_path
        )
    p = Path(name_or_path)
    if p.exists():
        return p
    if p.parent == Path(".") and p.suffix in ("", ".toml"):
        cand = SCENARIO_DIR / (p.stem + ".toml")
        if cand.is_file():
            return cand
    from .errors import did_you_mean

    hint = did_you_mean(p.stem, scenario_names()) if p.parent == Path(".") else ""
    raise ScenarioError(
        f"{name_or_path}: no such scenario file, and not a shipped scenario name{hint} (shipped: {', '.join(scenario_names())})"
    )


def load_scenario(path: Any) -> Scenario:
    """Read and validate a scenario TOML file, given as a path or a shipped scenario's name (``scenario_path``)."""
    from .files import read_toml

    path = scenario_path(path)
    data = read_toml(path, ScenarioError, "scenario")
    if isinstance(data, dict) and data.get("kind") == "pushbroom":
        raise ScenarioError(f'{path}: a pushbroom scenario (kind = "pushbroom"): load it with orbits.strip.load_strip_scenario')
    return scenario_from_dict(data, source=str(path))


# ---------------------------------------------------------------------------- geometry and runs


def _pass_geometry(sc: Scenario, k: int) -> PassGeometry:
    p = sc.passes[k]
    layout = p.landmarks or sc.landmarks
    lm_t = layout.positions_t_m()
    if sc.earth_model == "spherical":
        return spherical_pass(
            sc.orbit.orbit(),
            np.radians(p.site_lat_deg),
            np.radians(p.site_lon_deg),
            p.t_s,
            lm_t,
            p.direction,
            layout.placement,
            p.site_height_m,
        )
    return wgs84_pass(
        sc.orbit.altitude_km * 1e3,
        np.radians(sc.orbit.inclination_deg),
        p.site_lat_deg,
        p.site_lon_deg,
        _pass_epoch(sc, k),
        p.t_s,
        lm_t,
        p.direction,
        layout.placement,
        p.site_height_m,
    )


def campaign_geometry(sc: Scenario) -> tuple[list[PassGeometry], list[np.ndarray]]:
    """The true geometry and attitude C_IE of each pass."""
    geoms, atts = [], []
    for k, p in enumerate(sc.passes):
        try:
            g = _pass_geometry(sc, k)
        except ScenarioError:
            raise
        except ValueError as exc:  # geometry the numbers allow but the orbit cannot fly
            raise ScenarioError(f"{sc.source}: passes[{k}]: {exc}") from None
        geoms.append(g)
        atts.append(attitude_law(g, p.attitude, np.radians(p.yaw_deg)))
    return geoms, atts


def _pass_epoch(sc: Scenario, k: int) -> Any:
    from astropy import units as u
    from astropy.time import Time

    return Time(sc.epoch_utc, scale="utc") + _pass_offset_s(sc, k) * u.s


def _pass_offset_s(sc: Scenario, k: int) -> float:
    """Seconds from the scenario epoch to pass k's passage: its own epoch in the WGS84 mode; in
    the spherical mode (no calendar) pass k is labelled k days after the epoch."""
    p = sc.passes[k]
    if sc.earth_model == "wgs84" and p.epoch_utc:
        from astropy.time import Time

        return float((Time(p.epoch_utc, scale="utc") - Time(sc.epoch_utc, scale="utc")).sec)
    return 86400.0 * k


def campaign_arrays(scenario: Scenario) -> dict[str, Any]:
    """The deterministic part of a campaign as keyword arguments of ``orbits.measurements.observe``.

    Compute it once and reuse it for every chunk of a Monte Carlo study. ``rows`` = (image_index,
    target_index) (K,): the observations, each pass's landmarks inside the field of its images
    (``orbits.measurements.visible_rows``, found pass by pass: no images × landmarks array).

    A scenario with ``[[star_frames]]``: its star frames after its landmark passes (``_star_arrays``),
    the star rows carrying ``row_directions_i`` and ``star_catalogue``.
    """
    if scenario.star_frames:
        return _star_arrays(scenario)
    geoms, atts = campaign_geometry(scenario)
    t = np.concatenate([g.t_s + _pass_offset_s(scenario, k) for k, g in enumerate(geoms)])
    pidx = np.concatenate([np.full(g.t_s.size, k) for k, g in enumerate(geoms)])
    lm_pass = np.concatenate([np.full(g.landmarks_g_m.shape[0], k) for k, g in enumerate(geoms)])
    if len(geoms) == 1:
        ids = np.array([f"M{j + 1}" for j in range(geoms[0].landmarks_g_m.shape[0])])
    else:
        ids = np.concatenate([[f"P{k}M{j + 1}" for j in range(g.landmarks_g_m.shape[0])] for k, g in enumerate(geoms)])
    geometry: dict[str, Any] = dict(
        pass_index=pidx,
        r_sc_i_m=np.concatenate([g.r_sc_i_m for g in geoms]),
        C_GI=np.concatenate([g.C_GI for g in geoms]),
        C_IE=np.concatenate(atts),
        landmarks_g_m=np.concatenate([g.landmarks_g_m for g in geoms]),
        landmark_pass=lm_pass,
    )
    return dict(
        t_s=t,
        v_sc_i_m_s=np.concatenate([g.v_sc_i_m_s for g in geoms]),
        **geometry,
        rows=visible_rows(camera=scenario.camera, **geometry),
        landmark_ids=ids,
        camera=scenario.camera,
        C_ES=scenario.C_ES,
        epoch_utc=scenario.epoch_utc,
        frames=({"inertial": "GCRS", "earth_fixed": "ITRS"} if scenario.earth_model == "wgs84" else None),
        landmark_sight=scenario.landmark_sight,
        **_effect_arrays(scenario, geoms),
    )


def _star_arrays(scenario: Scenario) -> dict[str, Any]:
    """``campaign_arrays`` of a scenario with ``[[star_frames]]``: the star frames' rows
    (``orbits.star_campaign.star_frame_arrays``) after the landmark passes' (images, passes, targets
    and rows numbered after them, as ``boresight.simulate`` joins the two; ``row_directions_i`` NaN on
    a landmark row).

    DECISION: which stars each frame detects is drawn once from the ``[stars]`` seed
    (``default_rng(seed)``), not from a run's generator: the rows are part of the campaign's
    geometry, shared by every run and every chunk of a study (only a ``detection_probability`` < 1
    makes them depend on it); ``boresight.simulate`` draws them from its own generator.
    """
    from dataclasses import replace

    from .star_campaign import StarSpec, star_frame_arrays

    spec = scenario.stars or StarSpec()
    star, _, _ = star_frame_arrays(scenario, np.random.default_rng(spec.seed))
    if not scenario.passes:
        return star
    land = campaign_arrays(replace(scenario, star_frames=(), stars=None))
    n_img, n_tgt, k_land = land["t_s"].size, land["landmarks_g_m"].shape[0], land["rows"][0].size
    out = dict(land)
    for key in ("t_s", "r_sc_i_m", "C_GI", "C_IE", "v_sc_i_m_s", "landmarks_g_m", "landmark_ids"):
        out[key] = np.concatenate([land[key], star[key]])
    out["pass_index"] = np.concatenate([land["pass_index"], star["pass_index"] + len(scenario.passes)])
    out["landmark_pass"] = np.concatenate([land["landmark_pass"], np.full(star["landmarks_g_m"].shape[0], -1)])
    out["rows"] = tuple(np.concatenate([a, b + off]) for a, b, off in zip(land["rows"], star["rows"], (n_img, n_tgt)))
    out["row_directions_i"] = np.concatenate([np.full((k_land, 3), np.nan), star["row_directions_i"]])
    out["star_catalogue"] = star["star_catalogue"]
    if "pixel_sigma_rows_m" in star:  # the landmark rows keep the scenario's one pixel σ (NaN)
        out["pixel_sigma_rows_m"] = np.concatenate([np.full((k_land, 2), np.nan), star["pixel_sigma_rows_m"]])
    if "time_tag_rotation_e_rad" in land:
        out["time_tag_rotation_e_rad"] = np.concatenate([land["time_tag_rotation_e_rad"], star["time_tag_rotation_e_rad"]])
    return out


#: half-step (s) of the central difference giving the attitude law's body rate
_RATE_STEP_S = 0.01


def _effect_arrays(scenario: Scenario, geoms: Any) -> dict[str, Any]:
    """``observe`` keywords for the scenario's hidden effects (none when it has none)."""
    out: dict[str, Any] = {}
    if scenario.effects:
        out["effects"] = scenario.effects
        if "time_tag" in scenario.effects:
            # the exact shift A_rep(t) = A_true(t + dt) from the attitude law (orbits.measurements.observe)
            dt = float(scenario.effects["time_tag"][0])
            out["time_tag_rotation_e_rad"] = np.concatenate([_law_rotation(scenario, k, dt) for k in range(len(geoms))])
            out["time_tag_rotation_dt_s"] = dt
    if scenario.unmodelled:
        out["unmodelled"] = tuple(_unmodelled(scenario, geoms, name, dict(vals)) for name, vals in scenario.unmodelled)
    return out


def _attitude_at(scenario: Scenario, k: int, offset_s: float) -> np.ndarray:
    """C_IE (N, 3, 3) of pass k's attitude law at its image times + ``offset_s``."""
    p = scenario.passes[k]
    shifted = Scenario.__new__(Scenario)
    shifted.__dict__.update(scenario.__dict__)
    passes = list(scenario.passes)
    passes[k] = PassSpec(**dict(p.__dict__, t_s=tuple(np.asarray(p.t_s, float) + offset_s)))
    object.__setattr__(shifted, "passes", tuple(passes))
    return attitude_law(_pass_geometry(shifted, k), p.attitude, np.radians(p.yaw_deg))


def _law_rotation(scenario: Scenario, k: int, dt_s: float, start_s: float = 0.0) -> np.ndarray:
    """Rotation vector (N, 3), body axes, of pass k's attitude from t + start to t + start + dt:
    log(C_IE(t + start + dt) C_IE(t + start)ᵀ) = ε with exp(Φ(ε)) that matrix."""
    from scipy.spatial.transform import Rotation

    C1 = _attitude_at(scenario, k, start_s + dt_s)
    C0 = _attitude_at(scenario, k, start_s)
    result: np.ndarray = Rotation.from_matrix(C1 @ np.swapaxes(C0, -1, -2)).as_rotvec()
    return result


def attitude_rate(scenario: Scenario, k: int, step_s: float = _RATE_STEP_S, offset_s: float = 0.0) -> np.ndarray:
    """Body rate ω_E (N, 3) rad/s of pass k's attitude law at t + ``offset_s``, in body axes
    (dC_IE/dt = −Φ(ω_E) C_IE).

    Central difference of the law: C_IE(t + h) C_IE(t − h)ᵀ = exp(−Φ(2 h ω_E)) + O(h³);
    with h = 0.01 s the truncation is ~(h/T)² of ω for a rate varying on a time scale T ≳ 10 s.
    """
    return -_law_rotation(scenario, k, 2 * step_s, offset_s - step_s) / (2 * step_s)


def _unmodelled(scenario: Scenario, geoms: Any, name: str, vals: dict[str, Any]) -> fx.Unmodelled:
    if name == "tangential_distortion":
        return fx.tangential_distortion(vals["p1"], vals["p2"])
    g = geoms[int(vals["pass"])]
    center_t = np.array([vals["east_km"] * 1e3, vals["north_km"] * 1e3, 0.0])
    center_g = g.site_g_m + center_t @ g.C_GT
    shift_g = np.array([vals["east_m"], vals["north_m"], vals["up_m"]]) @ g.C_GT
    return fx.landmark_shift(center_g, vals["radius_km"] * 1e3, shift_g)


def draw_scenario_errors(
    scenario: Scenario, rng: np.random.Generator, runs: int, arrays: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Draw ``runs`` sets of θ and sensor errors for the scenario (``orbits.measurements.draw_errors``)."""
    arrays = arrays or campaign_arrays(scenario)
    theta_true = None if scenario.theta_true_arcsec is None else np.asarray(scenario.theta_true_arcsec, float) * ARCSEC
    return draw_errors(
        rng,
        runs,
        arrays["pass_index"],
        arrays["landmarks_g_m"].shape[0],
        rows=arrays.get("rows"),
        theta_true_rad=theta_true,
        theta_sigma_rad=scenario.theta_sigma0_arcsec * ARCSEC,
        pixel_sigma_rows_m=arrays.get("pixel_sigma_rows_m"),  # star rows' centroid σ by magnitude ([stars])
        **scenario.errors(),
    )


def simulate_passes(
    scenario: Scenario, rng: np.random.Generator, runs: int = 1, arrays: dict[str, Any] | None = None
) -> Measurements:
    """Simulate ``runs`` measurement sets of the scenario's landmark passes (leading run axis): the world's
    raw ``Measurements``, truth included. ``boresight.simulate`` turns them (and the star frames) into the
    analyst's ``ObservationSet``.

    DECISION: named for what it simulates, as ``simulate_star_frames`` and ``simulate_strip`` are (it was
    ``orbits.simulate``, a second ``simulate`` beside ``boresight.simulate`` returning another type);
    ``orbits.simulate`` still resolves to it with a ``DeprecationWarning`` for one release.

    ``arrays`` (from ``campaign_arrays``) skips recomputing the geometry.
    """
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ScenarioError(f"runs must be an integer ≥ 1, got {runs!r}")
    if not callable(getattr(rng, "normal", None)):  # a Generator, or a wrapper that draws like one (heavy-tailed tests)
        raise InputTypeError.expected("simulate", "rng", "a numpy.random.Generator (numpy.random.default_rng(seed))", rng)
    arrays = arrays or campaign_arrays(scenario)
    n, m = arrays["t_s"].size, arrays["landmarks_g_m"].shape[0]
    k = arrays["rows"][0].size
    check_memory(
        f"{scenario.source}: {runs} run(s) of {n} images, {m} landmarks, {k} observations",
        float(runs) * (k * BYTES_PER_OBSERVATION + (n + m) * BYTES_PER_IMAGE),
        hint="fewer runs",
    )
    return observe(draw_scenario_errors(scenario, rng, runs, arrays), **arrays)
