"""The ``boresight`` command line.

Each sub-command lives in the module that owns its work and exposes
``register(subparsers)``, which adds a parser whose ``func`` default takes the
parsed arguments and returns an exit code. This file only assembles them.

Example::

    $ boresight simulate scenarios/kiev2012-sensitivity.toml --seed 1 --out out
"""

from __future__ import annotations

import argparse
import importlib
import sys

from orbits.errors import BoresightError

# DECISION: sub-commands are registered by module name so that a module with a
# heavy import (matplotlib, dask) is imported only when its command runs.
_COMMAND_MODULES = (
    "boresight.commands.simulate",
    "boresight.commands.estimate",
    "boresight.commands.check",
    "boresight.commands.ingest",
    "boresight.commands.montecarlo",
    "boresight.commands.sensitivity",
    "boresight.commands.reproduce",
    "boresight.commands.diagnose",
    "boresight.pointing.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="boresight",
        description="Estimate camera / star-tracker misalignment and its accuracy.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:  # a command still being built
            if exc.name != name:
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (BoresightError, ValueError, FileNotFoundError) as exc:
        print(f"boresight {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
