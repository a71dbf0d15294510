"""Import contracts: the folders of ``boresight/`` are the layers of ``docs/architecture.md``.

A rule about folders, so it cannot drift when a module is added: a module in folder L may import,
from ``boresight``, only the folders in ``ALLOWED[L]`` (and its own). From the bottom up:

    errors, stats, files     generic: typed errors, statistics, atomic file writing (imports nothing else)
    core/                    the estimation core (measurement, noise model, GLS, CRLB, algorithms)
    observations/            the data: ObservationSet, its file format, simulation, doctor, flight
    reporting/               figures, output folders, provenance
    pointing/                gimbal / platform pointing calibration
    studies/                 Monte Carlo, sensitivity, discrepancy, planning
    reproductions/           published papers: scenarios, published numbers, reports
    cli/                     the command line

Also: ``orbits`` (the world) never imports ``boresight``; ``core/`` imports neither matplotlib nor
astropy's ``Table``; published numbers are imported only by their reproduction package, reports and
the command line; no two modules import each other, directly or round a circle; no module imports another's
private ``_name``, or reaches one through an object (``obs._x``, ``getattr(obs, "_x")``); every error class
sits in ``boresight/errors.py`` (whose docstring names it) or ``orbits/errors.py``. ``KNOWN_EXCEPTIONS``
(empty, and to stay so) would list imports that cross a layer the wrong way; the test fails if one
of them disappears (remove it from the list) or a new one appears.

Every import counts — top level or inside a function (a lazy import is still a dependency);
relative imports are resolved against the module's package.
"""

import ast
import pathlib
import subprocess
import sys

import pytest
from paths import ROOT

PKG = ROOT / "boresight"

# DECISION: atomic file writing (boresight/files.py) is infrastructure like the errors: the data
# format (observations/ecsv), the studies' checkpoints and every command's outputs use it, so it sits
# below every layer and imports nothing from boresight.
_BASE = {"errors", "stats", "files"}
ALLOWED = {
    "errors": set(),
    "stats": {"errors"},
    "files": set(),
    "core": _BASE,
    "observations": _BASE | {"core"},
    "reporting": _BASE | {"core", "observations"},
    "pointing": _BASE | {"core", "observations", "reporting"},
    "studies": _BASE | {"core", "observations", "reporting", "pointing"},
    "reproductions": _BASE | {"core", "observations", "reporting", "pointing", "studies"},
    "cli": _BASE | {"core", "observations", "reporting", "pointing", "studies", "reproductions"},
}
#: top-level modules of boresight/ that are not layers (the front door and the entry point)
FRONT = {"__init__", "__main__"}
CORE_FORBIDDEN = ("matplotlib", "astropy.table")
#: imports that still cross a layer the wrong way: (file relative to boresight/, imported module)
KNOWN_EXCEPTIONS: set = set()


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
    offenders = [
        f"{p.relative_to(ROOT)}: {n}" for p in _modules(ROOT / "orbits") for n in imports_of(p) if _matches(n, "boresight")
    ]
    assert offenders == []


def test_importing_orbits_loads_no_boresight_module():
    code = "import sys, orbits, orbits.scenario; print(sorted(m for m in sys.modules if m.split('.')[0] == 'boresight'))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


def _layer(path: pathlib.Path) -> str:
    return path.relative_to(PKG).parts[0].removesuffix(".py")


def _violations():
    """(file, boresight layer module) for every import of a layer its folder may not import."""
    found = set()
    for p in _modules(PKG):
        layer = _layer(p)
        if layer in FRONT:
            continue
        assert layer in ALLOWED, f"boresight/{layer} is not a known layer: add it to ALLOWED (and to docs/architecture.md)"
        for n in imports_of(p):
            parts = n.split(".")
            if parts[0] != "boresight" or len(parts) < 2:
                continue
            target = parts[1]
            if target in ALLOWED and target != layer and target not in ALLOWED[layer]:
                found.add((p.relative_to(PKG).as_posix(), f"boresight.{target}"))
            elif target not in ALLOWED and target not in FRONT and (PKG / f"{target}.py").exists():
                found.add((p.relative_to(PKG).as_posix(), f"boresight.{target}"))
    return found


