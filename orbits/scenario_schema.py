"""Type and range checks of a scenario document, before anything is built from it.

``check_document(data, source)`` walks the parsed TOML and raises ``ScenarioError`` at the first
value of the wrong type or outside its range, naming the file, the key *as the user wrote it*
(``[orbit] altitude_km``, ``passes[0].t_s.step``) and the value::

    scenarios/x.toml: [orbit] altitude_km = -680: must be > 0 km

It also refuses, before anything is allocated, a campaign whose arrays would exceed the memory
budget (``orbits.limits``). Keys it does not know are left to the dataclass builders of
``orbits.scenario`` (which reject unknown keys by name), so a table another module adds
(``[effects]``) passes through untouched.

Rules (documented in ``docs/reliability.md``):

* a number is a TOML integer or float, never a boolean or a string; it must be finite;
* a whole number (``n``, ``seed``) is a TOML integer (a float with an integral value such as
  ``4.0`` is accepted, ``2.5`` is not);
* ranges are physical: altitude 0 < h ≤ 100 000 km, inclination 0..180°, latitude −90..90°,
  σ ≥ 0 and below a bound that keeps the small-angle model and the arithmetic meaningful
  (star-tracker σ and θ ≤ 36 000″ = 10°; pixel σ ≤ 1 m on the focal plane; GNSS σ ≤ 10⁷ m);
* ``name`` becomes a file name: letters, digits, ``. _ + -``, at most 100 characters, not
  starting with a dot (so ``name = "../../x"`` or an absolute path cannot leave ``--out``);
* ``[misalignment]`` takes ``true_arcsec`` *or* ``sigma0_arcsec``, not both.

>>> check_document({"orbit": {"altitude_km": -680}, "camera": {}, "passes": []}, "x.toml")
Traceback (most recent call last):
...
orbits.errors.ScenarioError: x.toml: [orbit] altitude_km = -680: must be > 0 km and ≤ 100000 km
"""

from __future__ import annotations

import math
import re
from typing import Any

from .errors import ScenarioError
from .limits import BYTES_PER_IMAGE, BYTES_PER_OBSERVATION, check_memory

__all__ = ["ScenarioError", "check_document", "NAME_PATTERN", "SMALL_ANGLE_LIMIT_ARCSEC"]

#: what a scenario name may look like (it becomes a file name inside --out)
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,99}")
#: the largest θ, star-tracker σ and θ prior σ a scenario may state: the one small-angle range
from .rotations import SMALL_ANGLE_LIMIT_ARCSEC  # noqa: E402 - re-exported (defined once in orbits.rotations)

#: the most passes a scenario may list (each is a geometry computed up front)
MAX_PASSES = 10000
#: the most landmarks ``[landmarks] n`` may ask for
MAX_LANDMARKS = 10**6


def _show(v: Any) -> str:
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


class _Ctx:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, value: Any, problem: str) -> None:
        raise ScenarioError(f"{self.source}: {where} = {_show(value)}: {problem}")


# ---------------------------------------------------------------------------- value checkers
# each checker(ctx, where, value) returns the checked value or raises


def _number(lo: Any = None, hi: Any = None, *, lo_open: bool = False, hi_open: bool = False, unit: str = "") -> Any:
    def check(ctx: Any, where: str, v: Any) -> Any:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            ctx.fail(where, v, f"must be a number{' (' + unit + ')' if unit else ''}, not {_kind(v)}")
        try:
            x = float(v)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            ctx.fail(where, v, "must be finite")
        u = f" {unit}" if unit else ""
        if lo is not None and (x <= lo if lo_open else x < lo):
            ctx.fail(
                where,
                v,
                f"must be {'>' if lo_open else '≥'} {lo:g}{u}" if hi is None else _range_msg(lo, hi, lo_open, hi_open, u),
            )
        if hi is not None and (x >= hi if hi_open else x > hi):
            ctx.fail(
                where,
                v,
                f"must be {'<' if hi_open else '≤'} {hi:g}{u}" if lo is None else _range_msg(lo, hi, lo_open, hi_open, u),
            )
        return v

    return check


