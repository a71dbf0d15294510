"""Import contract: ``orbits`` (the world) never imports ``boresight`` (the analyst)."""

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_orbits_source_has_no_boresight_import():
    offenders = []
    for path in sorted((ROOT / "orbits").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            offenders += [f"{path.name}: {n}" for n in names if n == "boresight" or n.startswith("boresight.")]
    assert offenders == []


def test_importing_orbits_loads_no_boresight_module():
    code = "import sys, orbits, orbits.scenario; print(sorted(m for m in sys.modules if m.split('.')[0] == 'boresight'))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"
