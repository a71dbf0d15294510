"""Paths the tests share, defined once: the repository root (``ROOT``) and its scenario folder.

``tests/`` is on ``sys.path`` under pytest (rootdir-relative import mode), so a test module says
``from paths import ROOT``; helper modules beside it (``study_processes``, ``toml_writer``) are
imported the same way.
"""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