def _range_msg(lo: Any, hi: Any, lo_open: Any, hi_open: Any, u: Any) -> str:
    if lo_open and not hi_open and lo == 0:
        return f"must be > 0{u} and ≤ {hi:g}{u}"
    return f"must be in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}{u}"


def _kind(v: Any) -> str:
    if isinstance(v, bool):
        return "a boolean"
    if isinstance(v, str):
        return "a string"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return type(v).__name__


def _whole(lo: Any = None, hi: Any = None) -> Any:
    def check(ctx: Any, where: str, v: Any) -> Any:
        if isinstance(v, float) and math.isfinite(v) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            ctx.fail(where, v, f"must be a whole number, not {_kind(v) if not isinstance(v, float) else 'a fraction'}")
        if lo is not None and v < lo:
            ctx.fail(where, v, f"must be ≥ {lo}")
        if hi is not None and v > hi:
            ctx.fail(where, v, f"must be ≤ {hi}")
        return v

    return check


def _string(choices: Any = None, pattern: Any = None, what: str = "") -> Any:
    def check(ctx: Any, where: str, v: Any) -> Any:
        if not isinstance(v, str):
            ctx.fail(where, v, f"must be a string{' (' + what + ')' if what else ''}, not {_kind(v)}")
        if choices is not None and v not in choices:
            ctx.fail(where, v, "must be one of " + ", ".join(repr(c) for c in choices))
        if pattern is not None and not pattern.fullmatch(v):
            ctx.fail(where, v, what)
        return v

    return check


def _array(n: int, item: Any) -> Any:
    """An array of exactly ``n`` values, each checked by ``item``."""
    word = {2: "two", 3: "three"}.get(n, str(n))

    def check(ctx: Any, where: str, v: Any) -> Any:
        if not isinstance(v, list) or len(v) != n:
            ctx.fail(
                where,
                v,
                f"must be an array of {word} numbers, not {_kind(v) if not isinstance(v, list) else f'{len(v)} value(s)'}",
            )
        for i, x in enumerate(v):
            item(ctx, f"{where}[{i}]", x)
        return v

    return check


def _triple(item: Any) -> Any:
    return _array(3, item)


def _epoch(ctx: Any, where: str, v: Any) -> Any:
    _string(what="an ISO 8601 UTC time")(ctx, where, v)
    try:
        from astropy.time import Time

        Time(v, scale="utc")
    except Exception:  # astropy raises ValueError and several of its own kinds
        ctx.fail(where, v, "must be an ISO 8601 UTC time such as '2012-01-31T00:00:00'")
    return v


_ANGLE = _number(-360, 360, unit="deg")
_SMALL_ANGLE = _number(-SMALL_ANGLE_LIMIT_ARCSEC, SMALL_ANGLE_LIMIT_ARCSEC, unit="arcsec (the small-angle range, 10°)")
_SIGMA_ARCSEC = _number(0, SMALL_ANGLE_LIMIT_ARCSEC, unit="arcsec")
_MODE = _string(("per_image", "per_pass", "both"))

_TABLES = {
    "orbit": {
        "altitude_km": _number(0, 100000, lo_open=True, unit="km"),
        # open: the orbit model (orbits.orbit.CircularOrbit) needs 0 < i < 180° (it refused 0 and
        # 180 itself, in its own words, after this check had passed them)
        "inclination_deg": _number(0, 180, lo_open=True, hi_open=True, unit="deg"),
        "raan_deg": _ANGLE,
    },
    "camera": {
        "focal_length_m": _number(0, 100, lo_open=True, unit="m"),
        "fov_deg": _number(0, 180, lo_open=True, hi_open=True, unit="deg"),
        "pixel_pitch_m": _number(0, 1, lo_open=True, unit="m"),
        # a calibrated detector (orbits.camera.CameraCalibration checks the combination)
        "principal_point_px": _array(2, _number(-1e7, 1e7, unit="px")),
        "u_axis": _string(("+x", "-x", "+y", "-y")),
        "v_axis": _string(("+x", "-x", "+y", "-y")),
        **{k: _number(-1e6, 1e6) for k in ("k1", "k2", "k3", "p1", "p2")},
    },
    "star_tracker": {
        "mount_deg": _triple(_ANGLE),
        "sigma_arcsec": _triple(_SIGMA_ARCSEC),
        "error_mode": _MODE,
    },
    "gnss": {"sigma_m": _number(0, 1e7, unit="m"), "error_mode": _MODE},
    "pixel": {"sigma_m": _number(0, 1, unit="m on the focal plane")},
    "catalogue": {"sigma_m": _number(0, 1e6, unit="m")},
    "misalignment": {"true_arcsec": _triple(_SMALL_ANGLE), "sigma0_arcsec": _SIGMA_ARCSEC},
}

