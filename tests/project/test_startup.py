"""Start-up cost (issue 19): ``import boresight`` and every help / usage / version / typo path load
only what they use — numpy at most, never scipy, astropy, matplotlib or dask.

Each case runs in a fresh interpreter (a module imported by an earlier test would hide a
regression) and reports the third-party top-level packages in ``sys.modules`` afterwards. The
timing side is ``benchmarks/bench_startup.py`` (a benchmark, not a timed test).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from paths import ROOT

#: packages a start-up path must never load
HEAVY = ("scipy", "astropy", "matplotlib", "dask", "distributed", "threadpoolctl", "filterpy", "pandas")

_PROBE = """
import json, sys
{body}
mods = sorted(sys.modules)
print(json.dumps(mods))
"""

_CLI = """
import contextlib, io
from boresight.cli.main import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    try:
        main({argv!r})
    except SystemExit:
        pass
"""


def _loaded(body: str) -> list[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run(
        [sys.executable, "-c", _PROBE.format(body=body)], capture_output=True, text=True, env=env, cwd=ROOT, timeout=120
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _heavy(mods: list[str]) -> list[str]:
    return sorted({m.split(".")[0] for m in mods if m.split(".")[0] in HEAVY})


def test_bare_import_loads_only_the_package_itself():
    mods = _loaded("import boresight")
    assert _heavy(mods) == []
    assert "numpy" not in mods
    assert [m for m in mods if m.startswith(("boresight", "orbits"))] == ["boresight"]


def test_public_names_resolve_on_first_use():
    mods = _loaded("import boresight\nassert callable(boresight.estimate) and boresight.Estimate.__name__ == 'Estimate'")
    assert "boresight.core.estimation" in mods
    import boresight

    assert set(boresight.__all__) <= set(dir(boresight))
    assert "NormalEquations" not in boresight.__all__
    with pytest.raises(AttributeError, match="no attribute 'NormalEquations'"):
        boresight.NormalEquations  # noqa: B018 - an internal, imported from boresight.core.gls.normal_equations


@pytest.mark.parametrize(
    "argv",
    [
        ["--help"],
        ["--version"],
        [],
        ["estmate"],
        ["estimate", "--help"],
        ["montecarlo", "--help"],
        ["sensitivity", "--help"],
        ["plan", "--help"],
        ["diagnose", "--help"],
        ["pointing", "--help"],
        ["simulate", "--help"],
        ["ingest", "--help"],
        ["reproduce", "--help"],
        ["check", "--help"],
        ["docs", "--help"],
    ],
)
def test_help_usage_version_and_typos_load_no_heavy_package(argv):
    mods = _loaded(_CLI.format(argv=argv))
    assert _heavy(mods) == []
    # nor any library module beyond the few the options' defaults come from: the command
    # registry's names, the Monte Carlo block sizes (montecarlo.seeding, not the engines) and the
    # limits/rotation constants they import (issue 19)
    library = [
        m for m in mods if m.startswith(("boresight.", "orbits")) and not m.startswith(("boresight.cli", "boresight.errors"))
    ]
    assert set(library) <= LIBRARY_AT_HELP, sorted(set(library) - LIBRARY_AT_HELP)


#: the library modules a help / usage / version path may load (everything else waits for a command)
LIBRARY_AT_HELP = {
    "boresight.core",
    "boresight.core.losses",
    "boresight.core.registry",
    "boresight.studies",
    "boresight.studies.montecarlo",
    "boresight.studies.montecarlo.seeding",
    "boresight.files",
    "boresight.reporting",
    "boresight.reporting.outputs",
    "boresight.reporting.plots",
    "boresight.reporting.provenance",
    "orbits",
    "orbits.errors",
    "orbits.limits",
    "orbits.rotations",
}


def test_import_orbits_errors_does_not_build_the_world():
    mods = _loaded("import orbits.errors\nimport boresight.errors")
    assert _heavy(mods) == []
    assert "orbits.scenario" not in mods
