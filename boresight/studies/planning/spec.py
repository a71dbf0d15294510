"""The plan file: what to plan for, validated like a scenario file.

A plan file (TOML, ``docs/planning.md``) holds

* the tables a scenario file has for the world and the sensors — ``[orbit]``, ``[camera]``,
  ``[star_tracker]``, ``[gnss]``, ``[pixel]``, ``[catalogue]``, ``[landmarks]`` (the default
  landmark field of a site), ``[stars]`` (the star catalogue and magnitude limit of star-frame
  segments), ``earth_model``, ``epoch_utc`` — with the same keys, checked by the
  same code (``orbits.scenario_from_dict`` on a probe scenario, so the messages are the
  scenario's);
* ``[[sites]]``: candidate ground sites (``name``, ``lat_deg``, ``lon_deg``, optional
  ``height_m``, ``directions``, ``cost``, and ``landmarks_enu_km`` — a landmark catalogue of
  the site, east/north/up in km — instead of a generated field);
* ``[requirements]``: ``sigma_theta_arcsec`` (target 1σ per axis), ``[requirements.effects]``
  (the effects that must be separable and the size each must be detectable at, written as a
  scenario's ``[effects]`` table), ``alpha`` (family-wise level), ``n_candidates`` (how many
  catalogue effects the diagnosis tests: the Bonferroni divisor), ``power``;
* ``[cost]``: ``per_pass``, ``per_image``, ``per_site_tracking_pass``, ``per_nadir_pass``,
  ``per_star_segment`` (operator weights; a site's own ``cost`` is added per pass over it; a star-frame
  segment costs ``per_pass + per_star_segment + per_image`` × its frames) and ``unit``, the unit the
  weights are written in, printed on plan.png's cost axis and in summary.md (default
  ``"pass-equivalents"`` when ``per_pass`` is 1 — every other weight is then a fraction of a pass —,
  else it must be given: ``cost_unit``);
* ``[search]``: ``passes = [min, max]`` (campaign elements: passes and star-frame segments),
  ``attitudes``, ``yaw_deg``, ``images_per_pass``, ``landmarks_per_image``,
  ``image_interval_s = {nadir, site_tracking}``, ``star_segments`` (``"inertial_hold"``, ``"zenith"``:
  star-frame candidates, needs ``[stars]``; ``options.star_options``), ``star_frames_per_segment``,
  ``star_frame_interval_s = {inertial_hold, zenith}``, ``max_candidates``, ``seed``.

Every error is a ``PlanError`` (a ``BoresightError`` and ``ValueError``) naming the file, the
key as written and the value; errors in the shared tables are the scenario's ``ScenarioError``
naming the plan file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from boresight.errors import PlanError

__all__ = ["PlanError", "PlanSpec", "Site", "load_plan", "plan_from_dict", "SHARED_TABLES"]

#: tables a plan shares with a scenario file (same keys, same checks)
SHARED_TABLES = ("orbit", "camera", "star_tracker", "gnss", "pixel", "catalogue", "landmarks", "misalignment", "stars")
_SHARED_TOP = ("name", "description", "earth_model", "epoch_utc")
_ATTITUDES = ("nadir", "site_tracking")
_STAR_SEGMENTS = ("inertial_hold", "zenith")
_DIRECTIONS = ("ascending", "descending")


@dataclass(frozen=True)
class Site:
    """A candidate ground site. ``landmarks_enu_km`` (M, 3) is its catalogue, or None."""

    name: str
    lat_deg: float
    lon_deg: float
    height_m: float = 0.0
    directions: tuple = _DIRECTIONS
    cost: float = 0.0
    landmarks_enu_km: tuple | None = None


@dataclass(frozen=True)
class PlanSpec:
    """A validated plan (units in the field names)."""

    name: str
    source: str
    scenario_base: dict  # the shared tables, as a scenario document without [[passes]]
    sites: tuple
    sigma_theta_arcsec: tuple
    effects: dict  # name -> (k,) required size in the effect's units
    lookalikes: tuple = ()  # catalogue effects the diagnosis also tests (each floated in turn)
    scanned_rivals: tuple = ()  # ("alignment_step",): scored from the θ blocks of the passes after a boundary (fisher.step_terms)
    alpha: float = 0.01
    n_candidates: int = 8
    power: float = 0.95
    cost_per_pass: float = 1.0
    cost_per_image: float = 0.0
    cost_per_site_tracking_pass: float = 0.0
    cost_per_nadir_pass: float = 0.0
    passes_min: int = 1
    passes_max: int = 4
    attitudes: tuple = _ATTITUDES
    yaw_deg: tuple = (0.0,)
    images_per_pass: tuple = (20,)
    landmarks_per_image: tuple = (12,)
    image_interval_s: dict = field(default_factory=lambda: {"nadir": 0.5, "site_tracking": 5.0})
    star_segments: tuple = ()  # star-frame candidates ("inertial_hold", "zenith"); () none
    star_frames_per_segment: tuple = (20,)
    star_frame_interval_s: dict = field(default_factory=lambda: {"inertial_hold": 10.0, "zenith": 240.0})
    cost_per_star_segment: float = 0.0
    cost_unit: str = "pass-equivalents"  # [cost] unit: what one unit of cost is (the axis of plan.png)
    max_candidates: int = 200_000
    seed: int = 1
    description: str = ""

    @property
    def effect_names(self) -> list:
        return list(self.effects)


# ---------------------------------------------------------------------------- checks


def _show(v) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


class _Ctx:
    def __init__(self, source):
        self.source = source

    def fail(self, where, value, problem):
        raise PlanError(f"{self.source}: {where} = {_show(value)}: {problem}")

    def number(self, where, v, lo=None, hi=None, lo_open=False, unit=""):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(where, v, f"must be a number{' (' + unit + ')' if unit else ''}")
        x = float(v)
        if not math.isfinite(x):
            self.fail(where, v, "must be finite")
        if lo is not None and (x <= lo if lo_open else x < lo):
            self.fail(where, v, f"must be {'>' if lo_open else '≥'} {lo:g}{' ' + unit if unit else ''}")
        if hi is not None and x > hi:
            self.fail(where, v, f"must be ≤ {hi:g}{' ' + unit if unit else ''}")
        return x

    def whole(self, where, v, lo=None, hi=None):
        if isinstance(v, float) and math.isfinite(v) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(where, v, "must be a whole number")
        if lo is not None and v < lo:
            self.fail(where, v, f"must be ≥ {lo}")
        if hi is not None and v > hi:
            self.fail(where, v, f"must be ≤ {hi}")
        return int(v)

    def choices(self, where, v, allowed):
        if not isinstance(v, str) or v not in allowed:
            self.fail(where, v, "must be one of " + ", ".join(repr(a) for a in allowed))
        return v

    def array(self, where, v, item, min_len=1):
        if not isinstance(v, list) or len(v) < min_len:
            self.fail(where, v, f"must be an array of at least {min_len} value(s)")
        return tuple(item(f"{where}[{i}]", x) for i, x in enumerate(v))

    def table(self, where, v, keys):
        if not isinstance(v, dict):
            self.fail(where, v, "must be a table")
        unknown = sorted(set(v) - set(keys))
        if unknown:
            from orbits.errors import did_you_mean

            self.fail(
                f"{where}.{unknown[0]}",
                v[unknown[0]],
                f"unknown key{did_you_mean(unknown[0], keys)}; expected some of {list(keys)}",
            )
        return v


def _effect_sizes(table, where, source):
    """The required effect sizes through the catalogue's own parser (``orbits.effects``)."""
    try:
        from orbits.effects import effect_sizes
    except ImportError:  # the effects catalogue is not installed in this version
        if table:
            raise PlanError(
                f"{source}: [requirements.effects] needs the effects catalogue (orbits.effects), "
                "which this installation does not have"
            ) from None
        return {}

    def err(msg):
        return PlanError(f"{source}: {msg}")

    sizes = effect_sizes(table, where=where, error=err)
    return {k: np.asarray(sizes[k], float) for k in sizes}


