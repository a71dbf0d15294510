"""Root conftest: doctests run from the repository root; ``python -m boresight`` is not a test module."""

collect_ignore = ["boresight/__main__.py", "benchmarks", "build"]
