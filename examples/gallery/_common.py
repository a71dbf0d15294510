"""Shared by the gallery scripts: the output folder, the run sizes and how a command is run.

``BORESIGHT_GALLERY_SMALL=1`` (set by ``tests/project/test_gallery.py`` and by the documentation
build) runs every script with small sizes; without it the scripts use the sizes of the narrative
docs they illustrate. ``BORESIGHT_GALLERY_OUT`` is where they write (default ``out/gallery``).
The scripts run the same from a checkout (``examples/gallery/``) and from the copy installed with
the package (``boresight docs`` prints where it is).
"""

import os
from pathlib import Path

SMALL = bool(os.environ.get("BORESIGHT_GALLERY_SMALL"))
OUT = Path(os.environ.get("BORESIGHT_GALLERY_OUT", "out/gallery"))


def run(*argv: str) -> None:
    """Run one ``boresight`` command line in-process, printing it first; stop the script if it fails."""
    from boresight.cli.main import main

    print("$ boresight " + " ".join(argv))
    code = main(list(argv))
    if code != 0:
        raise SystemExit(f"boresight {argv[0]} exited with {code}")