def test_every_folder_imports_only_the_layers_below_it():
    found = _violations()
    new = sorted(found - KNOWN_EXCEPTIONS)
    gone = sorted(KNOWN_EXCEPTIONS - found)
    assert new == [], f"imports against the layers (see docs/architecture.md): {new}"
    assert gone == [], f"no longer crossing a layer, remove from KNOWN_EXCEPTIONS: {gone}"


def test_core_imports_no_plotting_or_tables():
    core = [p for p in _modules(PKG) if _layer(p) == "core"]
    assert any(p.name == "estimation.py" for p in core) and any("algorithms" in p.parts for p in core)
    offenders = [
        f"{p.relative_to(ROOT)}: {n}" for p in core for n in imports_of(p) if any(_matches(n, f) for f in CORE_FORBIDDEN)
    ]
    assert offenders == []


@pytest.mark.parametrize("module", ["core/crlb.py", "core/disturbances.py"])
def test_models_take_no_math_from_an_estimator(module):
    path = PKG / module
    assert [n for n in imports_of(path) if _matches(n, "boresight.core.algorithms")] == []


def test_the_rule_sees_a_violation(tmp_path, monkeypatch):
    """The folder rule would pass vacuously if it could not see a wrong-way import."""
    probe = PKG / "core" / "_layering_probe.py"
    probe.write_text("def f():\n    from boresight.studies import montecarlo\n")
    try:
        assert ("core/_layering_probe.py", "boresight.studies") in _violations()
    finally:
        probe.unlink()


def test_the_import_parser_sees_relative_and_lazy_imports(tmp_path):
    """The rules above would pass vacuously if ``imports_of`` missed these forms."""
    probe_rel = tmp_path / "rel.py"
    probe_rel.write_text("from ..disturbances import X\nfrom .image_plane import linearize\n")
    names = imports_of_file(probe_rel, "boresight.core.algorithms.rel")
    assert "boresight.core.disturbances" in names  # from ..disturbances import ...
    assert "boresight.core.algorithms.image_plane" in names  # from .image_plane import ...
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    import matplotlib.pyplot as plt\n    from astropy.table import Table\n")
    assert {"matplotlib.pyplot", "astropy.table", "astropy.table.Table"} <= set(imports_of_file(probe, "boresight.probe"))


def test_published_numbers_are_imported_only_by_reproductions_and_commands():
    """Each paper's ``published`` module: imported by its reproduction package (reports) and the
    command line only — never by the library proper (issue 18)."""
    pubs = {f"boresight.reproductions.{p.parent.name}.published" for p in PKG.glob("reproductions/*/published.py")}
    assert {"boresight.reproductions.kiev2012.published", "boresight.reproductions.usv_sea_sky.published"} <= pubs
    offenders = [
        f"{p.relative_to(PKG)}: {n}"
        for p in _modules(PKG)
        if _layer(p) not in ("reproductions", "cli")
        for n in imports_of(p)
        if any(_matches(n, m) for m in pubs)
    ]
    assert offenders == []


def test_importing_pointing_loads_no_estimator():
    """``import boresight.pointing`` (gimbal, turntable, sea-sky line) needs no θ estimator."""
    code = "import sys, boresight.pointing; print(sorted(m for m in sys.modules if m.startswith(('boresight.core.estimat', 'boresight.core.algorithms', 'boresight.studies'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == "[]"


def _import_graph():
    """module → the boresight modules it imports (an import of a package's submodule counts for the
    submodule, not for the package's own ``__init__``)."""
    mods = {_module_name(p): p for p in _modules(PKG)}

    def target(name):
        parts = name.split(".")
        while parts and ".".join(parts) not in mods:
            parts.pop()
        return ".".join(parts) or None

    graph = {}
    for m, p in mods.items():
        deps = {target(n) for n in imports_of(p)} - {None, m}
        graph[m] = {t for t in deps if not m.startswith(t + ".")}  # a submodule needs its package: not a circle
    return graph