def plan_from_dict(data: dict, source: str = "<dict>") -> PlanSpec:
    """Validate a parsed plan document and build the ``PlanSpec``."""
    ctx = _Ctx(source)
    if not isinstance(data, dict):
        raise PlanError(f"{source}: a plan must be a TOML document (a table), got {type(data).__name__}")
    known = set(SHARED_TABLES) | set(_SHARED_TOP) | {"sites", "requirements", "cost", "search"}
    unknown = sorted(set(data) - known)
    if unknown:
        ctx.fail(unknown[0], data[unknown[0]], f"unknown key; a plan file has {sorted(known)}")
    for req in ("orbit", "camera", "sites", "requirements"):
        if req not in data:
            raise PlanError(
                f"{source}: missing required table [{req}] ([orbit], [camera], [[sites]] and [requirements] are required)"
            )

    # ---- shared tables: checked by the scenario's own code on a probe scenario
    base = {k: data[k] for k in (*_SHARED_TOP, *SHARED_TABLES) if k in data}
    base.setdefault("name", "plan")
    sites = _sites(ctx, data["sites"])
    from orbits.scenario import scenario_from_dict

    probe = dict(
        base,
        passes=[
            {
                "site_lat_deg": sites[0].lat_deg,
                "site_lon_deg": sites[0].lon_deg,
                "t_s": [0.0],
                "direction": sites[0].directions[0],
            }
        ],
    )
    scenario_from_dict(probe, source=source)
    orbit = base["orbit"]
    inc = float(orbit.get("inclination_deg", 0.0))
    reach = min(inc, 180.0 - inc)
    for k, s in enumerate(sites):
        if abs(s.lat_deg) > reach + 1e-9:
            ctx.fail(
                f"sites[{k}].lat_deg",
                s.lat_deg,
                f"is never overflown: the orbit (inclination {inc:g}°) reaches latitudes up to ±{reach:g}°",
            )

    # ---- requirements
    req = ctx.table(
        "[requirements]", data["requirements"], ("sigma_theta_arcsec", "effects", "alpha", "n_candidates", "power", "lookalikes")
    )
    if "sigma_theta_arcsec" not in req:
        raise PlanError(f"{source}: [requirements] needs sigma_theta_arcsec (the target 1σ of θ per axis, arcsec)")
    st = req["sigma_theta_arcsec"]
    if isinstance(st, (int, float)) and not isinstance(st, bool):
        st = [st] * 3
    if not isinstance(st, list) or len(st) != 3:
        ctx.fail("[requirements] sigma_theta_arcsec", st, "must be a number or an array of three numbers (arcsec, per axis)")
    sig = tuple(
        ctx.number(f"[requirements] sigma_theta_arcsec[{i}]", x, 0, lo_open=True, unit="arcsec") for i, x in enumerate(st)
    )
    alpha = ctx.number("[requirements] alpha", req.get("alpha", 0.01), 0, 0.5, lo_open=True)
    power = ctx.number("[requirements] power", req.get("power", 0.95), 0.5, 0.9999)
    effects = _effect_sizes(req.get("effects", {}), "requirements.effects", source)
    for name, v in effects.items():
        if name in CAMPAIGN_WIDE:
            ctx.fail(
                f"[requirements.effects] {name}",
                v.tolist(),
                "cannot be planned: its columns depend on the whole campaign's times "
                "(the planner sums per-pass blocks); check it with boresight diagnose on a simulated campaign",
            )
        if not np.any(v != 0):
            ctx.fail(f"[requirements.effects] {name}", v.tolist(), "a required detectable size must not be zero")
    look, scanned = _lookalikes(ctx, req.get("lookalikes", "catalogue"), effects)
    n_cand = ctx.whole("[requirements] n_candidates", req.get("n_candidates", _n_catalogue()), max(1, len(effects)), 1000)

    # ---- cost
    cost = ctx.table(
        "[cost]",
        data.get("cost", {}),
        ("per_pass", "per_image", "per_site_tracking_pass", "per_nadir_pass", "per_star_segment", "unit"),
    )
    c = {
        k: ctx.number(f"[cost] {k}", cost.get(k, d), 0)
        for k, d in (
            ("per_pass", 1.0),
            ("per_image", 0.0),
            ("per_site_tracking_pass", 0.0),
            ("per_nadir_pass", 0.0),
            ("per_star_segment", 0.0),
        )
    }

    cost_unit = _cost_unit(ctx, cost, c["per_pass"])

    # ---- search space
    s = ctx.table(
        "[search]",
        data.get("search", {}),
        (
            "passes",
            "attitudes",
            "yaw_deg",
            "images_per_pass",
            "landmarks_per_image",
            "image_interval_s",
            "star_segments",
            "star_frames_per_segment",
            "star_frame_interval_s",
            "max_candidates",
            "seed",
        ),
    )
    passes = s.get("passes", [1, 4])
    if isinstance(passes, int) and not isinstance(passes, bool):
        passes = [1, passes]
    if not isinstance(passes, list) or len(passes) != 2:
        ctx.fail("[search] passes", passes, "must be [min, max] (the number of passes of a campaign) or a maximum")
    pmin = ctx.whole("[search] passes[0]", passes[0], 1, 50)
    pmax = ctx.whole("[search] passes[1]", passes[1], pmin, 50)
    att = ctx.array("[search] attitudes", s.get("attitudes", list(_ATTITUDES)), lambda w, v: ctx.choices(w, v, _ATTITUDES))
    yaw = ctx.array("[search] yaw_deg", s.get("yaw_deg", [0.0]), lambda w, v: ctx.number(w, v, -360, 360, unit="deg"))
    ipp = ctx.array("[search] images_per_pass", s.get("images_per_pass", [20]), lambda w, v: ctx.whole(w, v, 1, 2000))
    lpi = ctx.array("[search] landmarks_per_image", s.get("landmarks_per_image", [12]), lambda w, v: ctx.whole(w, v, 3, 500))
    iv = ctx.table("[search] image_interval_s", s.get("image_interval_s", {}), _ATTITUDES)
    interval = {
        a: ctx.number(f"[search] image_interval_s.{a}", iv.get(a, d), 0, 600, lo_open=True, unit="s")
        for a, d in (("nadir", 0.5), ("site_tracking", 5.0))
    }
    stars = _star_search(ctx, s, "stars" in data)
    maxc = ctx.whole("[search] max_candidates", s.get("max_candidates", 200_000), 1, 10_000_000)
    seed = ctx.whole("[search] seed", s.get("seed", 1), 0, 2**63 - 1)
    return PlanSpec(
        name=str(base["name"]),
        source=source,
        scenario_base=base,
        sites=sites,
        sigma_theta_arcsec=sig,
        effects=effects,
        lookalikes=look,
        scanned_rivals=scanned,
        alpha=alpha,
        n_candidates=n_cand,
        power=power,
        cost_per_pass=c["per_pass"],
        cost_per_image=c["per_image"],
        cost_per_site_tracking_pass=c["per_site_tracking_pass"],
        cost_per_nadir_pass=c["per_nadir_pass"],
        passes_min=pmin,
        passes_max=pmax,
        attitudes=tuple(dict.fromkeys(att)),
        yaw_deg=tuple(dict.fromkeys(yaw)),
        images_per_pass=tuple(dict.fromkeys(ipp)),
        landmarks_per_image=tuple(dict.fromkeys(lpi)),
        image_interval_s=interval,
        cost_per_star_segment=c["per_star_segment"],
        cost_unit=cost_unit,
        **stars,
        max_candidates=maxc,
        seed=seed,
        description=str(base.get("description", "")),
    )


