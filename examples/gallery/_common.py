"""Shared by the gallery scripts: the output folder and the run sizes.

``BORESIGHT_GALLERY_SMALL=1`` (set by ``tests/project/test_gallery.py``) runs every script with small
sizes so the whole gallery runs in the default test suite; without it the scripts use the sizes
of the narrative docs they illustrate.
"""

import os
from pathlib import Path

SMALL = bool(os.environ.get("BORESIGHT_GALLERY_SMALL"))
OUT = Path(os.environ.get("BORESIGHT_GALLERY_OUT", "out/gallery"))
EXAMPLES = Path(__file__).resolve().parents[1]


def run(*argv: str) -> None:
    """Run one ``boresight`` command line in-process; stop the script if it fails."""
    from boresight.cli.main import main

    print("$ boresight " + " ".join(argv))
    code = main(list(argv))
    if code != 0:
        raise SystemExit(f"boresight {argv[0]} exited with {code}")