def _circles(graph):
    """Strongly connected groups of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle():
    """No module of boresight imports, directly or round a circle, one that imports it (lazy imports
    count): the data model does not import its file format (``observations.model.FILE_FORMAT``)."""
    assert _circles(_import_graph()) == []
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]  # the check can fail


def _command_modules():
    """The ``cli/`` modules that are commands: they define ``register(subparsers)``."""
    out = set()
    for p in sorted((PKG / "cli").glob("*.py")):
        tree = ast.parse(p.read_text())
        if any(isinstance(n, ast.FunctionDef) and n.name == "register" for n in tree.body):
            out.add(_module_name(p))
    return out


def test_no_command_imports_another_command():
    """A command module (``cli/estimate.py``, …) is imported by no other ``cli/`` module: what two
    commands share lives in ``cli/options.py``, ``cli/noise_options.py``, ``cli/heartbeat.py``, …
    (``main.py`` assembles the commands by name, not by import)."""
    commands = _command_modules()
    assert {"boresight.cli.estimate", "boresight.cli.montecarlo", "boresight.cli.diagnose"} <= commands
    offenders = sorted(
        f"{p.relative_to(PKG)}: {n}"
        for p in _modules(PKG / "cli")
        for n in imports_of(p)
        if n in commands and n != _module_name(p)
    )
    assert offenders == []


#: the ``cli/`` modules that are not commands and that commands may import: what two commands share (options, the
#: noise-model options, the progress line, exit codes, the parser, the examples, the pushbroom inputs). A fixed list:
#: a new shared module is added here by name, and may hold no ``register`` and no ``run…`` function (a command's work).
CLI_SHARED = {"options", "noise_options", "heartbeat", "exit_codes", "parsing", "examples", "pushbroom_inputs"}
#: ``main`` assembles the commands by name (``_COMMAND_MODULES``), ``__init__`` is the package
CLI_ENTRY = {"main", "__init__"}


def _cli_import_offenders(cli_dir, package="boresight.cli", shared=CLI_SHARED):
    """Where ``cli_dir`` breaks the rule: (1) a module neither a command (``register``), the entry, nor in ``shared``;
    (2) a shared module defining ``register`` or a top-level ``run…`` function (a command hidden as a helper: the old
    ``cli/line_scan.py`` held seven commands' pushbroom ``run_*`` and escaped the command rule by having no
    ``register``); (3) a module other than the entry importing a ``cli`` module outside ``shared``."""
    mods = {p.stem: p for p in sorted(cli_dir.glob("*.py"))}
    out = []
    for name, p in mods.items():
        tree = ast.parse(p.read_text())
        defs = [n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
        command = "register" in defs
        if name in CLI_ENTRY:
            continue
        if not command and name not in shared:
            out.append(f"{name}: neither a command (register) nor a shared cli module ({sorted(shared)})")
        if name in shared and (command or any(d.startswith("run") for d in defs)):
            out.append(f"{name}: a shared cli module defines {[d for d in defs if d == 'register' or d.startswith('run')]}")
        for n in imports_of_file(p, f"{package}.{name}"):
            other = n[len(package) + 1 :].split(".")[0] if n.startswith(package + ".") else None
            if other in mods and other != name and other not in shared:
                out.append(f"{name} imports {package}.{other}")
    return sorted(set(out))


def test_commands_import_only_the_shared_cli_modules():
    """Of ``cli/``, a command imports only ``CLI_SHARED``; every other cli module is a command or the entry; a shared
    module holds no command (no ``register``, no ``run…``). Stricter than "no command imports another" (which only
    knew commands by ``register``): a helper module holding commands' work is refused by name."""
    assert _cli_import_offenders(PKG / "cli") == []


