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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from boresight.studies.planning.spec import PlanSpec
from orbits.earth import R_EARTH_M, enu_dcm, geocentric_unit

__all__ = ["PassOption", "pass_options", "pass_entry", "scenario_document", "ground_track_t"]

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

    @property
    def label(self) -> str:
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
    spec: PlanSpec, entries, name: str | None = None, description: str = "", effects: dict | None = None
) -> dict:
    """A scenario document (what a scenario TOML parses to) for a list of pass entries."""
    doc = {k: v for k, v in spec.scenario_base.items()}
    doc["name"] = name or spec.name
    doc["description"] = description or doc.get("description", "")
    doc.setdefault("misalignment", {"true_arcsec": [20.0, -15.0, 40.0]})
    doc["passes"] = [dict(e) for e in entries]
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
    return out
