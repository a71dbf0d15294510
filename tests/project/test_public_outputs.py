"""Public outputs equal the committed references (``tests/reference_outputs/``), text exactly, numbers
within a stated tolerance.

The three study commands — ``reproduce kiev2012``, ``montecarlo`` and ``sensitivity`` — are run
in-process with fixed seeds and small run counts, and every file they write (ECSV, JSON,
``reproduction.md``) and everything they print is compared with the references. A refactoring
(moving code between modules, renaming internals) must leave them unchanged.

DECISION (cross-CPU): floating-point results are reproducible on one machine, not across BLAS
kernels. OpenBLAS picks a kernel per CPU (Haswell, SkylakeX with AVX-512, Zen), and their sums
differ in the last bits: a Cramér–Rao value 8.410872189637715 on one is …798 on another. So the
comparison splits every text into its non-numeric skeleton, which must match EXACTLY (keys, column
names, words, layout, the count and order of numbers), and its numbers, which must agree to

    |a − b| ≤ REL_TOL · max(|a|, |b|) + ABS_TOL,   REL_TOL = 1e-9, ABS_TOL = 1e-12,

or, for a number printed with fewer digits than it carries, differ by at most one unit in its last
printed digit (a value within 1e-9 of a rounding boundary can round either way). 1e-9 is six orders
above the kernel-to-kernel differences seen (≤ 1e-13 relative) and far below anything a real change
of the mathematics produces (≥ 1e-6 relative in every mutation tried). Byte identity is kept where
it is promised on one machine: resume, chunk sizes and worker counts (``test_study_resume``,
``test_montecarlo``). ``test_public_outputs_under_every_blas_kernel`` runs this comparison in
subprocesses under ``OPENBLAS_CORETYPE`` = SkylakeX, Haswell and Zen (each one the CPU supports).

Normalised before the comparison, because they are genuinely volatile (nothing else is):

* ``elapsed_s``, ``versions`` and ``argv`` in the JSON files (wall time; python/numpy/... versions;
  the process's command line, which is pytest's when run here);
* the wall time printed at the end of the summary line (``…; 0.04 s`` → ``…; <elapsed> s``);
* the temporary output folder, wherever it appears (printed paths, ``argv``) → ``<OUT>``.

Not compared: the PNG figures (their bytes depend on the matplotlib and FreeType versions).

When a change of a public output is INTENDED, regenerate the references and say so in the commit::

    python tests/project/test_public_outputs.py          # rewrites tests/reference_outputs/

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
REFERENCE = ROOT / "tests" / "reference_outputs"

# name -> argv (OUT is replaced by the output folder). Seeds fixed, runs small, one worker.
CASES = {
    "montecarlo-sensitivity": ["montecarlo", "scenarios/kiev2012-sensitivity.toml", "--runs", "2000", "--seed", "3",
                               "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "montecarlo-kalman20": ["montecarlo", "scenarios/kiev2012-kalman20.toml", "--runs", "1000", "--seed", "5",
                            "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "sensitivity": ["sensitivity", "scenarios/kiev2012-sensitivity.toml", "--runs", "2000", "--seed", "3",
                    "--algorithm", "image_plane", "--workers", "1", "--no-plots", "--quiet", "--out", "OUT"],
    "reproduce-kiev2012": ["reproduce", "kiev2012", "--runs", "1000", "--kalman-runs", "200", "--workers", "1",
                           "--template", "docs/reproduction.md", "--out", "OUT"],
}
VOLATILE_JSON_KEYS = ("elapsed_s", "versions", "argv")
REL_TOL = 1e-9
ABS_TOL = 1e-12
#: a number as it appears in text: sign, digits, optional fraction and exponent (also inf/nan words stay text)
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: OpenBLAS kernels the comparison is run under, with the CPU flag each needs
BLAS_CORETYPES = {"SkylakeX": "avx512f", "Haswell": "avx2", "Zen": "avx2"}
COMPARED_SUFFIXES = (".ecsv", ".json", ".md")


def _normalise(text: str, out: Path) -> str:
    text = text.replace(str(out), "<OUT>")
    return re.sub(r"(\d+ runs per case, seed \d+, |; )\d+\.\d+ s$", r"\1<elapsed> s", text, flags=re.M)


def _normalise_json(text: str, out: Path) -> str:
    d = json.loads(text)
    for k in VOLATILE_JSON_KEYS:
        if k in d:
            d[k] = "<volatile>"
    return _normalise(json.dumps(d, indent=2, ensure_ascii=False) + "\n", out)


def run_case(name: str, out: Path) -> dict[str, str]:
    """Run one case with its output in ``out``; return {file name: normalised text}, stdout included."""
    from boresight.cli.main import main

    argv = [str(out) if a == "OUT" else a for a in CASES[name]]
    buf = io.StringIO()
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        with contextlib.redirect_stdout(buf):
            code = main(argv)
    finally:
        os.chdir(cwd)
    assert code == 0, f"boresight {' '.join(argv)} exited with {code}"
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


def numbers_agree(a: str, b: str) -> bool:
    """Two printed numbers agree within the module's stated tolerance (see the docstring)."""
    x, y = float(a), float(b)
    if abs(x - y) <= REL_TOL * max(abs(x), abs(y)) + ABS_TOL:
        return True
    # rounding-boundary flip: the same printed precision and one unit apart in the last digit
    unit = _last_digit_unit(a)
    return unit == _last_digit_unit(b) and unit > REL_TOL * max(abs(x), abs(y)) and abs(x - y) <= 1.000001 * unit


def compare_text(got: str, expected: str) -> str | None:
    """None if ``got`` equals ``expected`` (skeleton exactly, numbers within tolerance); else why not."""
    skel_got, skel_exp = _NUMBER.split(got), _NUMBER.split(expected)
    if skel_got != skel_exp:
        for i, (g, e) in enumerate(zip(skel_got, skel_exp)):
            if g != e:
                return f"text differs near number {i}: got {g[:80]!r}, expected {e[:80]!r}"
        return f"text differs: {len(skel_got)} vs {len(skel_exp)} parts"
    for i, (g, e) in enumerate(zip(_NUMBER.findall(got), _NUMBER.findall(expected))):
        if g != e and not numbers_agree(g, e):
            context = skel_exp[i][-60:]
            return f"number {i} (after {context!r}): got {g}, expected {e} (beyond rel {REL_TOL:g})"
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
        why = compare_text(text, expected[fname])
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
    cases = ["montecarlo-kalman20", "montecarlo-sensitivity", "sensitivity"]  # the BLAS-heavy ones
    proc = subprocess.run([sys.executable, __file__, "--compare", str(tmp_path), *cases], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"OPENBLAS_CORETYPE={coretype}:\n{proc.stdout}\n{proc.stderr[-3000:]}"


def regenerate() -> None:
    for name in sorted(CASES):
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
    regenerate()
