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

from orbits.errors import did_you_mean

__all__ = ["Parser", "parse_command_line"]

_INVALID_CHOICE = re.compile(r"invalid choice: '([^']*)' \(choose from (.*)\)$")


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors suggest the closest valid choice or option."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        m = _INVALID_CHOICE.search(message)
        if m:
            choices = re.findall(r"'([^']*)'", m.group(2))
            message = f"{message[: m.start()]}invalid choice: '{m.group(1)}'{did_you_mean(m.group(1), choices)}" \
                      f" (choose from {', '.join(choices)})"
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


def parse_command_line(parser: Parser, subparsers, argv):
    """Parse ``argv``; an unknown option is reported by the sub-command's own parser (its usage)."""
    args, extras = parser.parse_known_args(argv)
    if extras:
        command = getattr(args, "command", None)
        owner = subparsers.choices.get(command) if command else None
        while isinstance(owner, Parser):  # descend into a nested command (pointing sea-sky)
            nested = [a for a in owner._actions if isinstance(a, argparse._SubParsersAction)]
            child = nested[0].choices.get(getattr(args, nested[0].dest, None)) if nested else None
            if not isinstance(child, Parser):
                break
            owner = child
        (owner if isinstance(owner, Parser) else parser).unknown_options(extras)
    return args
