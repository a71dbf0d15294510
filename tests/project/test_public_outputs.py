"""Public outputs equal the committed references (``tests/reference_outputs/``), text exactly, numbers
within a stated tolerance.

Every command that writes results — ``reproduce kiev2012``, ``montecarlo``, ``sensitivity``,
``simulate``, ``estimate`` (a 6-pass campaign with a floated effect: the campaign GLS), ``diagnose``,
``plan`` and ``ingest`` — is run in-process with fixed seeds and small run counts, and every file it
writes (ECSV, JSON, Markdown) and everything it prints is compared with the references. A case may be
several commands in a row (simulate a file, then estimate it); their printed text is concatenated.
A refactoring (moving code between modules, renaming internals, a faster route to the same numbers)
must leave them unchanged.

DECISION (cross-CPU): floating-point results are reproducible on one machine, not across BLAS
kernels. OpenBLAS picks a kernel per CPU (Haswell, SkylakeX with AVX-512, Zen), and their sums
differ in the last bits: a Cramér–Rao value 8.410872189637715 on one is …798 on another. So the
comparison splits every text into its non-numeric skeleton, which must match EXACTLY (keys, column
names, words, layout, the count and order of numbers), and its numbers, which must agree to

    |a − b| ≤ REL_TOL · max(|a|, |b|) + ABS_TOL,   REL_TOL = 1e-9, ABS_TOL = 1e-11,

or, for a number printed with fewer digits than it carries, differ by at most one unit in its last
printed digit (a value within 1e-9 of a rounding boundary can round either way). 1e-9 is six orders
above the kernel-to-kernel differences seen (≤ 1e-13 relative) and far below anything a real change
of the mathematics produces (≥ 1e-6 relative in every mutation tried). ABS_TOL serves the numbers
that are small differences of large ones: a residual (~1e-6 m on the focal plane) is the difference
of two image coordinates of ~0.06 m, so the kernels' last-bit differences in θ reach it as up to
2e-12 m (seen on ``estimate-campaign``'s residuals.ecsv: rel 2.3e-9); 1e-11 m is 3e-6 of the 3 µm
pixel noise.

The planner (``plan-kiev680``) is compared at ``CASE_REL_TOL`` = 1e-7: its front holds campaigns whose
information is nearly singular (condition numbers up to 1e8, the planner's own ``SINGULAR_VARIANCE``
flag), and their σθ carry kernel-to-kernel differences up to cond · eps ≈ 1e8 · 2.2e-16 ≈ 2e-8 relative
(seen: 3393.19983 vs 3393.19987″, rel 1.2e-8, for a one-pass campaign's θ alone). Byte identity is kept where
it is promised on one machine: resume, chunk sizes and worker counts (``test_study_resume``,
``test_montecarlo``). ``test_public_outputs_under_every_blas_kernel`` runs this comparison in
subprocesses under ``OPENBLAS_CORETYPE`` = SkylakeX, Haswell and Zen (each one the CPU supports).

Normalised before the comparison, because they are genuinely volatile (nothing else is):

* ``elapsed_s``, ``versions`` and ``argv`` in the JSON files, at any depth (wall time; python/numpy/... versions;
  the process's command line, which is pytest's when run here);
* the wall time printed at the end of the summary line (``…; 0.04 s`` → ``…; <elapsed> s``);
* the temporary output folder, wherever it appears (printed paths, ``argv``) → ``<OUT>``, and the
  checkout's root (``ingest --example`` prints where the shipped files are) → ``<ROOT>``;
* ``plan``'s own timings: ``blocks_s``/``score_s`` in plan.json, "blocks … s, scoring … s" in
  summary.md and "in … s (blocks … s)" on the terminal.

Not compared: the PNG figures (their bytes depend on the matplotlib and FreeType versions).

When a change of a public output is INTENDED, regenerate the references and say so in the commit::

    python tests/project/test_public_outputs.py [CASE ...]   # rewrites tests/reference_outputs/[CASE]

and review ``git diff tests/reference_outputs`` — it must show exactly the intended change.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import sys
import tempfile
from pathlib import Path

import pytest

if __name__ == "__main__":  # run as a script (regenerating): the shared test helpers live one folder up
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from paths import ROOT  # noqa: E402
from study_argv import quiet_study  # noqa: E402

REFERENCE = ROOT / "tests" / "reference_outputs"

# name -> argv (OUT is replaced by the output folder). Seeds fixed, runs small, one worker.
CASES = {
    "montecarlo-sensitivity": quiet_study("montecarlo", "scenarios/kiev2012-sensitivity.toml", runs=2000, seed=3, out="OUT"),
    "montecarlo-kalman20": quiet_study("montecarlo", "scenarios/kiev2012-kalman20.toml", runs=1000, seed=5, out="OUT"),
    "sensitivity": quiet_study(
        "sensitivity", "scenarios/kiev2012-sensitivity.toml", "--algorithm", "image_plane", runs=2000, seed=3, out="OUT"
    ),
    "reproduce-kiev2012": [
        "reproduce",
        "kiev2012",
        "--runs",
        "1000",
        "--kalman-runs",
        "200",
        "--workers",
        "1",
        "--template",
        "docs/reproduction.md",
        "--out",
        "OUT",
    ],
    "estimate-campaign": [
        ["simulate", "scenarios/campaign-6pass.toml", "--seed", "11", "--out", "OUT"],
        [
            "estimate",
            "OUT/campaign-6pass.ecsv",
            "--effects",
            "time_tag",
            "--out",
            "OUT",
            "--no-plots",
            "--json",
            "OUT/estimate.json",
        ],
    ],
    "diagnose": [
        ["simulate", "scenarios/diagnose-example.toml", "--seed", "2", "--out", "OUT"],
        ["diagnose", "OUT/diagnose-example.ecsv", "--out", "OUT", "--no-plots", "--quiet"],
    ],
    "plan-kiev680": ["plan", "kiev680", "--out", "OUT", "--no-plots", "--quiet"],
    "ingest-flight-pass": ["ingest", "--example", "flight-pass", "--out", "OUT/flight.ecsv", "--quiet"],
}
VOLATILE_JSON_KEYS = ("elapsed_s", "versions", "argv", "blocks_s", "score_s")
REL_TOL = 1e-9
ABS_TOL = 1e-11
#: a looser relative tolerance for the cases whose outputs include ill-conditioned quantities (docstring)
CASE_REL_TOL = {"plan-kiev680": 1e-7}
#: a number as it appears in text: sign, digits, optional fraction and exponent (also inf/nan words stay text)
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: OpenBLAS kernels the comparison is run under, with the CPU flag each needs
BLAS_CORETYPES = {"SkylakeX": "avx512f", "Haswell": "avx2", "Zen": "avx2"}
COMPARED_SUFFIXES = (".ecsv", ".json", ".md")


_PLAN_TIMINGS = (
    re.compile(r"(blocks )\d+\.\d+( s, scoring )\d+\.\d+( s)"),
    re.compile(r"( scored in )\d+\.\d+( s \(blocks )\d+\.\d+( s\))"),
)


def _normalise(text: str, out: Path) -> str:
    text = text.replace(str(out), "<OUT>").replace(str(ROOT), "<ROOT>")
    for pattern in _PLAN_TIMINGS:
        text = pattern.sub(r"\1<s>\2<s>\3", text)
    return re.sub(r"(\d+ runs per case, seed \d+, |; )\d+\.\d+ s$", r"\1<elapsed> s", text, flags=re.M)


def _normalise_json(text: str, out: Path) -> str:
    def scrub(v):
        if isinstance(v, dict):
            return {k: "<volatile>" if k in VOLATILE_JSON_KEYS else scrub(x) for k, x in v.items()}
        return [scrub(x) for x in v] if isinstance(v, list) else v

    return _normalise(json.dumps(scrub(json.loads(text)), indent=2, ensure_ascii=False) + "\n", out)


def run_case(name: str, out: Path) -> dict[str, str]:
    """Run one case with its output in ``out``; return {file name: normalised text}, stdout included."""
    from boresight.cli.main import main

    case = CASES[name]
    steps = case if isinstance(case[0], list) else [case]
    buf = io.StringIO()
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        for step in steps:
            argv = [a.replace("OUT", str(out)) if a.startswith("OUT") else a for a in step]
            with contextlib.redirect_stdout(buf):
                code = main(argv)
            assert code == 0, f"boresight {' '.join(argv)} exited with {code}"
    finally:
        os.chdir(cwd)
    files = {"stdout.txt": _normalise(buf.getvalue(), out)}
    for p in sorted(out.iterdir()):
        if p.suffix not in COMPARED_SUFFIXES:
            continue
        text = p.read_text()
        files[p.name] = _normalise_json(text, out) if p.suffix == ".json" else _normalise(text, out)
    return files


def _last_digit_unit(token: str) -> float:
    """One unit in the last printed digit of ``token`` (``"6.09"`` → 0.01, ``"1.5e-03"`` → 1e-4)."""
    mant, _, exp = token.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 10.0 ** (-decimals + (int(exp) if exp else 0))


def numbers_agree(a: str, b: str, rel_tol: float = REL_TOL) -> bool:
    """Two printed numbers agree within the module's stated tolerance (see the docstring)."""
    x, y = float(a), float(b)
    if abs(x - y) <= rel_tol * max(abs(x), abs(y)) + ABS_TOL:
        return True
    # rounding-boundary flip: the same printed precision and one unit apart in the last digit
    unit = _last_digit_unit(a)
    return unit == _last_digit_unit(b) and unit > rel_tol * max(abs(x), abs(y)) and abs(x - y) <= 1.000001 * unit


