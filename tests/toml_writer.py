"""The tests' TOML writer: the library's (``boresight.studies.planning.toml_out``), letting NaN and
infinity through so hostile scenarios can be written (the library refuses them).

>>> import tomllib
>>> d = {"name": "x", "orbit": {"altitude_km": 680.0}, "passes": [{"t_s": {"start": 0, "stop": 1, "step": 0.5}}], "v": [1, [2.5, True]]}
>>> tomllib.loads(dumps(d)) == d
True
>>> tomllib.loads(dumps({"pixel": {"sigma_m": float("nan")}}))["pixel"]["sigma_m"]
nan
"""

from __future__ import annotations

from boresight.studies.planning import toml_out


def dumps(d: dict) -> str:
    """TOML text of ``d`` (NaN and infinity allowed)."""
    return toml_out.dumps(d, allow_nonfinite=True)