def _star_search(ctx, s, has_stars) -> dict:
    """``star_segments``, ``star_frames_per_segment``, ``star_frame_interval_s`` of ``[search]`` (none: no
    star-frame candidates); the segments need the plan's ``[stars]`` (catalogue and magnitude limit)."""
    seg = ctx.array(
        "[search] star_segments", s.get("star_segments", []), lambda w, v: ctx.choices(w, v, _STAR_SEGMENTS), min_len=0
    )
    if seg and not has_stars:
        ctx.fail(
            "[search] star_segments",
            list(seg),
            "star-frame candidates need a [stars] table (catalogue, mag_limit_hp: the stars the camera detects)",
        )
    fps = ctx.array(
        "[search] star_frames_per_segment", s.get("star_frames_per_segment", [20]), lambda w, v: ctx.whole(w, v, 1, 2000)
    )
    iv = ctx.table("[search] star_frame_interval_s", s.get("star_frame_interval_s", {}), _STAR_SEGMENTS)
    interval = {
        a: ctx.number(f"[search] star_frame_interval_s.{a}", iv.get(a, d), 0, 3600, lo_open=True, unit="s")
        for a, d in (("inertial_hold", 10.0), ("zenith", 240.0))
    }
    return dict(
        star_segments=tuple(dict.fromkeys(seg)),
        star_frames_per_segment=tuple(dict.fromkeys(fps)),
        star_frame_interval_s=interval,
    )


