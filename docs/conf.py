"""Sphinx configuration: the API reference (autodoc, numpy-style docstrings through napoleon) and
the narrative docs (Markdown through MyST). Built with warnings as errors by
``tests/project/test_docs.py`` (``python -m sphinx -W -b html docs <out>``)."""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))

project = "boresight"
author = "the boresight developers"
copyright = "2026, the boresight developers"  # noqa: A001 - Sphinx's name

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # numpy-style docstrings (numpydoc's format)
    "sphinx.ext.mathjax",
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "discrepancy-example/*.md", "api/_*"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
autodoc_member_order = "bysource"
autodoc_typehints = "none"
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
suppress_warnings = ["myst.xref_missing", "myst.header"]