def compare_text(got: str, expected: str, rel_tol: float = REL_TOL) -> str | None:
    """None if ``got`` equals ``expected`` (skeleton exactly, numbers within tolerance); else why not."""
    skel_got, skel_exp = _NUMBER.split(got), _NUMBER.split(expected)
    if skel_got != skel_exp:
        for i, (g, e) in enumerate(zip(skel_got, skel_exp)):
            if g != e:
                return f"text differs near number {i}: got {g[:80]!r}, expected {e[:80]!r}"
        return f"text differs: {len(skel_got)} vs {len(skel_exp)} parts"
    for i, (g, e) in enumerate(zip(_NUMBER.findall(got), _NUMBER.findall(expected))):
        if g != e and not numbers_agree(g, e, rel_tol):
            context = skel_exp[i][-60:]
            return f"number {i} (after {context!r}): got {g}, expected {e} (beyond rel {rel_tol:g})"
    return None


def compare_case(name: str, out: Path) -> list[str]:
    """Run one case and compare it with its references; the list of differences (empty if equal)."""
    ref_dir = REFERENCE / name
    expected = {p.name: p.read_text() for p in sorted(ref_dir.iterdir())}
    got = run_case(name, out)
    if sorted(got) != sorted(expected):
        return [f"{name}: files written {sorted(got)} differ from {sorted(expected)} in {ref_dir}"]
    problems = []
    for fname, text in got.items():
        why = compare_text(text, expected[fname], CASE_REL_TOL.get(name, REL_TOL))
        if why:
            problems.append(f"{name}/{fname}: {why}")
    return problems


