"""Run the ``boresight`` command line in-process for a test: one helper, shared by the test modules."""

from __future__ import annotations

import contextlib
import io


def run_cli(argv) -> tuple:
    """(exit code, stdout, stderr) of ``boresight argv`` in this process (argparse's exit included)."""
    from boresight.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()
