"""Pass options: every pass a campaign may contain, each as a one-pass scenario.

A pass option is (site, direction, attitude law, yaw, images, landmarks per image). Each is
written as a scenario ``[[passes]]`` entry (``pass_entry``), so the chosen campaign is a
scenario file that ``boresight simulate`` runs as is, and its geometry is built by the
simulator's own code (``orbits.scenario``): the planner never has a second geometry model.

Landmark fields (DECISION, ``docs/planning.md``): a site's own catalogue
(``landmarks_enu_km``) is used as given. Otherwise

* site tracking: the boresight stays on the site, so ``k`` landmarks uniform in a square of
  half-width ``min([landmarks] half_width_km, 0.75 × footprint half-width)`` around it, heights
  N(0, ``height_sigma_m``²) (default 300 m), keep ``k`` in view in every image;
* nadir: the footprint sweeps the ground track, so landmarks are laid uniformly over the swept
  strip (along track: the sub-satellite track of the pass extended by the footprint; across:
  ±0.9 footprint half-width) at the density that puts ``k`` in a footprint on average.

Fields are drawn from a seed fixed by the option (site, direction, attitude, images, k), so a
plan is reproducible and the written scenario lists the same landmarks (``layout =
"explicit"``, east/north/up in km, ``placement = "sphere"``).

Star-frame segments (``star_options``; a plan with ``[stars]`` and ``[search] star_segments``): the
camera turned to the sky on the plan's orbit, each a scenario ``[[star_frames]]`` entry
(``orbits.star_campaign``), so the chosen campaign's star frames are simulated by the simulator's own
code too. DECISION (``docs/planning.md``, "Star-frame segments"): the candidates are

* ``inertial_hold``: ``star_frames_per_segment`` frames ``star_frame_interval_s.inertial_hold`` apart with
  the boresight on the orbit normal, and another on the anti-normal — directions 90° from the zenith,
  so 24° above the Earth's limb at 600 km at every point of the orbit, and away from the Sun
  unless the orbit's β angle is near ±90° (a frame within the star tracker's Sun exclusion sees
  nothing, and a segment that sees no star is not a candidate);
* ``zenith``: one orbit of the zenith law at ``star_frame_interval_s.zenith``, the frames in the Earth's
  shadow only (``night_only``): the sky scanned at the orbital rate on the night side.

Their images are the frames that see at least one star of the plan's ``[stars]`` catalogue to its
magnitude limit (counted on the noise-free campaign), their cost ``[cost] per_pass + per_star_segment +
per_image × images`` (a segment is an operations slot, its frames are images downlinked). Like a pass,
a segment chosen twice is flown on another day (its per-pass errors drawn afresh).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.studies.planning.spec import PlanSpec
from orbits.earth import R_EARTH_M, enu_dcm, geocentric_unit

__all__ = ["PassOption", "pass_options", "pass_entry", "scenario_document", "ground_track_t", "star_options"]

DEFAULT_HALF_WIDTH_KM = 15.0
DEFAULT_HEIGHT_SIGMA_M = 300.0


@dataclass(frozen=True)
class PassOption:
    """One candidate pass. ``entry`` is its scenario ``[[passes]]`` table."""

    index: int
    site: str
    site_index: int
    direction: str
    attitude: str
    yaw_deg: float
    images: int
    landmarks_per_image: int
    u_deg: float
    cost: float
    entry: dict
    kind: str = "pass"  # "pass" (a landmark pass: [[passes]]) or "stars" (a star-frame segment: [[star_frames]])

    @property
    def label(self) -> str:
        if self.kind == "stars":
            return f"stars {self.attitude.replace('_', ' ')} ({self.direction}), {self.images} frames × {self.landmarks_per_image} stars"
        yaw = f", yaw {self.yaw_deg:g}°" if self.yaw_deg else ""
        return (
            f"{self.site} {self.direction[:3]} {self.attitude.replace('_', '-')}{yaw}, "
            f"{self.images} img × {self.landmarks_per_image} lm, u {self.u_deg:.0f}°"
        )


def _footprint_half_width_m(spec: PlanSpec) -> float:
    cam = spec.scenario_base["camera"]
    return spec.scenario_base["orbit"]["altitude_km"] * 1e3 * np.tan(np.radians(cam["fov_deg"]) / 2)


def _orbit(spec):
    from orbits.scenario import OrbitSpec

    o = spec.scenario_base["orbit"]
    return OrbitSpec(o["altitude_km"], o["inclination_deg"], o.get("raan_deg", 0.0)).orbit()


def ground_track_t(spec: PlanSpec, site, direction: str, t_s) -> np.ndarray:
    """Sub-satellite points of a pass over ``site`` at times ``t_s`` in the site's east/north
    frame (m), spherical Earth (Kiev 2012 eqs 25-27; used only to lay out a nadir field)."""
    from orbits.geometry import spherical_pass

    lat, lon = np.radians(site.lat_deg), np.radians(site.lon_deg)
    g = spherical_pass(_orbit(spec), lat, lon, np.asarray(t_s, float), np.zeros((1, 3)), direction)
    site_g = R_EARTH_M * geocentric_unit(lat, lon)
    sub = R_EARTH_M * g.subsatellite_g()
    return (sub - site_g) @ enu_dcm(lat, lon).T  # (N, 3) east, north, up


def _times(n: int, step: float) -> list:
    return [float(x) for x in np.round((np.arange(n) - (n - 1) / 2.0) * step, 9)]


def _field(spec: PlanSpec, site, k: int, attitude: str, direction: str, times, seed: int) -> list:
    if site.landmarks_enu_km is not None:
        return [list(r) for r in site.landmarks_enu_km]
    lm = spec.scenario_base.get("landmarks", {})
    hsig = float(lm.get("height_sigma_m", DEFAULT_HEIGHT_SIGMA_M))
    w_fp = _footprint_half_width_m(spec)
    rng = np.random.default_rng(seed)
    if attitude == "site_tracking":
        hw = min(float(lm.get("half_width_km", DEFAULT_HALF_WIDTH_KM)) * 1e3, 0.75 * w_fp)
        xy = rng.uniform(-hw, hw, size=(k, 2))
    else:
        track = ground_track_t(spec, site, direction, times)[:, :2]
        d = track[-1] - track[0]
        length = float(np.linalg.norm(d))
        along = d / length if length > 0 else np.array([0.0, 1.0])
        across = np.array([-along[1], along[0]])
        w = 0.9 * w_fp
        extent = length + 2 * w_fp
        n = max(int(round(k * extent * 2 * w / (2 * w_fp) ** 2)), k)
        s = rng.uniform(-w_fp, length + w_fp, size=n)
        c = rng.uniform(-w, w, size=n)
        xy = track[0] + s[:, None] * along + c[:, None] * across
        k = n
    h = rng.normal(0.0, hsig, size=k) if hsig > 0 else np.zeros(k)
    return [[round(float(x) / 1e3, 6), round(float(y) / 1e3, 6), round(float(z) / 1e3, 6)] for (x, y), z in zip(xy, h)]


def pass_entry(spec: PlanSpec, site_index: int, direction: str, attitude: str, yaw_deg: float, images: int, k: int) -> dict:
    """The scenario ``[[passes]]`` table of one option."""
    site = spec.sites[site_index]
    step = spec.image_interval_s[attitude]
    times = _times(images, step)
    seed = int(
        spec.seed * 1_000_003
        + site_index * 7919
        + (direction == "descending") * 104729
        + (attitude == "nadir") * 1299709
        + images * 31
        + k
    ) % (2**63)
    entry = {
        "site_lat_deg": site.lat_deg,
        "site_lon_deg": site.lon_deg,
        "direction": direction,
        "attitude": attitude,
        "t_s": times,
        "landmarks": {
            "layout": "explicit",
            "enu_km": _field(spec, site, k, attitude, direction, times, seed),
            "placement": "sphere",
        },
    }
    if site.height_m:
        entry["site_height_m"] = site.height_m
    if yaw_deg:
        entry["yaw_deg"] = yaw_deg
    return entry


def scenario_document(
    spec: PlanSpec, entries, name: str | None = None, description: str = "", effects: dict | None = None, star_entries=()
) -> dict:
    """A scenario document (what a scenario TOML parses to) for a list of pass entries and star-frame
    segment entries (``star_options``)."""
    doc = {k: v for k, v in spec.scenario_base.items()}
    doc["name"] = name or spec.name
    doc["description"] = description or doc.get("description", "")
    doc.setdefault("misalignment", {"true_arcsec": [20.0, -15.0, 40.0]})
    doc["passes"] = [dict(e) for e in entries]
    if star_entries:
        doc["star_frames"] = [dict(e) for e in star_entries]
    if not doc["passes"]:
        del doc["passes"]  # a campaign of star frames alone
    if not star_entries:
        doc.pop("stars", None)  # [stars] without [[star_frames]]: nothing to simulate
    if effects:
        doc["effects"] = {k: [float(x) for x in np.atleast_1d(v)] for k, v in effects.items()}
    return doc


def pass_options(spec: PlanSpec) -> list:
    """Every pass option of the search space, in a fixed order."""
    out: list[Any] = []
    for si, site in enumerate(spec.sites):
        for direction in site.directions:
            u_deg = float(np.degrees(_orbit(spec).passage(np.radians(site.lat_deg), direction).u_rad) % 360.0)
            for attitude in spec.attitudes:
                for yaw in spec.yaw_deg:
                    for n in spec.images_per_pass:
                        lms = spec.landmarks_per_image if site.landmarks_enu_km is None else (len(site.landmarks_enu_km),)
                        for k in lms:
                            cost = (
                                spec.cost_per_pass
                                + spec.cost_per_image * n
                                + site.cost
                                + (spec.cost_per_site_tracking_pass if attitude == "site_tracking" else spec.cost_per_nadir_pass)
                            )
                            out.append(
                                PassOption(
                                    index=len(out),
                                    site=site.name,
                                    site_index=si,
                                    direction=direction,
                                    attitude=attitude,
                                    yaw_deg=float(yaw),
                                    images=int(n),
                                    landmarks_per_image=int(k),
                                    u_deg=u_deg,
                                    cost=float(cost),
                                    entry=pass_entry(spec, si, direction, attitude, float(yaw), int(n), int(k)),
                                )
                            )
    return out + (star_options(spec, len(out)) if spec.star_segments else [])


def _star_entries(spec: PlanSpec) -> list[tuple[str, str, dict]]:
    """(attitude, where, ``[[star_frames]]`` entry) of each star-frame candidate (module docstring)."""
    orbit = _orbit(spec)
    r, v = orbit.state(np.array([0.0]))
    h = np.cross(r[0], v[0])
    h = h / np.linalg.norm(h)
    out = []
    for att in spec.star_segments:
        if att == "inertial_hold":
            dt = spec.star_frame_interval_s["inertial_hold"]
            for frames in spec.star_frames_per_segment:
                t = {"start": 0.0, "stop": round((frames - 1) * dt, 9), "step": dt}
                for where, d in (("orbit normal", h), ("anti-normal", -h)):
                    ra = float(np.degrees(np.arctan2(d[1], d[0])) % 360.0)
                    dec = float(np.degrees(np.arcsin(np.clip(d[2], -1.0, 1.0))))
                    out.append((att, where, {"attitude": att, "ra_deg": round(ra, 6), "dec_deg": round(dec, 6), "t_s": t}))
        else:  # zenith, night side, one orbit
            dt = spec.star_frame_interval_s["zenith"]
            period = 2 * np.pi / orbit.mean_motion_rad_s
            t = {"start": 0.0, "stop": round(float(np.floor(period / dt) * dt), 9), "step": dt}
            out.append((att, "night side", {"attitude": "zenith", "night_only": True, "t_s": t}))
    return out


def star_options(spec: PlanSpec, first_index: int) -> list:
    """The star-frame segment candidates of the plan (module docstring), indexed from ``first_index``; a
    segment that sees no star is left out. Each is counted on its noise-free campaign (its images: the
    frames that see a star; ``landmarks_per_image``: its mean number of stars per frame)."""
    from boresight.observations.simulate import nominal_observations
    from orbits.scenario import scenario_from_dict

    out: list[Any] = []
    for att, where, entry in _star_entries(spec):
        doc = scenario_document(spec, [], name="star-option", star_entries=[entry])
        obs = nominal_observations(scenario_from_dict(doc, source=f"{spec.source}: star segment {att} ({where})"))
        n = int(obs.n_images)
        if n == 0 or obs.n_observations == 0:
            continue
        out.append(
            PassOption(
                index=first_index + len(out),
                site="sky",
                site_index=-1,
                direction=where,
                attitude=att,
                yaw_deg=0.0,
                images=n,
                landmarks_per_image=int(round(obs.n_observations / n)),
                u_deg=0.0,
                cost=float(spec.cost_per_pass + spec.cost_per_star_segment + spec.cost_per_image * n),
                entry=entry,
                kind="stars",
            )
        )
    return out
