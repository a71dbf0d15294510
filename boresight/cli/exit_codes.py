"""The ``boresight`` command's exit status (``docs/reliability.md``), shared by every command.

The library raises typed errors (``boresight.errors``, ``BoresightError``); which status each
gives is decided here and in ``cli.main.classify``, never by the library.
"""

__all__ = [
    "EXIT_OK",
    "EXIT_INPUT_ERROR",
    "EXIT_USAGE",
    "EXIT_NOT_CONVERGED",
    "EXIT_CONVENTION",
    "EXIT_NO_CAMPAIGN",
    "EXIT_INTERNAL_ERROR",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
]

#: success (an estimate may still carry warnings, printed in the summary and JSON)
EXIT_OK = 0
#: the input was refused: a ``BoresightError`` (bad file, scenario, option, geometry, memory
#: budget, locked or mismatched study) or an ``OSError`` on a path the user gave
EXIT_INPUT_ERROR = 1
#: the command line itself is malformed (argparse's own status)
EXIT_USAGE = 2
#: an estimate was computed but did not converge (printed as such; results written)
EXIT_NOT_CONVERGED = 3
#: ``estimate``/``check`` found a convention slip in the data (mirrored axes, quaternion order, …)
EXIT_CONVENTION = 4
#: ``plan``: no candidate campaign in the search space meets every requirement (the outputs are
#: still written: the front shows the trade-offs)
EXIT_NO_CAMPAIGN = 5
#: a bug in boresight: a traceback is printed (please report it)
EXIT_INTERNAL_ERROR = 70
#: interrupted by the user (Ctrl-C); a study's finished blocks are kept for ``--resume``
EXIT_INTERRUPTED = 130
#: stopped by SIGTERM (``kill PID``; 128 + 15, what a shell reports for it): temporary files
#: removed, workers stopped, a study's finished blocks kept for ``--resume``
EXIT_TERMINATED = 143