#: catalogue effects whose columns depend on the whole campaign, so that the campaign's information
#: is not the sum of per-pass blocks: the planner cannot score them
# DECISION: alignment_drift is referred to the campaign's mean image time (orbits.effects.campaign_time_s);
# a pass scored alone has its own. The planner leaves it out of the look-alikes and refuses it as
# a requirement (docs/planning.md) rather than score it wrongly.
# alignment_step likewise as a requirement: its boundary is a time of the whole campaign, scanned by the
# diagnosis over the gaps between passes (Effect.scan), and a pass scored alone has no gap. As a rival
# (a look-alike of a required effect, named in [requirements] lookalikes) it is scored: over the passes
# after a boundary its columns are θ's, so its Gram blocks are suffix sums of the passes' θ rows
# (SCANNED_RIVALS, fisher.step_terms; the passes fly in the candidate's option order).
CAMPAIGN_WIDE = ("alignment_drift", "alignment_step")
#: campaign-wide effects the planner scores as rivals from the per-pass θ blocks (``fisher.step_terms``)
SCANNED_RIVALS = ("alignment_step",)


def _lookalikes(ctx, v, effects) -> tuple:
    """``lookalikes``: "catalogue" (every other catalogue effect, the diagnosis' candidates),
    "none", or a list of catalogue names. Returns (the per-pass look-alikes, the ``SCANNED_RIVALS`` among them)."""
    if not effects:
        return (), ()
    try:
        from orbits.effects import EFFECTS
    except ImportError:
        return (), ()
    if v == "catalogue":
        # DECISION: alignment_step is scored only when the list names it (opt-in), not in "catalogue" yet.
        # Scored by default, it moves the shipped plan's choice (kiev680: candidate 62671 → 40093, the old
        # choice's thermal η 0.84 → 2.96: its three Nairobi ascending passes fly before the descending ones,
        # and a step at that gap mimics thermal), which the worked example of docs/planning.md, its tests and
        # checks.detection_check (which cannot float a scanned boundary yet) must follow first.
        return tuple(n for n in EFFECTS if n not in effects and n not in CAMPAIGN_WIDE), ()
    if v == "none":
        return (), ()
    names = (
        ctx.array("[requirements] lookalikes", v, lambda w, x: ctx.choices(w, x, tuple(EFFECTS)), min_len=0)
        if isinstance(v, list)
        else ctx.fail("[requirements] lookalikes", v, 'must be "catalogue", "none" or a list of effect names')
    )
    for n in names:
        if n in CAMPAIGN_WIDE and n not in SCANNED_RIVALS:
            ctx.fail(
                "[requirements] lookalikes",
                n,
                "cannot be scored by the planner (its columns depend on the whole campaign's times)",
            )
    return (
        tuple(dict.fromkeys(n for n in names if n not in effects and n not in SCANNED_RIVALS)),
        tuple(dict.fromkeys(n for n in names if n in SCANNED_RIVALS)),
    )


