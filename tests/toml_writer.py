"""A minimal TOML writer for the tests (scenario dicts → files; no dependency on tomli_w).

Handles what scenarios hold: strings, booleans, integers, floats (nan/inf too), arrays, tables,
inline tables and arrays of tables.

>>> import tomllib
>>> d = {"name": "x", "orbit": {"altitude_km": 680.0}, "passes": [{"t_s": {"start": 0, "stop": 1, "step": 0.5}}], "v": [1, [2.5, True]]}
>>> tomllib.loads(dumps(d)) == d
True
"""

from __future__ import annotations

import json
import math


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def _key(k: str) -> str:
    return k if k and all(c.isalnum() or c in "_-" for c in k) else json.dumps(k)


def dumps(d: dict) -> str:
    lines, tables, arrays = [], [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            arrays.append((k, v))
        else:
            lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in tables:
        lines.append(f"\n[{_key(k)}]")
        lines += [f"{_key(a)} = {_value(x)}" for a, x in v.items()]
    for k, v in arrays:
        for item in v:
            lines.append(f"\n[[{_key(k)}]]")
            lines += [f"{_key(a)} = {_value(x)}" for a, x in item.items()]
    return "\n".join(lines) + "\n"
