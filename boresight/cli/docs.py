"""``boresight docs [NAME]``: the documentation that ships with the package, from any install.

The Markdown files of ``docs/`` are package data (``boresight/data/docs`` is a symlink to
``docs/`` in a checkout, a copy in the wheel), so a pip install carries them, and so are the gallery's
scripts (``boresight/data/gallery``, a symlink to ``examples/gallery/``): ``boresight docs``
lists the documents with their titles and where they are, and the folder of the gallery scripts; ``boresight docs NAME`` prints one
(``boresight docs tutorial-flight-data``). The site with the API reference is built from the same
files with Sphinx (README, "Documentation").
"""

from __future__ import annotations

import sys
from pathlib import Path

#: the shipped documentation (a symlink to docs/ in a checkout)
DOCS_DIR = Path(__file__).resolve().parents[1] / "data" / "docs"
#: the shipped gallery scripts (a symlink to examples/gallery/ in a checkout; docs/gallery.md)
GALLERY_DIR = Path(__file__).resolve().parents[1] / "data" / "gallery"


def shipped_docs() -> dict[str, Path]:
    """{name: path} of every shipped Markdown document (name = file stem), sorted by name."""
    return {p.stem: p for p in sorted(DOCS_DIR.glob("*.md")) if p.stem != "index"}


def _title(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return ""


def register(sub):
    p = sub.add_parser("docs", help="list the documentation shipped with boresight, or print one document")
    p.add_argument("name", nargs="?", default=None, help="a document's name (e.g. tutorial-flight-data); omit to list them")
    p.set_defaults(func=run)


def run(args) -> int:
    from orbits.errors import BoresightError, did_you_mean

    docs = shipped_docs()
    if args.name is None:
        print(f"documentation shipped with boresight, in {DOCS_DIR.resolve()}:")
        for name, path in docs.items():
            print(f"  {name:<22} {_title(path)}")
        print("print one with: boresight docs NAME")
        scripts = sorted(p.name for p in GALLERY_DIR.glob("*.py") if not p.name.startswith("_"))
        print(f"gallery scripts (boresight docs gallery), in {GALLERY_DIR.resolve()}:")
        print("  " + ", ".join(scripts))
        # DECISION: run from a working folder, never inside the installed copy: a script writes into out/gallery
        # under the folder it is run from, which inside an install is site-packages
        print(
            "  run one from a working folder of yours, not from that folder (it writes into out/gallery where it runs): "
            f"mkdir work && cd work && python {GALLERY_DIR.resolve() / 'estimate_a_pass.py'}"
        )
        return 0
    name = Path(args.name).stem
    if name not in docs:
        raise BoresightError(
            f"no document named {args.name!r}{did_you_mean(name, docs)}; "
            f"the shipped ones: {', '.join(docs)} (boresight docs lists them)"
        )
    sys.stdout.write(docs[name].read_text(encoding="utf-8"))
    return 0