def _n_catalogue() -> int:
    try:
        from orbits.effects import EFFECTS
    except ImportError:
        return 8
    return len(EFFECTS)


def _sites(ctx, raw) -> tuple:
    if not isinstance(raw, list) or not raw:
        ctx.fail("sites", raw, "[[sites]] must list at least one candidate site (an array of tables)")
    out, names = [], set()
    keys = ("name", "lat_deg", "lon_deg", "height_m", "directions", "cost", "landmarks_enu_km")
    for k, s in enumerate(raw):
        w = f"sites[{k}]"
        ctx.table(w, s, keys)
        for req in ("lat_deg", "lon_deg"):
            if req not in s:
                raise PlanError(f"{ctx.source}: {w} is missing {req}")
        name = s.get("name", f"site{k}")
        if not isinstance(name, str) or not name.strip() or len(name) > 60:
            ctx.fail(f"{w}.name", name, "must be a non-empty string of at most 60 characters")
        if name in names:
            ctx.fail(f"{w}.name", name, "repeats an earlier site's name")
        names.add(name)
        dirs = ctx.array(f"{w}.directions", s.get("directions", list(_DIRECTIONS)), lambda ww, v: ctx.choices(ww, v, _DIRECTIONS))
        lm = None
        if "landmarks_enu_km" in s:
            rows = s["landmarks_enu_km"]
            if not isinstance(rows, list) or len(rows) < 3:
                ctx.fail(f"{w}.landmarks_enu_km", rows, "must be an array of at least three [east, north, up] triples (km)")
            lm = tuple(
                tuple(ctx.number(f"{w}.landmarks_enu_km[{i}][{j}]", x, -2000, 2000, unit="km") for j, x in enumerate(r))
                if isinstance(r, list) and len(r) == 3
                else ctx.fail(f"{w}.landmarks_enu_km[{i}]", r, "must be [east, north, up] (km)")
                for i, r in enumerate(rows)
            )
        out.append(
            Site(
                name=name,
                lat_deg=ctx.number(f"{w}.lat_deg", s["lat_deg"], -90, 90, unit="deg"),
                lon_deg=ctx.number(f"{w}.lon_deg", s["lon_deg"], -360, 360, unit="deg"),
                height_m=ctx.number(f"{w}.height_m", s.get("height_m", 0.0), -500, 9000, unit="m"),
                directions=tuple(dict.fromkeys(dirs)),
                cost=ctx.number(f"{w}.cost", s.get("cost", 0.0), 0),
                landmarks_enu_km=lm,
            )
        )
    return tuple(out)