_LANDMARKS = {
    "layout": _string(("kiev_m1_m4", "grid", "random", "explicit")),
    # DECISION: at most 10⁶ landmarks (a grid of n × n is also held by the memory budget);
    # n = 2**62 used to pass with the kiev_m1_m4 layout, which ignores it
    "n": _whole(1, MAX_LANDMARKS),
    "half_width_km": _number(0, 20000, lo_open=True, unit="km"),
    "height_m": _number(-1e4, 1e5, unit="m"),
    "height_sigma_m": _number(0, 1e5, unit="m"),
    "seed": _whole(0, 2**63 - 1),
    "enu_km": None,  # checked by _enu
    "placement": _string(("tangent_plane", "sphere")),
}

_PASS = {
    "site_lat_deg": _number(-90, 90, unit="deg"),
    "site_lon_deg": _ANGLE,
    "site_height_m": _number(-500, 9000, unit="m"),
    "direction": _string(("ascending", "descending")),
    "attitude": _string(("nadir", "site_tracking")),
    "yaw_deg": _ANGLE,
    "epoch_utc": _epoch,
}

_TOP = {
    "name": _string(
        pattern=NAME_PATTERN,
        what="a file-name stem: letters, digits, '.', '_', '+', '-', at most 100 characters, not starting with '.' or '-'",
    ),
    "description": _string(),
    "earth_model": _string(("spherical", "wgs84")),
    "epoch_utc": _epoch,
    "landmark_sight": _string(("geometric", "light_time+aberration")),
}


def _table(ctx: Any, where: str, v: Any) -> Any:
    if not isinstance(v, dict):
        ctx.fail(where, v, f"must be a table, not {_kind(v)}")
    return v


def _check_keys(ctx: Any, table: dict[str, Any], schema: dict[str, Any], label: str) -> None:
    for key, value in table.items():
        check = schema.get(key)
        if check is not None:
            check(ctx, f"{label}{key}", value)


def _enu(ctx: Any, where: str, v: Any) -> Any:
    if not isinstance(v, list) or not v:
        ctx.fail(where, v, "must be a non-empty array of [east, north, up] triples (km)")
    check_memory(f"{ctx.source}: {where} with {len(v)} landmarks", len(v) * 3 * 8 * 8)
    for i, row in enumerate(v):
        _triple(_number(-20000, 20000, unit="km"))(ctx, f"{where}[{i}]", row)
    return v


def _landmark_count(ctx: Any, lm: dict[str, Any], label: str) -> int:
    _table(ctx, label.rstrip(". ") or "[landmarks]", lm)
    _check_keys(ctx, lm, _LANDMARKS, label)
    if "enu_km" in lm:
        _enu(ctx, f"{label}enu_km", lm["enu_km"])
    layout = lm.get("layout", "kiev_m1_m4")
    if layout == "explicit" and "enu_km" not in lm:
        ctx.fail(f"{label}layout", layout, "needs enu_km, the [east, north, up] triples (km) of the landmarks")
    n = int(lm.get("n", 4))
    if layout == "grid":
        return n * n
    if layout == "random":
        return n
    if layout == "explicit":
        return len(lm.get("enu_km", [])) or 1
    return 4