@pytest.mark.parametrize("name", sorted(CASES))
def test_public_output_matches_reference(name, tmp_path):
    problems = compare_case(name, tmp_path / "out")
    assert not problems, (
        "\n".join(problems) + "\nA public output changed beyond floating-point tolerance. If (and only if) "
        "the change is intended, regenerate with `python tests/project/test_public_outputs.py` and review the diff."
    )


def test_comparison_can_fail():
    """The tolerance is tight enough to catch a real change and loose enough for a BLAS kernel's last bits."""
    assert compare_text("σ = 8.410872189637715 s", "σ = 8.410872189637798 s") is None
    assert compare_text("6.09 ″", "6.10 ″") is None  # a rounding-boundary flip in the last printed digit
    assert compare_text("σ = 8.410872 s", "σ = 8.410890 s") is not None  # 2e-6 relative: a real change
    assert compare_text("6.09 ″", "6.11 ″") is not None
    assert compare_text("σ = 8.41 s", "σ = 8.41 m") is not None  # the text is compared exactly
    assert compare_text("[1, 2]", "[1, 2, 3]") is not None
    assert compare_text("3393.1998317383004", "3393.1998708237174", 1e-7) is None  # the planner's ill-conditioned σθ
    assert compare_text("3393.1998317383004", "3393.2025", 1e-7) is not None  # 8e-7 relative: a real change


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    return {f for line in text.splitlines() if line.startswith("flags") for f in line.split(":", 1)[1].split()}


@pytest.mark.parametrize("coretype", sorted(BLAS_CORETYPES))
def test_public_outputs_under_every_blas_kernel(coretype, tmp_path):
    """The comparison passes whichever OpenBLAS kernel the CPU would pick (a fresh process per kernel)."""
    import subprocess

    flags = _cpu_flags()
    if not flags:
        pytest.skip("no /proc/cpuinfo: cannot tell which OpenBLAS kernels this CPU runs")
    if BLAS_CORETYPES[coretype] not in flags:
        pytest.skip(f"this CPU lacks {BLAS_CORETYPES[coretype]}, which OpenBLAS's {coretype} kernel needs")
    env = dict(os.environ, OPENBLAS_CORETYPE=coretype, PYTHONPATH=str(ROOT))
    cases = ["montecarlo-kalman20", "montecarlo-sensitivity", "sensitivity", "estimate-campaign", "diagnose"]  # BLAS-heavy
    proc = subprocess.run(
        [sys.executable, __file__, "--compare", str(tmp_path), *cases], env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, f"OPENBLAS_CORETYPE={coretype}:\n{proc.stdout}\n{proc.stderr[-3000:]}"


def regenerate(names: list[str]) -> None:
    unknown = sorted(set(names) - set(CASES))
    if unknown:
        sys.exit(f"unknown case(s) {unknown}; the cases are {sorted(CASES)}")
    for name in names or sorted(CASES):
        with tempfile.TemporaryDirectory() as tmp:
            files = run_case(name, Path(tmp) / "out")
        ref_dir = REFERENCE / name
        ref_dir.mkdir(parents=True, exist_ok=True)
        for old in ref_dir.iterdir():
            old.unlink()
        for fname, text in files.items():
            (ref_dir / fname).write_bytes(text.encode())
        print(f"wrote {ref_dir} ({len(files)} files)", file=sys.stderr)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    if sys.argv[1:2] == ["--compare"]:  # used by test_public_outputs_under_every_blas_kernel
        where = Path(sys.argv[2])
        found = [p for name in sys.argv[3:] for p in compare_case(name, where / name)]
        print("\n".join(found) or "equal")
        sys.exit(1 if found else 0)
    regenerate(sys.argv[1:])
