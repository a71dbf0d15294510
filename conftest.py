"""Root conftest: doctests run from the repository root; ``python -m boresight`` is not a test module,
and neither is package data (``boresight/data/gallery`` links the gallery's scripts, which
``tests/project/test_gallery.py`` runs as scripts: importing one would run it)."""

collect_ignore = ["boresight/__main__.py", "benchmarks", "build", "boresight/data"]
