"""A small TOML writer for scenario documents (the standard library reads TOML, it does not write it).

Writes what a scenario holds: top-level strings and numbers, tables of scalars and arrays, and
arrays of tables (``[[passes]]``) whose values may be inline tables of arrays of arrays. The
round trip ``tomllib.loads(dumps(doc)) == doc`` is tested.

>>> import tomllib
>>> doc = {"name": "x", "orbit": {"altitude_km": 680.0}, "passes": [{"t_s": [0.0, 5.0], "landmarks": {"enu_km": [[1.0, 2.0, 0.1]]}}]}
>>> tomllib.loads(dumps(doc)) == doc
True
"""

from __future__ import annotations

import json
import math

__all__ = ["dumps"]


def _value(v, nonfinite: bool = False) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v) and nonfinite:
            return "nan"
        if math.isinf(v) and nonfinite:
            return "inf" if v > 0 else "-inf"
        if not math.isfinite(v):
            # The callers (boresight plan's chosen.toml) write the scenario the command already loaded (orbits/scenario.py
            # refuses a non-finite number) with the planner's grid values; the hostile-scenario tests pass allow_nonfinite.
            # internal: no user value reaches here non-finite (see above)
            raise ValueError(f"TOML writer: a scenario value must be finite, got {v!r}")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x, nonfinite) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x, nonfinite)}" for k, x in v.items()) + " }"
    if hasattr(v, "item"):  # numpy scalar
        return _value(v.item(), nonfinite)
    # internal: the planner's docs hold only TOML types (from a loaded scenario) and numpy scalars (handled above)
    raise TypeError(f"TOML writer: cannot write {type(v).__name__} {v!r}")


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def dumps(doc: dict, header: str = "", *, allow_nonfinite: bool = False) -> str:
    """TOML text of ``doc``; ``header`` lines are written as comments first. A NaN or infinite
    value is refused unless ``allow_nonfinite`` (the tests write hostile scenarios with it)."""
    nf = allow_nonfinite
    lines = [f"# {h}" if h else "#" for h in header.splitlines()] if header else []
    scalars = {
        k: v
        for k, v in doc.items()
        if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))
    }
    tables = {k: v for k, v in doc.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in doc.items() if k not in scalars and k not in tables}
    for k, v in scalars.items():
        lines.append(f"{_key(k)} = {_value(v, nf)}")
    for k, t in tables.items():
        lines.append("")
        lines.append(f"[{_key(k)}]")
        for kk, vv in t.items():
            lines.append(f"{_key(kk)} = {_value(vv, nf)}")
    for k, rows in arrays.items():
        for row in rows:
            lines.append("")
            lines.append(f"[[{_key(k)}]]")
            for kk, vv in row.items():
                lines.append(f"{_key(kk)} = {_value(vv, nf)}")
    return "\n".join(lines) + "\n"
