"""The documentation builds with no warning: the API reference (autodoc over the public modules,
numpy-style docstrings) and the narrative docs (Markdown), ``sphinx -W`` as in a release.

Skipped only where Sphinx is not installed (the ``test`` extra installs it, so CI builds it)."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys

import pytest
from paths import ROOT


@pytest.fixture(scope="module")
def html(tmp_path_factory):
    """The site, built once: ``sphinx -E -W`` (every warning an error), the gallery's scripts run."""
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("sphinx_gallery")
    pytest.importorskip("matplotlib")
    out = tmp_path_factory.mktemp("docs") / "html"
    env = dict(os.environ, BORESIGHT_GALLERY_WORKDIR=str(out.parent), BORESIGHT_GALLERY_SMALL="1")
    r = subprocess.run(
        [sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html", str(ROOT / "docs"), str(out)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
        env=env,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    return out


def test_docs_build_without_warnings(html):
    assert (html / "api" / "boresight.html").exists()


#: figures each gallery script writes (the PNG files of its commands, or its own pyplot figure)
GALLERY_FIGURES = {
    "estimate_a_pass": 1,  # the histogram of residual_z
    "flight_pass": 2,  # estimate --out: residuals on the focal plane and against time
    "diagnose_hidden_effects": 2,  # one residual plot per named effect (time_tag, radial_distortion)
    "plan_a_campaign": 1,  # plan.png, the Pareto front
    "reproduce_kiev2012": 2,  # the eq 28 and Kalman figures of the report
}


def test_the_gallery_renders_every_example_with_its_figures(html):
    """Every script of ``examples/gallery/`` has its page with code, printed output and its figures,
    and the gallery's index shows one thumbnail per script."""
    scripts = sorted(p.stem for p in (ROOT / "examples" / "gallery").glob("*.py") if not p.name.startswith("_"))
    assert sorted(GALLERY_FIGURES) == scripts
    index = (html / "examples" / "index.html").read_text()
    assert sorted(set(re.findall(r"sphx_glr_([a-z_0-9]+)_thumb\.png", index))) == scripts
    for name, n in GALLERY_FIGURES.items():
        page = (html / "examples" / f"{name}.html").read_text()
        images = set(re.findall(rf'<img[^>]+src="[^"]*(sphx_glr_{name}_\d+\.png)"', page))
        assert len(images) == n, f"{name}: {len(images)} figure(s) on its page, expected {n}"
        assert all((html / "_images" / i).stat().st_size > 5000 for i in images), name  # real figures, not blanks
        assert "sphx-glr-script-out" in page, f"{name}: no printed output on its page"
        assert "highlight-Python" in page or "highlight-python" in page, f"{name}: no code on its page"
        # the pages show what a reader's run prints: paths relative to the working folder, not the builder's
        for path in (str(html.parent), str(ROOT), "/tmp/"):  # its working folder, its checkout, any temporary one
            assert path not in page, f"{name}: the builder's absolute path {path} on its page"


def test_the_docs_ship_with_the_package_and_the_command_prints_them(capsys):
    from boresight.cli.docs import shipped_docs
    from boresight.cli.main import main

    docs = shipped_docs()
    assert {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"} == set(docs)
    assert main(["docs"]) == 0
    out = capsys.readouterr().out
    assert "tutorial-flight-data" in out and "Tutorial" in out
    assert "run one from a working folder of yours, not from that folder" in out  # not inside site-packages
    assert main(["docs", "conventions"]) == 0
    assert capsys.readouterr().out == (ROOT / "docs" / "conventions.md").read_text()
    assert main(["docs", "convention"]) == 1
    assert "did you mean 'conventions'" in capsys.readouterr().err


# ---------------------------------------------------------------------------- what the guides name exists

#: the guides a user reads (README and docs/): every file path and dotted name they give must exist
GUIDES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: a path in a guide: from the repository root anywhere in the text, or in backticks relative to the package
#: (`core/gls/rows.py`, as architecture.md writes them); a trailing `.name` or `:name` names a definition in it
ROOT_PATH = re.compile(r"(?<![\w./-])((?:boresight|orbits|tests|scenarios|benchmarks|examples|docs|plans)/[\w./:\-*]*[\w/*])")
PACKAGE_PATH = re.compile(
    r"(?<![\w./-])((?:core|observations|reporting|pointing|studies|reproductions|cli|stats|data)/[\w./:\-]*\w)"
)

#: paths a guide writes that are not files of the checkout: a placeholder for the reader's own name, a glob,
#: the gallery's index that sphinx-gallery writes while the site builds (docs/gallery.md's toctree)
NOT_FILES = re.compile(r"NAME|(?<![\w-])x\.toml|\*")
BUILT_BY_SPHINX = {"examples/index"}

#: file types a dotted word in backticks may end in without being a Python name (`montecarlo.json`)
FILE_SUFFIXES = r"py|toml|ecsv|csv|json|md|png|txt|parquet|oem|aem|tle|xml|npz|lock|pid|bsp|bc|tf"

#: a dotted Python name in backticks: from a package, or from a subpackage as the guides abbreviate it
#: (`gls.rows.row_residuals` is `boresight.core.gls.rows.row_residuals`)
DOTTED_PREFIX = {
    "boresight": "boresight",
    "orbits": "orbits",
    "core": "boresight.core",
    "algorithms": "boresight.core.algorithms",
    "gls": "boresight.core.gls",
    "observations": "boresight.observations",
    "flight": "boresight.observations.flight",
    "reporting": "boresight.reporting",
    "pointing": "boresight.pointing",
    "studies": "boresight.studies",
    "montecarlo": "boresight.studies.montecarlo",
    "discrepancy": "boresight.studies.discrepancy",
    "planning": "boresight.studies.planning",
    "reproductions": "boresight.reproductions",
    "kiev2012": "boresight.reproductions.kiev2012",
    "stats": "boresight.stats",
    "cli": "boresight.cli",
}
DOTTED = re.compile(rf"(?<![\w./-])((?:{'|'.join(DOTTED_PREFIX)})(?:\.[A-Za-z_]\w*)+)(?![\w/-])")


def _defines(path, name: str) -> bool:
    """Whether the Python file ``path`` defines ``name`` at its top level or in a class (def, class, assignment)."""
    return (
        re.search(rf"^\s*(?:async def|def|class) {re.escape(name)}\b|^\s*{re.escape(name)}\s*[:=]", path.read_text(), re.M)
        is not None
    )


def _path_problem(written: str, bases) -> str | None:
    """None if the path ``written`` (with an optional ``.name`` / ``:name`` of a definition) exists under one of ``bases``."""
    if NOT_FILES.search(written) or written in BUILT_BY_SPHINX:
        return None
    path, _, name = written.partition("::") if "::" in written else written.partition(":")  # a test, or a definition
    name = name.split("::")[0]  # a test class's method: its class is defined
    for base in bases:
        f = base / path
        if not name and (f.exists() or (base / f"{path}.py").exists()):  # a file, a folder, a module (`tests/builders`)
            return None
        if f.suffix == ".py" and f.exists():
            return None if _defines(f, name) else f"{path} defines no {name}"
        stem, dot, attr = path.rpartition(".")
        if dot and (base / f"{stem}.py").exists() and not re.fullmatch(FILE_SUFFIXES, attr):
            return None if _defines(base / f"{stem}.py", attr) else f"{stem}.py defines no {attr}"
    return "no such file"


def _name_problem(dotted: str) -> str | None:
    """None if ``dotted`` imports: its longest importable module prefix, then attributes."""
    import importlib

    first, *rest = dotted.split(".")
    parts = DOTTED_PREFIX[first].split(".") + rest
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for k, attr in enumerate(parts[i:], i):
            if not hasattr(obj, attr):
                return f"{'.'.join(parts[:k])} has no {attr}"
            obj = getattr(obj, attr)
        return None
    return "no such module"


def _references():
    """(guide:line, kind, reference) for every path and dotted name the guides give."""
    for guide in GUIDES:
        text = guide.read_text()
        line = lambda i: f"{guide.relative_to(ROOT)}:{text.count(chr(10), 0, i) + 1}"  # noqa: E731
        for m in ROOT_PATH.finditer(text):
            yield line(m.start()), "path", m.group(1)
        for span in re.finditer(r"`([^`\n]+)`", text):
            for m in PACKAGE_PATH.finditer(span.group(1)):
                yield line(span.start()), "package path", m.group(1)
            for m in DOTTED.finditer(span.group(1)):
                if not re.fullmatch(FILE_SUFFIXES, m.group(1).rpartition(".")[2]):  # `montecarlo.json` is a file
                    yield line(span.start()), "name", m.group(1)


def test_every_path_and_name_the_guides_give_exists():
    """A guide that names a file (`tests/oracles.py:dense_rows`, `core/gls/rows.py`) or a Python name
    (`boresight.core.gls.rows.row_residuals`, `gls.campaign.fit_rows`) names one that exists: a module moved or
    a function renamed fails here, with the guide's line."""
    refs = list(_references())
    kinds = {k for _, k, _ in refs}
    assert kinds == {"path", "package path", "name"} and len(refs) > 500, (kinds, len(refs))  # the scan sees the guides
    problems = []
    for where, kind, ref in refs:
        if kind == "name":
            problem = _name_problem(ref)
        else:
            problem = _path_problem(ref, [ROOT] if kind == "path" else [ROOT / "boresight"])
        if problem:
            problems.append(f"{where}: `{ref}`: {problem}")
    assert problems == [], "\n".join(problems)


def test_the_reference_check_can_fail():
    """The checks above see a moved module, a deleted function and a missing file."""
    assert _name_problem("gls.campaign.reduced_rows") == "boresight.core.gls.campaign has no reduced_rows"
    assert _name_problem("boresight.observations.LIMITS") == "boresight.observations has no LIMITS"
    assert _name_problem("gls.rows.row_reduced_rows") is None
    assert _path_problem("tests/test_pointing_gimbal.py", [ROOT]) == "no such file"
    assert _path_problem("tests/oracles.py:dense_rows", [ROOT]) is None
    assert _path_problem("tests/oracles.py:no_such_oracle", [ROOT]) == "tests/oracles.py defines no no_such_oracle"
    assert _path_problem("core/disturbances.error_jacobians", [ROOT / "boresight"]) is None
    assert _path_problem("tests/builders.no_such_builder", [ROOT]) == "tests/builders.py defines no no_such_builder"


def test_the_readme_names_every_extra_with_its_licence_section():
    """Every optional extra of ``pyproject.toml`` is named in the README's "Dependencies and licences" (a new
    extra brings a new licence a user must be able to read about), and the README names no extra that is gone."""
    import tomllib

    extras = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])
    section = (ROOT / "README.md").read_text().split("## Dependencies and licences", 1)[1]
    named = set(re.findall(r"`([a-z][\w-]*)` —", section))  # each written "`name` — its packages (licence) …"
    assert extras <= named, f"extras not in the README's licences: {sorted(extras - named)}"
    assert named - extras == set(), f"the README names extras pyproject.toml does not have: {sorted(named - extras)}"


def _power_of_ten(v: float) -> str:
    """``1e9`` → ``"10⁹"`` as the guides write a bound (a round number otherwise: ``100``)."""
    e = round(math.log10(v))
    return "10" + str(e).translate(str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")) if v == 10.0**e and e > 2 else f"{v:g}"


def test_the_reliability_guide_states_the_librarys_thresholds():
    """The thresholds and defaults ``docs/reliability.md`` states are the library's, computed here from its constants and
    functions: the weights below which a robust loss rejects an observation, the scatter check's threshold for
    kiev2012-kalman20's components and its minimum, the small-angle limit, the reader's bounds, the memory budget, the
    checkpoint's sync interval and block size, every exit status. A constant changed without its guide fails here."""
    import numpy as np
    from scipy.optimize import brentq

    from boresight import simulate
    from boresight.cli import exit_codes
    from boresight.core.consistency import MIN_COMPONENTS, threshold
    from boresight.core.robust import REJECTED_WEIGHT, robust_weights
    from boresight.observations.model import LIMITS
    from boresight.studies.montecarlo.checkpoint import SYNC_INTERVAL_S
    from boresight.studies.montecarlo.seeding import BLOCK_RUNS
    from orbits.limits import DEFAULT_MEMORY_BUDGET_GB
    from orbits.rotations import SMALL_ANGLE_LIMIT_ARCSEC

    text = " ".join((ROOT / "docs" / "reliability.md").read_text().split())  # prose wraps anywhere

    def rejected_above(loss):
        return brentq(lambda z: robust_weights(np.array([z]), loss)[0] - REJECTED_WEIGHT, 1e-3, 1e4)

    components = 2 * simulate("kiev2012-kalman20", np.random.default_rng(0)).n_observations
    spaced = f"{SMALL_ANGLE_LIMIT_ARCSEC:,.0f}".replace(",", " ")
    stated = [
        f"(weight < {REJECTED_WEIGHT:g}: Huber z > {rejected_above('huber'):.0f}, Cauchy z > {rejected_above('cauchy'):.1f}, "
        f"Tukey z > {rejected_above('tukey'):.2f};",
        f"{threshold(components):.2f} for the {components} components of kiev2012-kalman20. At least {MIN_COMPONENTS} components",
        f"(|θ| > {spaced}″ = {SMALL_ANGLE_LIMIT_ARCSEC / 3600:g}°, `orbits.rotations.SMALL_ANGLE_LIMIT_ARCSEC`)",
        f"at most {spaced}″ ({SMALL_ANGLE_LIMIT_ARCSEC / 3600:g}°)",
        f"The budget is {DEFAULT_MEMORY_BUDGET_GB:g} GiB by default.",
        f"every {SYNC_INTERVAL_S:g} s (`checkpoint.SYNC_INTERVAL_S`)",
        f"(`--block-runs`, default {BLOCK_RUNS},",
    ]
    columns = {"t_s": "`t`", "r_sc_i_m": "`r_x r_y r_z`", "v_sc_i_m_s": "`v_x v_y v_z`", "landmark_g_m": "`X Y Z`"}
    columns |= {"xy_m": "`x y`", "focal_length_m": "metadata `focal_length_m`"}
    assert set(columns) == set(LIMITS), "a bound of the reader that the guide's table does not show"
    stated += [f"| {columns[k]} | {_power_of_ten(v)} {unit.replace(' ', '')} |" for k, (v, unit, _) in LIMITS.items()]
    stated += [f"| {v} | `{k}` |" for k, v in vars(exit_codes).items() if k.startswith("EXIT_")]
    missing = [s for s in stated if s not in text]
    assert missing == [], "docs/reliability.md does not state the library's value:\n" + "\n".join(missing)


def _mib(n_bytes: float) -> str:
    """``2**28`` → ``"256 MiB"``, ``2**30`` → ``"1 GiB"``: a size as the guides write it."""
    return f"{n_bytes / 2**30:g} GiB" if n_bytes >= 2**30 else f"{n_bytes / 2**20:g} MiB"


def test_the_architecture_states_the_librarys_thresholds():
    """The sizes and thresholds ``docs/architecture.md`` states for the one GLS, the reader's budget and the
    observability check are the library's constants (a constant changed without its guide fails here)."""
    import inspect

    from boresight.core.algorithms.homography import estimate_homography
    from boresight.core.gls import rows
    from boresight.core.gls.normal_equations import DEFAULT_MAX_CONDITION
    from boresight.observations.ecsv import READ_BYTES_PER_FILE_BYTE, READ_FIXED_BYTES

    text = " ".join((ROOT / "docs" / "architecture.md").read_text().split())
    leverage_max = f"{rows.LEVERAGE_MAX:,}".replace(",", " ")
    dlt_condition = inspect.signature(estimate_homography).parameters["cond_max"].default
    stated = [
        f"up to {leverage_max} unknowns a block; else from S⁻¹ formed whole up to D = {leverage_max}",
        f"S⁻¹ whole only up to {leverage_max} unknowns and {_mib(rows.LEVERAGE_INVERSE_MAX_BYTES)} over the runs; above, the band "
        f"selected inverse within {_mib(rows.SELECTED_INVERSE_MAX_BYTES)} per run, else batches of solves of "
        f"{_mib(8 * rows.LEVERAGE_SOLVE_ELEMENTS)}",
        f"`estimate` warns above {rows.CONDITION_WARN:.0e}".replace("e+", "e"),
        f"{READ_BYTES_PER_FILE_BYTE:g} × the ECSV file's size + {_mib(READ_FIXED_BYTES)}",
        f"DLT condition number above {dlt_condition:.0e}".replace("e+", "e"),
        f"condition number (threshold {DEFAULT_MAX_CONDITION:.0e})".replace("e+", "e").replace("e0", "e"),
    ]
    missing = [s for s in stated if s not in text]
    assert missing == [], "docs/architecture.md does not state the library's value:\n" + "\n".join(missing)


def test_the_architecture_lists_every_shared_test_helper():
    """Every helper module in ``tests/`` itself (what tests share, imported by name) is named in docs/architecture.md's
    "A test" paragraph, so a reader finds the one place a setup lives before writing it again."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    paragraph = text[text.index("* **A test**") :].split("\n\n", 1)[0]
    helpers = sorted(p.name for p in (ROOT / "tests").glob("*.py"))
    assert len(helpers) > 10, helpers
    assert [h for h in helpers if f"`{h}`" not in paragraph] == []


def test_the_architecture_names_every_module():
    """Every module of ``boresight/`` and ``orbits/`` is named in docs/architecture.md (its module maps: the module's
    name, file or path in backticks), so the picture of the code stays the tree's: a module added, moved or split
    without its line in the map fails here."""
    ticks = {
        tok
        for m in re.finditer(r"`([^`\n]+)`", (ROOT / "docs" / "architecture.md").read_text())
        for tok in re.findall(r"[\w./]+", m.group(1))
    }
    modules = sorted(p.relative_to(ROOT) for top in ("boresight", "orbits") for p in (ROOT / top).rglob("*.py"))
    assert len(modules) > 150, len(modules)
    unnamed = [
        str(p)
        for p in modules
        if p.stem not in ("__init__", "__main__")
        and not {p.stem, p.name, str(p), str(p.relative_to(p.parts[0])), f"{p.parent.name}/{p.name}"} & ticks
    ]
    assert unnamed == [], f"add these modules to docs/architecture.md's module map: {unnamed}"


#: a command line in a guide: a line of a fenced code block (``$ `` prompt optional), or a span in backticks, that
#: starts with ``boresight COMMAND`` (not ``boresight COMMAND:``, the start of a printed message)
FENCED = re.compile(r"^```[^\n]*\n(.*?)^```", re.M | re.S)
COMMAND = r"boresight (pointing sea-sky|[a-z]+)(?![\w:-])"
COMMAND_LINE = re.compile(rf"^(?:\$ )?{COMMAND}(.*)", re.M)
COMMAND_SPAN = re.compile(rf"`{COMMAND}([^`\n]*)`")


def _command_lines(guide):
    """(where, command, the rest of its line) of every command line of ``guide``."""
    text = guide.read_text()
    where = lambda i: f"{guide.relative_to(ROOT)}:{text.count(chr(10), 0, i) + 1}"  # noqa: E731
    for block in FENCED.finditer(text):
        for m in COMMAND_LINE.finditer(block.group(1)):
            yield where(block.start(1) + m.start()), m.group(1), m.group(2)
    prose = FENCED.sub(lambda b: "\n" * b.group(0).count("\n"), text)  # the same line numbers
    for m in COMMAND_SPAN.finditer(prose):
        yield where(m.start()), m.group(1), m.group(2)


def test_every_command_line_in_the_guides_uses_options_the_command_has(capsys):
    """Each ``boresight COMMAND … --option`` written in README.md or docs/*.md names a command that exists and options
    it takes (read off its own ``--help``): a renamed or removed option fails here with the guide's line."""
    from boresight.cli.main import main

    helps: dict = {}

    def help_of(command: str) -> str:
        if command not in helps:
            with pytest.raises(SystemExit) as exit_:
                main([*command.split(), "--help"])
            helps[command] = capsys.readouterr().out if exit_.value.code == 0 else ""
        return helps[command]

    lines = [line for guide in GUIDES for line in _command_lines(guide)]
    assert len(lines) > 100, len(lines)  # the scan sees the guides' commands
    problems = []
    for where, command, rest in lines:
        text = help_of(command)
        if not text:
            problems.append(f"{where}: boresight {command}: no such command")
            continue
        options = re.findall(r"(?<![\w-])(--[a-z][\w-]*)", rest.split("#")[0])  # not a comment's words
        problems += [
            f"{where}: boresight {command} {o}: not an option of it" for o in options if not re.search(rf"{o}(?![\w-])", text)
        ]
    assert problems == [], "\n".join(problems)


def test_the_pointing_guide_states_what_the_command_prints(tmp_path, capsys):
    """docs/pointing.md's sea-sky numbers are what ``boresight pointing sea-sky`` prints for the shipped 120 frames (the
    guide says the command prints them): its table's coarse, grid and least-squares rows, and the residual analysis'
    attitude effect, F-test, outliers, autocorrelation, harmonics and bins, each rounded as the guide writes it."""
    from boresight.cli.main import main

    assert main(["pointing", "sea-sky", "--no-plots", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    text = " ".join((ROOT / "docs" / "pointing.md").read_text().split())

    def got(pattern):
        m = re.search(pattern, out)
        assert m, f"the command no longer prints {pattern!r}:\n{out}"
        return m.groups()

    coarse = got(r"coarse \(eq 23, special points .*?\): alpha = ([\d.]+), beta = ([\d.]+) deg")
    grid = got(r"grid \(eq 24.*?\): alpha = ([\d.]+), beta = ([\d.]+) deg")
    ls = got(
        r"least squares \(huber\): alpha = ([\d.]+) ± ([\d.]+), beta = ([\d.]+) ± ([\d.]+) deg.*?iid ± ([\d.]+), ([\d.]+); n_eff ([\d.]+)/120"
    )
    level = got(r"without hull attitude \(P = R = 0\): alpha = ([\d.]+), beta = ([\d.]+) deg")
    gain = got(r"attitude gain k .*?: ([\d.]+) ± ([\d.]+)")
    effect = got(r"max \|effect of P, R on fitted h'\| = ([\d.]+) deg \(inlier rms residual ([\d.]+) deg\)")
    f_test = got(r"F = ([\d.]+), p = ([\d.]+) \(n_eff: p = ([\d.]+)\), dAIC = ([\d.]+)")
    outliers = re.findall(r"frame (\d+) \(", out)
    acf = got(r"lag-1 acf ([\d.]+), n_eff = ([\d.]+) of 120")
    harmonics = re.findall(r"k=\d: ([\d.]+)±", out)
    bins = got(r"binned vs azimuth .*?chi2/dof = ([\d.]+/\d+), p = ([\d.]+)")
    attitude = got(r"binned vs pitch: p = ([\d.]+); vs roll: p = ([\d.]+)")

    def r(v, digits):
        return f"{float(v):.{digits}f}"

    stated = [
        f"| {coarse[0]}, {coarse[1]} |",
        f"| **{grid[0]}, {grid[1]}** |",
        f"**{ls[0]} ± {ls[1]}, {ls[2]} ± {ls[3]}** (1σ HAC) | iid ±{ls[4]}, ±{ls[5]}; n_eff {r(ls[6], 0)}/120 |",
        f"| {level[0]}, {level[1]} |",
        f"k = {r(gain[0], 1)} ± {r(gain[1], 1)}",
        f"at most **{effect[0]}°**, against an inlier rms residual of **{effect[1]}°**",
        f"F = {f_test[0]}, p = {r(f_test[1], 2)} (p = {r(f_test[2], 2)} with n_eff), ΔAIC = +{f_test[3]}",
        f"**{', '.join(outliers)}**",
        f"Lag-1 autocorrelation of ψ(r) {acf[0]}, n_eff = {r(acf[1], 0)} of 120",
        f"amplitudes {', '.join(harmonics)}°",
        f"χ² = {bins[0]} (p = {bins[1]},",
        f"Binned by pitch p = {r(attitude[0], 2)}, by roll p = {r(attitude[1], 2)}",
    ]
    assert len(outliers) == 8 and len(harmonics) == 4, (outliers, harmonics)
    missing = [s for s in stated if s not in text]
    assert missing == [], "docs/pointing.md does not state what the command prints:\n" + "\n".join(missing)


def test_the_guides_python_examples_import_what_exists():
    """Every ``import`` / ``from … import …`` of boresight or orbits in a ```python block of README.md or docs/*.md
    names a module and names that exist (the examples are run by hand with the guides' sizes; their imports are
    checked here, cheaply: a moved function fails with the guide's line)."""
    import ast
    import importlib

    blocks = [(guide, m) for guide in GUIDES for m in re.finditer(r"^```python\n(.*?)^```", guide.read_text(), re.M | re.S)]
    assert len(blocks) >= 8, len(blocks)
    problems, seen = [], 0
    for guide, m in blocks:
        line0 = guide.read_text().count("\n", 0, m.start(1)) + 1
        for node in ast.walk(ast.parse(m.group(1))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ("boresight", "orbits"):
                names = [(node.module, a.name) for a in node.names]
            elif isinstance(node, ast.Import):
                names = [(a.name, None) for a in node.names if a.name.split(".")[0] in ("boresight", "orbits")]
            else:
                continue
            for module, name in names:
                seen += 1
                try:
                    mod = importlib.import_module(module)
                except ImportError as exc:
                    problems.append(f"{guide.relative_to(ROOT)}:{line0 + node.lineno - 1}: {module}: {exc}")
                    continue
                if name is not None and not hasattr(mod, name):
                    try:
                        importlib.import_module(f"{module}.{name}")  # a submodule
                    except ImportError:
                        problems.append(f"{guide.relative_to(ROOT)}:{line0 + node.lineno - 1}: {module} has no {name}")
    assert seen > 10, seen
    assert problems == [], "\n".join(problems)


#: ``Class.attribute`` the guides mention only to say it is gone (history, kept on purpose)
DELETED_ATTRIBUTES = {"ObservationSet.dense_view"}


def _class_attribute_problems() -> list[str]:
    """``Class.attribute`` in backticks, for a class defined in boresight/ or orbits/: the attribute is a method,
    property, dataclass field, named-tuple field, annotation or an attribute its class body sets (``self.name``)."""
    import importlib
    import inspect

    defined: dict = {}
    for top in ("boresight", "orbits"):
        for path in sorted((ROOT / top).rglob("*.py")):
            module = ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
            for m in re.finditer(r"^class ([A-Z]\w*)", path.read_text(), re.M):
                defined.setdefault(m.group(1), []).append(module)

    def has(cls, attr: str) -> bool:
        if hasattr(cls, attr) or attr in getattr(cls, "__dataclass_fields__", {}) or attr in getattr(cls, "_fields", ()):
            return True
        return any(attr in getattr(c, "__annotations__", {}) for c in cls.__mro__) or any(
            re.search(rf"self\.{attr}\b", inspect.getsource(c))
            for c in cls.__mro__
            if c.__module__.startswith(("boresight", "orbits"))
        )

    problems = []
    for guide in GUIDES:
        text = guide.read_text()
        for span in re.finditer(r"`([^`\n]+)`", text):
            for m in re.finditer(r"(?<![\w.])([A-Z]\w+)\.([a-z_]\w*)", span.group(1)):
                name, attr = m.groups()
                if name not in defined or f"{name}.{attr}" in DELETED_ATTRIBUTES:
                    continue
                classes = [getattr(importlib.import_module(mod), name, None) for mod in defined[name]]
                if not any(c is not None and has(c, attr) for c in classes):
                    problems.append(f"{guide.relative_to(ROOT)}:{text.count(chr(10), 0, span.start()) + 1}: `{name}.{attr}`")
    return problems


def test_every_class_attribute_the_guides_name_exists():
    """``ObservationSet.landmark_sight``, ``Estimate.chi2_text``, ``RowFit.condition_bound`` …: each
    ``Class.attribute`` a guide gives, for a class of the package, is one the class has."""
    assert _class_attribute_problems() == []


def test_the_reliability_guide_lists_every_error_class():
    """docs/reliability.md's table of the one error hierarchy names every typed error of ``orbits.errors`` and
    ``boresight.errors``, and its list of the classes that are not also a ``ValueError`` is exactly those."""
    import boresight.errors
    import orbits.errors

    classes = {
        c
        for module in (orbits.errors, boresight.errors)
        for c in vars(module).values()
        if isinstance(c, type) and issubclass(c, orbits.errors.BoresightError) and c is not orbits.errors.BoresightError
    }
    text = (ROOT / "docs" / "reliability.md").read_text()
    table = text[text.index("| class | where | raised for |") :].split("\n\n", 1)[0]
    assert sorted(c.__name__ for c in classes if f"`{c.__name__}`" not in table) == []
    not_value_errors = sorted(c.__name__ for c in classes if not issubclass(c, ValueError))
    sentence = " ".join(text.split()).split('The exceptions to "also a `ValueError`":', 1)[1].split(". ", 1)[0]
    listed = sorted(set(re.findall(r"`(\w+Error)`", sentence)) & {c.__name__ for c in classes})  # not the builtins named
    assert listed == not_value_errors, (sentence, not_value_errors)
