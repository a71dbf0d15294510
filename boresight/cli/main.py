"""The ``boresight`` command line.

Each sub-command lives in the module that owns its work and exposes
``register(subparsers)``, which adds a parser whose ``func`` default takes the
parsed arguments and returns an exit code. This file only assembles them.

Example::

    $ boresight simulate scenarios/kiev2012-sensitivity.toml --seed 1 --out out

Errors (``docs/reliability.md``): a ``BoresightError`` — anything refused on purpose — and an
``OSError`` on a path the user gave print one line, ``boresight COMMAND: error: …``, and exit
``EXIT_INPUT_ERROR`` (1); a malformed command line exits 2 (argparse); a non-converged
estimate exits ``EXIT_NOT_CONVERGED`` (3); a convention slip found by the doctor, in any command
that runs it, prints ``boresight COMMAND: ConventionError: …`` and exits ``EXIT_CONVENTION`` (4);
anything else is a bug: a traceback and exit
``EXIT_INTERNAL_ERROR`` (70). ``BORESIGHT_DEBUG=1`` prints the traceback of every error.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import signal
import sys
import traceback
from typing import TYPE_CHECKING

import numpy as np

from boresight.cli.exit_codes import EXIT_CONVENTION, EXIT_INPUT_ERROR, EXIT_INTERNAL_ERROR, EXIT_INTERRUPTED, EXIT_TERMINATED
from orbits.errors import BoresightError

if TYPE_CHECKING:
    from boresight.cli.parsing import Parser

# DECISION: sub-commands are registered by module name; a command module keeps its heavy imports
# (matplotlib, dask) inside its ``run`` so that building the parser stays cheap. Add a module here
# only once it exists: a missing one is an error (see build_parser).
_COMMAND_MODULES = (
    "boresight.cli.simulate",
    "boresight.cli.estimate",
    "boresight.cli.check",
    "boresight.cli.ingest",
    "boresight.cli.montecarlo",
    "boresight.cli.sensitivity",
    "boresight.cli.reproduce",
    "boresight.cli.diagnose",
    "boresight.cli.plan",
    "boresight.cli.pointing",
    "boresight.cli.docs",
)


def build_parser() -> Parser:
    from boresight.cli.parsing import Parser

    parser = Parser(
        prog="boresight",
        description="Estimate camera / star-tracker misalignment and its accuracy.",
        epilog="documentation: `boresight docs` lists the guides shipped with the package (tutorial, formats, "
        "conventions, reliability, …); `boresight docs NAME` prints one.",
    )
    from boresight import __version__
    from boresight.cli.examples import add_examples

    parser.add_argument("--version", action="version", version=f"boresight {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    parser._boresight_subparsers = sub  # for parse_command_line: unknown options go to the sub-command
    # DECISION: a registered command module that cannot be imported is an error, never a command
    # that silently disappears from the help (register a new command here when its module exists).
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    from boresight.cli.parsing import add_common_options

    for child in sub.choices.values():  # -q/--quiet and --traceback, one meaning everywhere
        add_common_options(child)
    add_examples(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from boresight.cli.parsing import parse_command_line

    parser = build_parser()
    args = parse_command_line(parser, parser._boresight_subparsers, argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        # --json -: the JSON alone on stdout, the other lines on stderr (reporting.outputs.json_on_stdout)
        json_dash = str(getattr(args, "json", None)) == "-"
        if json_dash:
            from boresight.reporting.outputs import json_on_stdout
        with _sigterm_raises(), json_on_stdout() if json_dash else contextlib.nullcontext():
            return int(args.func(args) or 0)
    except BaseException as exc:  # noqa: BLE001 - classified below; SystemExit passes through
        if isinstance(exc, SystemExit):
            raise
        if isinstance(exc, BrokenPipeError):  # the reader closed our output (`| head`): stop quietly
            # DECISION: the recipe of Python's signal docs — point stdout at devnull so the
            # interpreter's final flush does not raise again; exit 141 as a shell reports SIGPIPE
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 141
        code, message = classify(exc, study=hasattr(args, "resume"))
        if code == EXIT_INPUT_ERROR:
            message = name_the_argument(parser._boresight_subparsers.choices.get(args.command), args, message)
        if code == EXIT_INTERNAL_ERROR or os.environ.get("BORESIGHT_DEBUG") or getattr(args, "traceback", False):
            traceback.print_exc()
        print(f"boresight {args.command}: {message}", file=sys.stderr)
        return code


def name_the_argument(sub_parser, args, message: str) -> str:
    """``message`` with the argument that gave the path it names: a refusal such as
    ``/tmp/x: Is a directory`` or ``no such observation file: x.ecsv`` gains ``(given as FILE)``
    or ``(given as --out)``, so the user knows which argument to fix (refusals name their
    culprit). Unchanged when it already names an option, or names no argument's value."""
    if sub_parser is None or "--" in message or "argument " in message:
        return message
    best = None
    for action in sub_parser._actions:
        values = getattr(args, action.dest, None)
        for v in values if isinstance(values, list) else [values]:
            text = str(v) if v is not None and not isinstance(v, bool) else ""
            if len(text) >= 2 and text in message and (best is None or len(text) > len(best[0])):
                name = action.option_strings[-1] if action.option_strings else (action.metavar or action.dest.upper())
                best = (text, name)
    return message if best is None else f"{message} (given as {best[1]})"