def _times(ctx: Any, where: str, v: Any) -> int:
    """Check t_s (an array of seconds or {start, stop, step}); return the number of images."""
    if isinstance(v, dict):
        extra = sorted(set(v) - {"start", "stop", "step"})
        if extra:
            ctx.fail(f"{where}.{extra[0]}", v[extra[0]], "unknown key; t_s takes start, stop and step")
        for key in ("start", "stop", "step"):
            if key not in v:
                ctx.fail(where, v, f"needs start, stop and step, missing {key!r}")
            _number(-1e7, 1e7, unit="s")(ctx, f"{where}.{key}", v[key])
        start, stop, step = float(v["start"]), float(v["stop"]), float(v["step"])
        if not step > 0:
            ctx.fail(f"{where}.step", v["step"], "must be > 0 s")
        if stop < start:
            ctx.fail(f"{where}.stop", v["stop"], f"must be ≥ start = {v['start']!r}")
        count = math.floor((stop - start) / step + 0.5) + 1
        check_memory(
            f"{ctx.source}: {where} = {_show(v)} ({count:.3g} images)",
            count * BYTES_PER_IMAGE * 8,
            hint="use a larger step",
        )
        return count
    if not isinstance(v, list) or not v:
        ctx.fail(where, v, "must be a non-empty array of times (s) or a table {start, stop, step}")
    check_memory(f"{ctx.source}: {where} with {len(v)} times", len(v) * BYTES_PER_IMAGE * 8)
    for i, t in enumerate(v):
        _number(-1e7, 1e7, unit="s")(ctx, f"{where}[{i}]", t)
    return len(v)


def check_document(data: Any, source: str = "<dict>", passes_required: bool = True) -> None:
    """Type-, range- and size-check a parsed scenario document (see the module docstring).
    ``passes_required=False``: a star-frame scenario without landmark passes (its ``[stars]`` and
    ``[[star_frames]]`` tables are checked by ``orbits.star_campaign.star_tables``)."""
    ctx = _Ctx(source)
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: a scenario must be a TOML document (a table), got {_kind(data)}")
    missing = [t for t in ("orbit", "camera") + (("passes",) if passes_required else ()) if t not in data]
    if missing:
        raise ScenarioError(f"{source}: missing required table {missing[0]!r} ([orbit], [camera] and [[passes]] are required)")
    _check_keys(ctx, data, _TOP, "")
    for name, schema in _TABLES.items():
        if name in data:
            _table(ctx, f"[{name}]", data[name])
            _check_keys(ctx, data[name], schema, f"[{name}] ")
    mis = data.get("misalignment", {})
    if isinstance(mis, dict) and "true_arcsec" in mis and "sigma0_arcsec" in mis:
        raise ScenarioError(
            f"{source}: [misalignment] gives both true_arcsec = {_show(mis['true_arcsec'])} and sigma0_arcsec = "
            f"{_show(mis['sigma0_arcsec'])}: give one (a fixed true θ, or θ drawn per run from N(0, σ0²))"
        )
    default_landmarks = 4
    if "landmarks" in data:
        default_landmarks = _landmark_count(ctx, data["landmarks"], "[landmarks] ")
    passes = data.get("passes")
    if passes is None:
        return
    if not isinstance(passes, list) or not passes:
        ctx.fail("passes", passes, "[[passes]] must list at least one pass (an array of tables)")
    if len(passes) > MAX_PASSES:
        ctx.fail("passes", f"<{len(passes)} passes>", f"at most {MAX_PASSES} passes")
    n_images = n_landmarks = 0
    for k, p in enumerate(passes):
        where = f"passes[{k}]"
        _table(ctx, where, p)
        _check_keys(ctx, p, _PASS, f"{where}.")
        if "t_s" in p:
            n_images += _times(ctx, f"{where}.t_s", p["t_s"])
        n_landmarks += _landmark_count(ctx, p["landmarks"], f"{where}.landmarks.") if "landmarks" in p else default_landmarks
    # the campaign's arrays are (images × all passes' landmarks) per run
    check_memory(
        f"{source}: {n_images} images × {n_landmarks} landmarks (one run)",
        float(n_images) * (float(n_landmarks) * BYTES_PER_OBSERVATION + BYTES_PER_IMAGE),
        hint="fewer images or landmarks",
    )
