"""The command line's argument parser: argparse with "did you mean" and the sub-command's own usage.

DECISION: argparse (Python 3.11) answers a typo with the whole list of choices, and an unknown
option of a sub-command with the *top-level* usage. A user who types ``boresight estimat`` or
``boresight estimate f.ecsv --sigma-pixl 3`` should get one line naming what they wrote, the
closest valid spelling, and the usage of the command they were running. ``Parser`` does that by
overriding ``error`` (``orbits.errors.did_you_mean``), and ``parse_command_line`` hands unknown options to the sub-command's parser.
"""

from __future__ import annotations

import argparse
import re
from typing import Any

from orbits.errors import did_you_mean

__all__ = ["Parser", "RENAMED_OPTIONS", "parse_command_line", "renamed_option"]

#: Options renamed or removed (``CHANGES.md``, "Renamed"): (commands, old, new, why); ``()`` means every
#: command. Each command refuses an old spelling it used to take with ``OLD: renamed: use NEW (why)``, exit 2,
#: before anything else is parsed (argparse alone answered ``--float time_tag`` with "did you mean '--out'?"
#: and ``diagnose --effects`` with nothing). ``tests/cli/test_renamed_options.py`` runs every row.
#: DECISION: refused, not kept as a warning alias — 0.1.0 has no deprecation cycle (``CHANGES.md``), and an
#: alias that still works would keep the two spellings alive in scripts and docs.
RENAMED_OPTIONS: tuple[tuple[tuple[str, ...], str, str, str], ...] = (
    (("estimate", "montecarlo"), "--float", "--effects", "the library's keyword is estimate(effects=...)"),
    (("diagnose",), "--effects", "--candidates", "the effects the diagnosis may name, not effects fitted"),
    (("plan",), "--check", "--mc-check", "a Monte Carlo check, unrelated to `boresight check`"),
    ((), "-v", "--traceback", "it prints the traceback of an error, not more output"),
    ((), "--verbose", "--traceback", "it prints the traceback of an error, not more output"),
    (("estimate",), "--prior-sigma-arcsec", "--sigma-prior-arcsec", "σ first, as in every σ option: --sigma-pixel-m, ..."),
    (
        ("ingest",),
        "--centroid-sigma-ref-px",
        "--centroid-sigma-reference-px",
        "one word for the reference magnitude, as in --centroid-reference-mag",
    ),
)


def renamed_option(command: str, word: str) -> tuple[str, str] | None:
    """(new name, why) when ``word`` is an option ``command`` used to take under another name, else None.

    >>> renamed_option("diagnose", "--effects")
    ('--candidates', 'the effects the diagnosis may name, not effects fitted')
    >>> renamed_option("estimate", "--effects") is None
    True
    """
    for commands, old, new, why in RENAMED_OPTIONS:
        if word == old and (not commands or command in commands):
            return new, why
    return None


_INVALID_CHOICE = re.compile(r"invalid choice: '([^']*)' \(choose from (.*)\)$")


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors suggest the closest valid choice or option."""

    #: the top-level parser's sub-command action (``boresight.cli.main.build_parser``), or None
    _boresight_subparsers: Any = None

    def error(self, message: str):  # noqa: D401 - argparse's hook
        m = _INVALID_CHOICE.search(message)
        if m:
            choices = re.findall(r"'([^']*)'", m.group(2))
            message = (
                f"{message[: m.start()]}invalid choice: '{m.group(1)}'{did_you_mean(m.group(1), choices)}"
                f" (choose from {', '.join(choices)})"
            )
        super().error(message)

    def unknown_options(self, extras: list[str]):
        """Refuse ``extras`` (what argparse could not place) with a suggestion for each option."""
        known = [s for a in self._actions for s in a.option_strings]
        groups: list[list[str]] = []
        for tok in extras:  # an option and the values that follow it read as one group
            if tok.startswith("-") or not groups or not groups[-1][0].startswith("-"):
                groups.append([tok])
            else:
                groups[-1].append(tok)
        parts = []
        for group in groups:
            word = group[0].split("=", 1)[0]
            hint = did_you_mean(word, known) if word.startswith("-") else ""
            parts.append(" ".join(group) + hint)
        self.error("unrecognized arguments: " + "; ".join(parts))


def _refuse_renamed(subparsers, argv: list[str]) -> None:
    """Refuse an option of ``RENAMED_OPTIONS`` by its command's parser (the leaf of a nested command)."""
    words = [t for t in argv if not t.startswith("-")]
    owner = subparsers.choices.get(words[0]) if words else None
    if not isinstance(owner, Parser):
        return
    command = words[0]
    for word in words[1:2]:  # a nested command (pointing sea-sky): its own parser's usage
        nested = [a for a in owner._actions if isinstance(a, argparse._SubParsersAction)]
        if nested and isinstance(nested[0].choices.get(word), Parser):
            owner = nested[0].choices[word]
    at = argv.index(command)
    for tok in argv[:at] + argv[at + 1 :]:  # before the command too: ``boresight -v estimate …``
        if tok == "--":  # what follows is positional
            break
        found = renamed_option(command, tok.split("=", 1)[0]) if tok.startswith("-") else None
        if found:
            owner.error(f"{tok.split('=', 1)[0]}: renamed: use {found[0]} ({found[1]})")


def parse_command_line(parser: Parser, subparsers, argv):
    """Parse ``argv``; an option that was renamed is refused naming its new name (``RENAMED_OPTIONS``), an
    unknown option is reported by the sub-command's own parser (its usage)."""
    import sys

    _refuse_renamed(subparsers, list(sys.argv[1:] if argv is None else argv))
    args, extras = parser.parse_known_args(argv)
    if extras:
        command = getattr(args, "command", None)
        owner = subparsers.choices.get(command) if command else None
        while isinstance(owner, Parser):  # descend into a nested command (pointing sea-sky)
            nested = [a for a in owner._actions if isinstance(a, argparse._SubParsersAction)]
            chosen: Any = getattr(args, nested[0].dest, None) if nested else None
            child = nested[0].choices.get(chosen) if nested else None
            if not isinstance(child, Parser):
                break
            owner = child
        (owner if isinstance(owner, Parser) else parser).unknown_options(extras)
    return args


def add_common_options(parser: argparse.ArgumentParser) -> None:
    """The options every command has, with one meaning everywhere (``docs/reliability.md``):

    * ``-q/--quiet``: no progress bar or heartbeat on stderr; the results are still printed;
    * ``--traceback``: on an error, its traceback too (as ``BORESIGHT_DEBUG=1``).

    Added to every (sub-)command parser that does not define them already; nested commands
    (``pointing sea-sky``) get them on the leaf.
    """
    nested = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if nested:
        for child in nested[0].choices.values():
            add_common_options(child)
        return
    have = {s for a in parser._actions for s in a.option_strings}
    if "--quiet" not in have:
        parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or heartbeat (results are still printed)")
    if "--traceback" not in have:
        parser.add_argument("--traceback", action="store_true", help="on an error, print its traceback too")