#: the shipped plans (a symlink to the repository's plans/ in a checkout; package data in a wheel)
PLAN_DIR = Path(__file__).resolve().parent / "plans"


def plan_path(name_or_path) -> Path:
    """An existing file path as given; otherwise a bare name (``"kiev680"``, with or without
    ``.toml``) is a shipped plan (``PLAN_DIR``) — the rule ``orbits.scenario_path`` applies to
    scenarios. A path that exists nowhere is returned as given (``load_plan`` names it).

    >>> plan_path("kiev680").name
    'kiev680.toml'
    """
    p = Path(name_or_path)
    if not p.exists() and p.parent == Path(".") and p.suffix in ("", ".toml"):
        if (PLAN_DIR / (p.stem + ".toml")).is_file():
            return PLAN_DIR / (p.stem + ".toml")
        from orbits.errors import did_you_mean

        shipped = sorted(q.stem for q in PLAN_DIR.glob("*.toml"))
        hint = did_you_mean(p.stem, shipped)
        if hint:  # a typo of a shipped name: say so rather than "no such file"
            raise PlanError(
                f"{name_or_path}: no such plan file, and not a shipped plan name{hint} (shipped: {', '.join(shipped)})"
            )
    return p


def load_plan(path) -> PlanSpec:
    """Read and validate a plan TOML file, given as a path or a shipped plan's name (``plan_path``)."""
    from orbits.files import read_toml

    path = plan_path(path)
    data = read_toml(path, PlanError, "plan")
    return plan_from_dict(data, source=str(path))


def _cost_unit(ctx, cost: dict, per_pass: float) -> str:
    """``[cost] unit``: a non-empty string; by default "pass-equivalents" when a pass costs 1 (the
    other weights are then fractions of a pass), and required otherwise — a cost axis without a unit
    is not a quantity."""
    unit = cost.get("unit")
    if unit is None:
        if per_pass == 1.0:
            return "pass-equivalents"
        raise PlanError(
            f"{ctx.source}: [cost] unit is not given, and [cost] per_pass = {per_pass:g} (not 1: a cost is not counted "
            'in passes): say what one unit of cost is, e.g. unit = "hours of ground-station time"'
        )
    if not isinstance(unit, str) or not unit.strip():
        ctx.fail("[cost] unit", unit, 'must be a non-empty string naming what one unit of cost is, e.g. "pass-equivalents"')
    return unit.strip()
