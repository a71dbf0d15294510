"""Sphinx configuration: the API reference (autodoc, numpy-style docstrings through napoleon), the
narrative docs (Markdown through MyST) and the gallery (sphinx-gallery runs ``examples/gallery/``
and renders each script with its code, printed output and figures). Built with warnings as errors
by ``tests/project/test_docs.py`` (``python -m sphinx -W -b html docs <out>``)."""

import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, os.path.abspath(".."))
_GALLERY = Path(__file__).resolve().parents[1] / "examples" / "gallery"
sys.path.insert(0, str(_GALLERY))  # the scripts' shared helper, _common.py

project = "boresight"
author = "the boresight developers"
copyright = "2026, the boresight developers"  # noqa: A001 - Sphinx's name

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # numpy-style docstrings (numpydoc's format)
    "sphinx.ext.mathjax",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "discrepancy-example/*.md", "api/_*", "examples/*.md", "examples/*.ipynb"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
# DECISION: an "Attributes" section renders as :ivar: fields, not attribute directives, which would
# describe a dataclass field a second time beside autodoc's own member entry (sphinx -W refuses duplicates)
napoleon_use_ivar = True
html_theme = "alabaster"
html_static_path: list = []
# DECISION: the narrative docs link to source files and to each other by relative path (they read
# well on a repository host); a link Sphinx cannot resolve to a document is not an error there.
# sphinx-gallery's configuration holds a function (the PNG scraper): Sphinx cannot pickle it for its
# incremental cache, which only costs a full rebuild (the test builds with -E anyway).
suppress_warnings = ["myst.xref_missing", "myst.header", "config.cache"]

# ---- the gallery (sphinx-gallery, BSD-3-Clause): every script of examples/gallery/ is run at build time
# with the small sizes of tests/project/test_gallery.py (each page says so), its commands in a temporary
# working folder (BORESIGHT_GALLERY_WORKDIR, entered by the scripts' ``_common.run``) writing into
# out/gallery there: a page shows the paths a reader's own run would print (out/gallery/pass.ecsv), never
# the builder's temporary folder. The commands draw their figures without pyplot
# (boresight.reporting.plots) and write PNG files; ``_written_pngs`` shows, under each code block, the PNG
# files that block wrote (in the order written).
os.environ.setdefault("BORESIGHT_GALLERY_SMALL", "1")
os.environ.setdefault("BORESIGHT_GALLERY_WORKDIR", tempfile.mkdtemp(prefix="boresight-gallery-"))
os.environ["BORESIGHT_GALLERY_OUT"] = "out/gallery"  # relative to the working folder: what the pages print
os.environ.setdefault("MPLBACKEND", "Agg")
_SEEN: set = set()


def _written_pngs(block, block_vars, gallery_conf):
    """sphinx-gallery image scraper: the PNG files written under the gallery's output folder since the
    previous block, copied to the gallery's image paths and shown below the block."""
    from sphinx_gallery.scrapers import figure_rst

    out = Path(os.environ["BORESIGHT_GALLERY_WORKDIR"]) / os.environ["BORESIGHT_GALLERY_OUT"]
    new = sorted(
        (p for p in out.rglob("*.png") if (p, p.stat().st_mtime_ns) not in _SEEN),
        key=lambda p: (p.stat().st_mtime_ns, str(p)),
    )
    shown = []
    for png, dest in zip(new, block_vars["image_path_iterator"]):
        _SEEN.add((png, png.stat().st_mtime_ns))
        shutil.copyfile(png, dest)
        shown.append(dest)
    return figure_rst(shown, gallery_conf["src_dir"])


sphinx_gallery_conf = {
    "examples_dirs": str(_GALLERY),
    "gallery_dirs": "examples",
    "filename_pattern": r"/[a-z]",  # run every script (not only plot_*.py)
    "ignore_pattern": r"_common\.py",  # the shared helper
    "image_scrapers": ("matplotlib", _written_pngs),
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "write_computation_times": False,
    "abort_on_example_error": True,
    # every build runs every script: an unchanged script's page would otherwise keep the output of the
    # build that last ran it (docs/examples/ is generated in the source tree and survives -E)
    "run_stale_examples": True,
    "show_signature": False,
    "remove_config_comments": True,
}
