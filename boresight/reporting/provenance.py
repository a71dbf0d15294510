"""Provenance of a study's outputs: the inputs and versions written beside every result.

Used by the commands (``montecarlo.json``, ``sensitivity.json``) and by any report that must say
exactly what produced its numbers: ``scenario_dict`` (the validated scenario, every field),
``versions`` (python, numpy, scipy, astropy, boresight) and ``study_payload``; the files are written
by ``boresight.files.write_json``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["scenario_dict", "versions", "study_payload"]


def scenario_dict(scenario) -> dict:
    """The scenario as a JSON-ready dict (every field, nested dataclasses included)."""
    from dataclasses import asdict

    def clean(v):
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        if isinstance(v, np.generic):
            return v.item()
        return v

    d = asdict(scenario)
    # hidden effects (orbits.effects) as {name: [values]}; omitted when there are none (star frames too)
    for key in ("effects", "unmodelled", "stars", "star_frames"):
        if key in d and not d[key]:
            del d[key]
    if d.get("landmark_sight") == "geometric":  # the default: absent, as before the key (docs/stars.md)
        del d["landmark_sight"]
    if "effects" in d:
        d["effects"] = {k: np.asarray(v).tolist() for k, v in scenario.effects.items()}
    return clean(d)


def versions() -> dict:
    import platform

    import astropy
    import scipy

    import boresight

    return {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "astropy": astropy.__version__,
        "boresight": boresight.__version__,
    }


def study_payload(command: str, args, scenario, result, **fields) -> dict:
    """The JSON product of a study command (``montecarlo``, ``sensitivity``): the command line,
    the scenario, the engine's inputs (``result.inputs``), then the command's own ``fields``,
    the wall time and the versions — in that order (the file keeps it)."""
    import sys

    return {
        "command": f"boresight {command}",
        "argv": sys.argv[1:],
        "scenario_file": str(args.scenario),
        "scenario": scenario_dict(scenario),
        **result.inputs,
        **fields,
        "elapsed_s": result.elapsed_s,
        "versions": versions(),
    }
