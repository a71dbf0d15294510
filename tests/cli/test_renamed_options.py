"""An option that was renamed is refused naming its new name, by every command that took it (issue 32, item 2).

Before ``boresight.cli.parsing.RENAMED_OPTIONS``, argparse answered ``estimate --float time_tag`` with
"did you mean '--out'?" and ``diagnose --effects`` with no hint at all. Every row of the table is run here
through the real parser, on every command it names (all of them for ``()``), and the changelog's table of
renamed options is held to it, so a rename recorded in ``CHANGES.md`` without a refusal fails.
"""

from __future__ import annotations

import argparse
import re

import pytest
from paths import ROOT

from boresight.cli.main import build_parser, main
from boresight.cli.parsing import RENAMED_OPTIONS


def _leaves():
    """{command words: its parser} for every command (a nested one as its two words)."""
    sub = build_parser()._boresight_subparsers
    out = {}
    for name, p in sub.choices.items():
        nested = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if nested:
            out.update({(name, child): cp for child, cp in nested[0].choices.items()})
        else:
            out[(name,)] = p
    return out


LEAVES = _leaves()
CASES = [
    (words, old, new) for commands, old, new, _why in RENAMED_OPTIONS for words in LEAVES if not commands or words[0] in commands
]


def test_every_command_is_covered():
    assert len(LEAVES) >= 11 and {w[0] for w, _, _ in CASES} == {w[0] for w in LEAVES}


@pytest.mark.parametrize("words, old, new", CASES, ids=[f"{' '.join(w)} {o}" for w, o, _ in CASES])
def test_a_renamed_option_is_refused_naming_its_new_name(capsys, words, old, new):
    options = {s for a in LEAVES[words]._actions for s in a.option_strings}
    assert new in options and old not in options, (words, sorted(options))
    for argv in ([*words, "FILE", old, "x"], [*words, f"{old}=x"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        err = capsys.readouterr().err
        assert info.value.code == 2, err
        assert f"boresight {' '.join(words)}: error: {old}: renamed: use {new} (" in err, err


def test_an_old_name_before_the_command_is_refused_too(capsys):
    with pytest.raises(SystemExit):
        main(["-v", "estimate", "f.ecsv"])
    assert "boresight estimate: error: -v: renamed: use --traceback (" in capsys.readouterr().err


def test_an_old_name_after_a_double_dash_is_a_value(capsys):
    assert main(["estimate", "--", "--float"]) == 1
    err = capsys.readouterr().err
    assert "no such observation file: --float" in err and "renamed" not in err, err


def test_a_typo_still_gets_the_closest_spelling(capsys):
    with pytest.raises(SystemExit):
        main(["estimate", "f.ecsv", "--efects", "none"])
    err = capsys.readouterr().err
    assert "did you mean '--effects'" in err and "renamed" not in err, err


def test_every_option_the_changelog_renames_is_refused():
    """The rows of CHANGES.md's ``| command | old | new | why |`` tables whose old and new are options are
    exactly the table's rows: a rename recorded without a refusal fails, and a refusal not recorded."""
    text = (ROOT / "CHANGES.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| ([^|]+) \| `(-[^` ]+)[^`]*`(?:, `(-[^` ]+)`)? \| `(--[^` ]+)[^|]*\|", text, flags=re.M)
    assert len(rows) >= 4, rows
    table = {(old, new) for _c, old, new, _w in RENAMED_OPTIONS}
    recorded = {(o, new) for _command, old, other, new in rows for o in (old, other) if o}
    assert recorded == table, (sorted(recorded - table), sorted(table - recorded))


def _long_options():
    return sorted({s for p in LEAVES.values() for a in p._actions for s in a.option_strings if s.startswith("--")})


def test_one_spelling_per_word_across_every_option():
    """No word of one option is an abbreviation of a word of another (``--centroid-sigma-ref-px`` beside
    ``--centroid-reference-mag`` failed this); plurals are the one exception."""
    units = {"m", "px", "deg", "arcsec"}  # a unit is its own word (``m`` starts ``max``, ``mode``, ...)
    words = {w for o in _long_options() for w in o[2:].split("-")} - units
    clashes = [(a, b) for a in words for b in words if a != b and b.startswith(a) and b != a + "s"]
    assert not clashes, clashes


def test_every_sigma_option_says_sigma_then_what_then_its_unit():
    """``--sigma-<what>-<unit>`` (after a group word such as ``centroid``), the architecture's ``sigma_<source>_<unit>``
    (``estimate --prior-sigma-arcsec`` beside ``ingest --sigma-prior-arcsec`` failed this)."""
    for option in _long_options():
        words = option[2:].split("-")
        if "sigma" in words:
            i = words.index("sigma")
            assert len(words) - i >= 3 and words[-1] in ("m", "px", "arcsec"), option
