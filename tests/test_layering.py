"""Import contracts (the layers of ``docs/architecture.md``), checked on the source of every module.

1. ``orbits`` (the world) never imports ``boresight`` (the analyst).
2. The estimation core — ``boresight/algorithms/``, ``estimate``, ``normal_equations``, ``crlb``,
   ``disturbances``, ``measurement`` and ``effect_model`` (and any module later added to ``CORE``) — imports
   neither the command line (``boresight.commands``), the seminar's reproduction
   (``boresight.kiev2012``), the Monte Carlo studies (``boresight.montecarlo``), astropy's
   ``Table`` nor matplotlib. It also takes no rotation math from an estimator: ``crlb`` and
   ``disturbances`` do not import ``boresight.algorithms`` (shared math lives in ``orbits``).
3. Nothing outside ``boresight/commands/`` and ``boresight/cli.py`` imports ``boresight.commands``.
4. Nothing in the library proper imports ``boresight.kiev2012``: only the commands, the
   deprecated ``boresight.reproduce`` shim and the studies that print the seminar's numbers beside
   ours (``KIEV2012_USERS``).

Every import counts — top level or inside a function (a lazy import is still a dependency);
relative imports are resolved against the module's package. New modules are covered by the
rules 1, 3 and 4 automatically; put a new estimation-core module in ``CORE``.
"""

import ast
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PKG = ROOT / "boresight"

#: the estimation core (paths relative to boresight/; a folder means every module below it)
CORE = ("algorithms", "estimate.py", "normal_equations.py", "crlb.py", "disturbances.py", "effect_model.py", "measurement.py")
CORE_FORBIDDEN = ("boresight.commands", "boresight.kiev2012", "boresight.montecarlo", "astropy.table", "matplotlib")
#: modules outside boresight/kiev2012 allowed to import it
KIEV2012_USERS = ("commands", "cli.py", "reproduce.py", "sensitivity.py")


def _module_name(path: pathlib.Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: pathlib.Path) -> list:
    """Absolute names of every module ``path`` imports (``from a import b`` gives ``a`` and ``a.b``)."""
    return imports_of_file(path, _module_name(path), is_package=path.name == "__init__.py")


def imports_of_file(path: pathlib.Path, module: str, is_package: bool = False) -> list:
    tree = ast.parse(path.read_text())
    pkg = module.split(".")
    if not is_package:
        pkg = pkg[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append(mod)
            out += [f"{mod}.{a.name}" for a in node.names]
    return out


def _matches(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def _under(path: pathlib.Path, entries) -> bool:
    rel = path.relative_to(PKG).as_posix()
    return any(rel == e or rel.startswith(e.rstrip("/") + "/") for e in entries)


def _modules(root):
    return sorted(p for p in root.rglob("*.py") if "reference_outputs" not in p.parts)


def test_orbits_source_has_no_boresight_import():
    offenders = [f"{p.relative_to(ROOT)}: {n}" for p in _modules(ROOT / "orbits") for n in imports_of(p) if _matches(n, "boresight")]
    assert offenders == []


def test_importing_orbits_loads_no_boresight_module():
    code = "import sys, orbits, orbits.scenario; print(sorted(m for m in sys.modules if m.split('.')[0] == 'boresight'))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


def test_estimation_core_imports_no_study_report_or_plotting_code():
    core = [p for p in _modules(PKG) if _under(p, CORE)]
    assert any(p.name == "estimate.py" for p in core) and any("algorithms" in p.parts for p in core)
    offenders = [
        f"{p.relative_to(ROOT)}: {n}" for p in core for n in imports_of(p) if any(_matches(n, f) for f in CORE_FORBIDDEN)
    ]
    assert offenders == []


@pytest.mark.parametrize("module", ["crlb.py", "disturbances.py"])
def test_models_take_no_math_from_an_estimator(module):
    path = PKG / module
    assert [n for n in imports_of(path) if _matches(n, "boresight.algorithms")] == []


def test_only_the_command_line_imports_commands():
    offenders = [
        f"{p.relative_to(ROOT)}: {n}"
        for p in _modules(PKG)
        if not _under(p, ("commands", "cli.py"))
        for n in imports_of(p)
        if _matches(n, "boresight.commands")
    ]
    assert offenders == []


def test_the_library_does_not_import_the_seminar_reproduction():
    offenders = [
        f"{p.relative_to(ROOT)}: {n}"
        for p in _modules(PKG)
        if not _under(p, ("kiev2012",) + KIEV2012_USERS)
        for n in imports_of(p)
        if _matches(n, "boresight.kiev2012")
    ]
    assert offenders == []


def test_the_import_parser_sees_relative_and_lazy_imports(tmp_path):
    """The rules above would pass vacuously if ``imports_of`` missed these forms."""
    path = PKG / "algorithms" / "kalman.py"
    names = imports_of(path)
    assert "boresight.disturbances" in names  # from ..disturbances import ...
    assert "boresight.algorithms.image_plane" in names  # from .image_plane import ...
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    import matplotlib.pyplot as plt\n    from astropy.table import Table\n")
    assert {"matplotlib.pyplot", "astropy.table", "astropy.table.Table"} <= set(imports_of_file(probe, "boresight.probe"))