def test_the_shared_cli_rule_sees_a_hidden_command(tmp_path):
    """The rule can fail: a helper without ``register`` whose ``run_estimate`` two commands import (the shape of the
    old ``cli/line_scan.py``), and a shared module that grew a ``run``."""
    cli = tmp_path / "cli"
    cli.mkdir()
    (cli / "helper.py").write_text("def run_estimate(args):\n    return 0\n")
    (cli / "options.py").write_text("def run(args):\n    return 0\n")
    (cli / "estimate.py").write_text(
        "from boresight.cli import helper\nfrom boresight.cli.options import run\n\ndef register(sub):\n    pass\n"
    )
    found = _cli_import_offenders(cli)
    assert any(f.startswith("helper: neither a command") for f in found), found
    assert "estimate imports boresight.cli.helper" in found, found
    assert any(f.startswith("options: a shared cli module defines") for f in found), found


def _statistics_imported(cli_dir):
    """(module, import) of every ``cli`` module importing a statistic: ``boresight.stats`` or ``scipy.stats``."""
    return sorted(
        (p.stem, n)
        for p in sorted(cli_dir.glob("*.py"))
        for n in imports_of_file(p, f"boresight.cli.{p.stem}")
        if _matches(n, "boresight.stats") or _matches(n, "scipy.stats")
    )


def test_commands_compute_no_statistic(tmp_path):
    """A command prints the statistics the library returned (its χ² test, σ and rate intervals, residual statistics)
    and computes none: no ``cli`` module imports ``boresight.stats`` or ``scipy.stats``. The pushbroom Monte Carlo
    rebuilt its runs within 3σ from rounded fractions and called ``stats.binomial_interval`` itself (now
    ``LineScanMonteCarlo.count_within_3_sigma`` / ``within_3_sigma_interval``). The check can fail: a tmp module
    importing ``binomial_interval`` is found."""
    assert _statistics_imported(PKG / "cli") == []
    (tmp_path / "mc.py").write_text("def run(a):\n    from boresight.stats import binomial_interval\n")
    assert ("mc", "boresight.stats.binomial_interval") in _statistics_imported(tmp_path)


#: the reductions that describe data (its range, centre or spread), called as ``np.f(x)`` or ``x.f()``
_DATA_REDUCTIONS = {
    "min",
    "max",
    "amin",
    "amax",
    "nanmin",
    "nanmax",
    "ptp",
    "mean",
    "nanmean",
    "average",
    "median",
    "nanmedian",
    "percentile",
    "nanpercentile",
    "quantile",
    "nanquantile",
    "std",
    "nanstd",
    "var",
    "nanvar",
}


