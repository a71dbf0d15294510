"""Every command's --help ends with examples; --version; scenarios resolve by name (one rule)."""

import subprocess
import sys

import pytest
from paths import ROOT

import boresight
import orbits
from boresight.cli.main import build_parser


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return sub.choices


@pytest.mark.parametrize("name", sorted(_commands()))
def test_every_help_has_examples(name):
    p = _commands()[name]
    text = p.format_help()
    assert "examples:" in text and f"boresight {name}" in text.split("examples:")[1]


def test_version():
    out = subprocess.run([sys.executable, "-m", "boresight", "--version"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.strip() == f"boresight {boresight.__version__}"
    # the one version: pyproject.toml reads boresight.__version__ (tests/project/test_public_api.py)


def test_scenarios_by_name_and_path(tmp_path, monkeypatch):
    from dataclasses import replace

    by_name = replace(orbits.load_scenario("kiev2012-sensitivity"), source="")
    assert by_name == replace(orbits.load_scenario("kiev2012-sensitivity.toml"), source="")
    assert by_name == replace(orbits.load_scenario(ROOT / "scenarios" / "kiev2012-sensitivity.toml"), source="")
    monkeypatch.chdir(tmp_path)  # a name works from any directory
    assert orbits.load_scenario("kiev2012-kalman20").name == "kiev2012-kalman20"
    (tmp_path / "kiev2012-kalman20.toml").write_text(
        (orbits.scenario_path("kiev2012-kalman20")).read_text().replace('"kiev2012-kalman20"', '"local"', 1)
    )
    assert orbits.load_scenario("kiev2012-kalman20.toml").name == "local"  # an existing path wins over a shipped name
    with pytest.raises(orbits.ScenarioError, match="shipped: .*kiev2012-sensitivity"):
        orbits.load_scenario("no-such-scenario")
    assert set(orbits.scenario_names()) >= {"kiev2012-sensitivity", "kiev2012-kalman20", "kiev2012-algorithm1"}


def _leaf_parsers():
    import argparse

    from boresight.cli.main import build_parser

    def walk(name, p):
        nested = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if not nested:
            yield name, p
            return
        for child_name, child in nested[0].choices.items():
            yield from walk(f"{name} {child_name}".strip(), child)

    yield from walk("", build_parser())


def test_every_command_follows_the_option_conventions():
    """One convention (docs/reliability.md, "Command-line conventions"): -q/--quiet and
    --traceback everywhere; --no-plots (never --no-plot alone) wherever a PNG is written; an
    --out folder that defaults to out/<subject> or is required (ingest: the file to write)."""
    seen = set()
    for name, p in _leaf_parsers():
        seen.add(name)
        opts = {s: a for a in p._actions for s in a.option_strings}
        assert "-q" in opts and "--quiet" in opts, name
        assert "--traceback" in opts and "-v" not in opts, name
        if "--no-plot" in opts:
            assert "--no-plots" in opts and opts["--no-plot"] is opts["--no-plots"], name
        if "--out" in opts and opts["--out"].default is not None and not opts["--out"].required:
            assert str(opts["--out"].default).startswith("out"), (name, opts["--out"].default)
    assert {"estimate", "plan", "diagnose", "montecarlo", "sensitivity", "pointing sea-sky"} <= seen
    for name in ("estimate", "plan", "diagnose", "montecarlo", "sensitivity", "pointing sea-sky"):
        p = dict(_leaf_parsers())[name]
        assert "--no-plots" in {s for a in p._actions for s in a.option_strings}, name
