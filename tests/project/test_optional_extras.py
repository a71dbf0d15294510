"""A missing optional library (issue 31, class 7; code review 2026-11-27 §7.3, §8.2 item 2).

Every command that draws figures runs in a child process whose ``sys.modules["matplotlib"]`` is
None (what ``import matplotlib`` sees when the ``plot`` extra is not installed). The property:
exit 0, every non-figure output written (no half-written folder), no PNG, and the one sentence of
``boresight.reporting.plots.MISSING`` printed once. Before issue 31, ``diagnose`` and ``pointing
sea-sky`` exited 70 ("internal error") and ``diagnose`` left ``diagnosis.json`` without
``diagnosis.md``. Also: ``import boresight`` and the Kalman filter need neither matplotlib nor
filterpy (filterpy is a test extra, imported only by the reference ``kalman_filter_filterpy``).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest
from extras_cases import EXTRA_REQUESTS, PLOTTING_COMMANDS, TLE
from paths import ROOT

from orbits.errors import extra_hint

CHILD = textwrap.dedent(
    """
    import sys
    sys.modules["matplotlib"] = None  # the plot extra is not installed
    from boresight.cli.main import main
    sys.exit(main(sys.argv[1:]))
    """
)


def _child(argv, cwd):
    return subprocess.run([sys.executable, "-c", CHILD, *argv], cwd=cwd, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    folder = tmp_path_factory.mktemp("no-matplotlib")
    r = _child(["simulate", "kiev2012-kalman20", "--out", str(folder)], ROOT)
    assert r.returncode == 0, r.stderr
    return folder


@pytest.mark.parametrize("name, argv, outputs", PLOTTING_COMMANDS, ids=[c[0] for c in PLOTTING_COMMANDS])
def test_every_plotting_command_skips_its_figures_without_matplotlib(out, name, argv, outputs):
    from boresight.reporting.plots import MISSING

    obs = out / "kiev2012-kalman20.ecsv"  # the module's simulated file
    r = _child([a.replace("OUT", str(out)).replace("OBS", str(obs)) for a in argv], ROOT)
    both = r.stdout + r.stderr
    assert r.returncode == 0, both
    assert "Traceback" not in both and "internal error" not in both, both
    assert both.count(MISSING) == 1, both
    for rel in outputs:
        assert (out / rel).exists(), (rel, both)
    assert not list(out.rglob("*.png")), list(out.rglob("*.png"))


def test_import_and_the_kalman_filter_need_neither_matplotlib_nor_filterpy():
    code = textwrap.dedent(
        """
        import sys
        sys.modules["matplotlib"] = None
        sys.modules["filterpy"] = None
        import numpy as np, boresight
        from boresight.core.algorithms.kalman import kalman_filter
        from boresight.reporting.plots import available
        assert available() is False
        obs = boresight.simulate("scenarios/kiev2012-kalman20.toml", np.random.default_rng(1))
        est = boresight.estimate(obs, algorithm="kalman")
        print(est.theta)
        """
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr


def test_filterpy_is_a_test_extra_not_a_core_dependency():
    import tomllib

    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = " ".join(meta["dependencies"]).lower()
    assert "filterpy" not in core and "matplotlib" not in core, meta["dependencies"]
    assert any("filterpy" in d for d in meta["optional-dependencies"]["test"])


@pytest.mark.parametrize("module, extra, argv", EXTRA_REQUESTS, ids=[e[0] for e in EXTRA_REQUESTS])
def test_a_missing_extra_is_refused_naming_it_and_writes_nothing(tmp_path, module, extra, argv):
    """Every optional extra a request needs: exit 1 (not 70), one line naming ``boresight[extra]``,
    and no output folder or file (the dask engine used to exit 70 after making ``--out`` with an
    "interrupted study" checkpoint in it)."""
    (tmp_path / "in").mkdir()
    tle = tmp_path / "in" / "sat.tle"
    tle.write_text(TLE)
    out = tmp_path / "out"
    code = CHILD.replace('sys.modules["matplotlib"] = None', f"sys.modules[{module!r}] = None")
    args = [a.replace("OUT", str(out)).replace("TLE", str(tle)) for a in argv]
    r = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stdout + r.stderr
    assert f"boresight[{extra}]" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert extra_hint(extra) in r.stderr, r.stderr  # the README's install form, not the PyPI one
    assert not out.exists()