def _data_reductions(cli_dir):
    """``module:line call`` of every attribute call to one of ``_DATA_REDUCTIONS`` in the ``cli`` modules."""
    found = []
    for p in sorted(cli_dir.glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in _DATA_REDUCTIONS:
                found.append(f"{p.stem}:{node.lineno} {ast.unparse(node)}")
    return found


def test_commands_compute_no_description_of_their_data(tmp_path):
    """A command prints the ranges, means and spreads of its input as the library returns them, under a name
    (``ObservationSet.landmark_range_span_m``, ``field_angle_span_deg``, ``sigma_xy_span_m``, ``pass_time_span_s``,
    ``line_span``; ``OrbitTrack.position_sigma``; ``star_centroids.centroid_sigma_span_px``): no ``cli`` module calls
    a numpy reduction of ``_DATA_REDUCTIONS`` (``simulate`` computed the landmarks' range, ``ingest`` the OEM
    covariance's σ range and the σ it wrote). Counts (``sum``, ``size``) and formatting are the command's. The check
    can fail: a tmp module taking ``obs.t_s.max()`` and ``np.percentile`` is found."""
    assert _data_reductions(PKG / "cli") == []
    (tmp_path / "cmd.py").write_text("import numpy as np\ndef run(obs):\n    print(obs.t_s.max(), np.percentile(obs.z, 90))\n")
    assert _data_reductions(tmp_path) == ["cmd:3 obs.t_s.max()", "cmd:3 np.percentile(obs.z, 90)"]


#: private names still imported across modules: (file relative to boresight/, module, name), each
#: with who removes it. Shrink only: the test fails when one of these disappears, so it is deleted here.
PRIVATE_IMPORT_EXCEPTIONS: set[tuple[str, str, str]] = set()


def _private_imports(root):
    """(file, module, name) for every ``from M import _name`` of a boresight or orbits module
    (``__dunder__`` names excepted), absolute or relative."""
    found = set()
    for p in _modules(root):
        tree = ast.parse(p.read_text())
        pkg = list(p.relative_to(root.parent).with_suffix("").parts)[:-1]  # the package the module is in
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            mod = ".".join(pkg[: len(pkg) - node.level + 1] + [node.module or ""]) if node.level else node.module or ""
            if mod.split(".")[0] not in ("boresight", "orbits"):
                continue
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.add((p.relative_to(root).as_posix(), mod.rstrip("."), a.name))
    return found


def test_no_private_name_is_imported_across_modules():
    """``from boresight.x import _y`` makes ``_y`` public in all but name: give it a public name (or an
    accessor) where it is defined. ``orbits/`` is held to the same rule."""
    found = _private_imports(PKG) | {("orbits/" + f, m, n) for f, m, n in _private_imports(ROOT / "orbits")}
    new = sorted(found - PRIVATE_IMPORT_EXCEPTIONS)
    gone = sorted(PRIVATE_IMPORT_EXCEPTIONS - found)
    assert new == [], f"private names imported across modules: {new}"
    assert gone == [], f"no longer imported, remove from PRIVATE_IMPORT_EXCEPTIONS: {gone}"


def test_the_private_import_rule_sees_one(tmp_path):
    """The rule would pass vacuously if it missed ``from .x import _y`` or ``from boresight.x import _y``."""
    pkg = tmp_path / "boresight" / "core"
    pkg.mkdir(parents=True)
    (pkg / "probe.py").write_text("from .measurement import _projected\nfrom orbits.camera import _x as y\n")
    found = _private_imports(tmp_path / "boresight")
    assert ("core/probe.py", "boresight.core.measurement", "_projected") in found
    assert ("core/probe.py", "orbits.camera", "_x") in found


def _private_definitions(tree: ast.AST) -> set:
    """The private names a module defines: functions, classes, module or class-level assignments and
    attributes it stores (``self._x = …``)."""
    out = set()
    for n in ast.walk(tree):
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(n.name)
        elif isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store):
            out.add(n.attr)
        elif isinstance(n, (ast.Assign, ast.AnnAssign)):
            out |= {t.id for t in (n.targets if isinstance(n, ast.Assign) else [n.target]) if isinstance(t, ast.Name)}
    return {x for x in out if x.startswith("_") and not x.startswith("__")}


def _private_attribute_uses(roots, base: pathlib.Path = ROOT) -> set:
    """(file, expression, defining files) for every ``x._name`` (or ``getattr(x, "_name")``) in the
    modules under ``roots`` whose ``_name`` is defined only in other modules: another module's private
    method or attribute reached through an object (``obs._target_kinds()``), which no import shows.
    ``self._x`` and ``cls._x`` are the class's own; a name the file defines too is its own."""
    trees = {p: ast.parse(p.read_text()) for root in roots for p in _modules(root)}
    defined: dict = {}
    for p, tree in trees.items():
        for name in _private_definitions(tree):
            defined.setdefault(name, set()).add(p)
    found = set()
    for p, tree in trees.items():
        for n in ast.walk(tree):
            if isinstance(n, ast.Attribute):
                owner, name = n.value, n.attr
            elif (
                isinstance(n, ast.Call)
                and isinstance(n.func, ast.Name)
                and n.func.id in ("getattr", "hasattr", "setattr")
                and len(n.args) >= 2
                and isinstance(n.args[1], ast.Constant)
                and isinstance(n.args[1].value, str)
            ):
                owner, name = n.args[0], n.args[1].value
            else:
                continue
            if not name.startswith("_") or name.startswith("__"):
                continue
            if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
                continue
            where = defined.get(name, set())
            if where and p not in where:
                rel = sorted(w.relative_to(base).as_posix() for w in where)
                found.add((p.relative_to(base).as_posix(), ast.unparse(n)[:60], ", ".join(rel)))
    return found