class Terminated(BaseException):
    """SIGTERM arrived (``kill PID``): raised in the main thread like Ctrl-C's
    ``KeyboardInterrupt``, so that temporary files are removed, worker pools stopped and a
    study's checkpoint kept before the command exits ``EXIT_TERMINATED``."""


@contextlib.contextmanager
def _sigterm_raises():
    """DECISION: SIGTERM's default action ends the process at once, leaving temporary files and
    (for the dask engine) a cluster to its own watchdogs. While a command runs, the first SIGTERM
    raises ``Terminated`` instead; a second one (a stop that hangs) ends the process at once."""

    def handler(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        raise Terminated

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave SIGTERM alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def classify(exc: BaseException, study: bool = False) -> tuple[int, str]:
    """(exit code, one-line message) for an exception escaping a command.

    * ``ConventionError`` (the convention doctor found a slip) → ``EXIT_CONVENTION`` (4), named;
    * ``BoresightError`` → input error (its message names file, key, row and value);
    * ``OSError`` (the user's path: missing, a folder, a file where a folder is needed, a name
      too long, no permission; or the environment: disk full) → input error naming the path;
    * a plain ``ValueError`` (validation in older library code) → input error, except numpy's
      ``LinAlgError``, which is a bug (an unchecked singular geometry);
    * ``KeyboardInterrupt`` (Ctrl-C) → interrupted, ``Terminated`` (SIGTERM) → terminated: the
      line says what was kept (``study``: the finished blocks, for ``--resume``; every command:
      its outputs are old or new, never half-written — ``boresight.reporting.outputs``); everything else
      (and ``MemoryError``, which the memory budget should have prevented) → internal error.

    >>> classify(FileExistsError(17, "File exists", "out"))
    (1, 'error: out: File exists')
    >>> classify(ZeroDivisionError("x"))[0]
    70
    """
    from boresight.observations.doctor import ConventionError  # loaded with the doctor, before any raise

    if isinstance(exc, ConventionError):
        # the convention doctor's finding has a status of its own (4), and is named
        return EXIT_CONVENTION, f"{type(exc).__name__}: {_one_line(exc)}"
    if isinstance(exc, BoresightError):
        return EXIT_INPUT_ERROR, f"error: {_one_line(exc)}"
    if isinstance(exc, OSError):
        if exc.filename is not None:
            return EXIT_INPUT_ERROR, f"error: {exc.filename}: {exc.strerror or exc}"
        return EXIT_INPUT_ERROR, f"error: {_one_line(exc)}"
    if isinstance(exc, ValueError) and not isinstance(exc, np.linalg.LinAlgError):
        return EXIT_INPUT_ERROR, f"error: {_one_line(exc)}"
    if isinstance(exc, (KeyboardInterrupt, Terminated)):
        code, what = (
            (EXIT_INTERRUPTED, "interrupted") if isinstance(exc, KeyboardInterrupt) else (EXIT_TERMINATED, "terminated (SIGTERM)")
        )
        kept = (
            "its finished blocks are kept: continue it with --resume"
            if study
            else "no output was half-written: each is the old file or a complete new one"
        )
        return code, f"{what}; {kept}"
    if isinstance(exc, MemoryError):
        return (
            EXIT_INTERNAL_ERROR,
            "internal error: out of memory (the memory budget should have refused this; please report it with the command line)",
        )
    return (
        EXIT_INTERNAL_ERROR,
        f"internal error (a bug, please report it with the traceback above): {type(exc).__name__}: {_one_line(exc)}",
    )


def _one_line(exc) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
