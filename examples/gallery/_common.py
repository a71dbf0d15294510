"""Shared by the gallery scripts: the output folder, the run sizes and how a command is run.

``BORESIGHT_GALLERY_SMALL=1`` (set by ``tests/project/test_gallery.py`` and by the documentation
build) runs every script with small sizes; without it the scripts use the sizes of the narrative
docs they illustrate. The scripts write into ``out/gallery`` under the folder they are run from
(``BORESIGHT_GALLERY_OUT`` names another); ``BORESIGHT_GALLERY_WORKDIR``, if set, is the folder
every command runs in (the documentation build sets it, so the pages show paths relative to it,
never the builder's own). Run them from a working folder of yours — in a checkout or from the copy
installed with the package (``boresight docs`` prints where it is) —, never from inside that copy:

    mkdir work && cd work && python /path/to/gallery/flight_pass.py
"""

import contextlib
import os
import sys
from pathlib import Path

SMALL = bool(os.environ.get("BORESIGHT_GALLERY_SMALL"))
OUT = Path(os.environ.get("BORESIGHT_GALLERY_OUT", "out/gallery"))


def run(*argv: str) -> None:
    """Run one ``boresight`` command line in-process, printing it first; stop the script if it fails.
    The command runs in ``BORESIGHT_GALLERY_WORKDIR`` when that is set (else where the script runs),
    with the output folder ``OUT`` created there."""
    from boresight.cli.main import main

    # DECISION: the working folder is entered here, before every command, not once on import: the
    # documentation build (sphinx-gallery) runs each code block from the script's own folder and
    # restores its working folder after the block, and a module is imported only once per build.
    work = os.environ.get("BORESIGHT_GALLERY_WORKDIR")
    if work:
        os.chdir(work)
    OUT.mkdir(parents=True, exist_ok=True)
    print("$ boresight " + " ".join(argv))
    with _install_root_hidden() if work else contextlib.nullcontext():
        code = main(list(argv))
    if code != 0:
        raise SystemExit(f"boresight {argv[0]} exited with {code}")


class _Relative:
    """A stdout that writes the folder holding the ``boresight`` and ``orbits`` packages as ``<install>``."""

    def __init__(self, stream, root: str):
        self.stream, self.root = stream, root

    def write(self, text: str) -> int:
        return self.stream.write(text.replace(self.root, "<install>"))

    def flush(self) -> None:
        self.stream.flush()


def _install_root_hidden():
    """The documentation build's pages show the shipped files a command reads (the flight tutorial's
    data, a shipped scenario) from ``<install>``, the folder that holds the packages — a checkout or
    site-packages —, never the builder's own path."""
    import boresight

    root = str(Path(boresight.__file__).resolve().parents[1]) + os.sep
    return contextlib.redirect_stdout(_Relative(sys.stdout, root[:-1]))