def test_no_private_attribute_is_used_across_modules():
    """``obs._target_kinds()`` in another module makes ``_target_kinds`` public in all but name, as an
    import of it would: give it a public, documented name where it is defined."""
    offenders = [
        f"{f}: {expr} (defined in {where})" for f, expr, where in sorted(_private_attribute_uses([PKG, ROOT / "orbits"]))
    ]
    assert offenders == [], "private names used across modules:\n" + "\n".join(offenders)


def test_the_private_attribute_rule_sees_one(tmp_path):
    """The rule would pass vacuously if it missed an attribute, a method call or a ``getattr`` string."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "model.py").write_text(
        "class Set:\n    def _kinds(self):\n        return self._cache\n\n    def f(self):\n        self._cache = 1\n"
    )
    (pkg / "user.py").write_text(
        "def g(obs, problem):\n    return obs._kinds(), obs._cache, getattr(problem, '_kinds', None), obs._own\n\n\n_own = 1\n"
    )
    found = {(f, expr) for f, expr, _ in _private_attribute_uses([pkg], base=pkg)}
    assert found == {("user.py", "obs._kinds"), ("user.py", "obs._cache"), ("user.py", "getattr(problem, '_kinds', None)")}


def _module_strings(path: pathlib.Path) -> list:
    """String constants of ``path`` that are exactly a boresight module name (``"boresight.x.y"``):
    what ``importlib.import_module`` will load, an import the AST's import nodes do not show."""
    import re

    name = re.compile(r"^boresight(\.\w+)+$")
    return [
        n.value
        for n in ast.walk(ast.parse(path.read_text()))
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and name.match(n.value)
    ]


def test_module_names_in_strings_obey_the_layers():
    """A module named in a string (the registry's rows, a lazy export table) is loaded by importlib:
    it obeys the same folder rule, so the core's registry names no study module."""
    offenders = []
    for p in _modules(PKG):
        layer = _layer(p)
        if layer in FRONT:
            continue
        for n in _module_strings(p):
            target = n.split(".")[1]
            if target in ALLOWED and target != layer and target not in ALLOWED[layer]:
                offenders.append(f"{p.relative_to(PKG)}: {n!r}")
    assert offenders == []
    assert "boresight.core.algorithms.batched" in _module_strings(PKG / "core" / "registry.py")  # the rule sees the rows


def _error_classes(root: pathlib.Path) -> set:
    """(file relative to ``root``, class) of every class named ``…Error`` at the top level of a module."""
    found = set()
    for p in _modules(root):
        for node in ast.parse(p.read_text()).body:
            if isinstance(node, ast.ClassDef) and node.name.endswith("Error"):
                found.add((p.relative_to(root).as_posix(), node.name))
    return found


def test_errors_live_in_one_place():
    """Every error class of a package is defined in its one errors module — ``boresight/errors.py``,
    ``orbits/errors.py`` (the lower package, which never imports ``boresight``): a reader finds them in
    one file, and the modules that raise them import them from there."""
    for root in (PKG, ROOT / "orbits"):
        found = _error_classes(root)
        assert sorted(f for f in found if f[0] != "errors.py") == [], f"define error classes in {root.name}/errors.py"
    assert ("errors.py", "ConventionError") in _error_classes(PKG)  # the rule sees the files
    assert ("errors.py", "ScenarioError") in _error_classes(ROOT / "orbits")


def test_the_errors_module_names_its_classes():
    """``boresight/errors.py``'s docstring is its table of contents: it names every error it defines or
    re-exports (a class added without a line there fails here)."""
    import boresight.errors as errors

    names = {n for n in errors.__all__ if n.endswith("Error")}
    assert {"ConventionError", "ObservationError", "PlanError", "BoresightError"} <= names  # the rule sees them
    assert sorted(n for n in names if f"``{n}``" not in (errors.__doc__ or "")) == []
