"""Regenerate the worked example of ``docs/discrepancy.md``: ``docs/discrepancy-example/`` and the
printed block quoted in the page.

It runs the one command the page shows,

    boresight diagnose scenarios/diagnose-example.toml --seed 1 --out docs/discrepancy-example

writes its outputs (diagnosis.json, diagnosis.md, the figures) into ``docs/discrepancy-example/``
(figures of an earlier run that this one did not write are removed), and replaces the fenced block
after "It prints" in ``docs/discrepancy.md`` with the summary lines it printed (long
``separated by`` texts cut to "…", as the page shows them). ``tests/studies/test_discrepancy_example.py``
reruns the command and compares the whole diagnosis.json, and the block, with what is committed.

Run from anywhere: ``python examples/make_discrepancy_example.py``.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = "docs/discrepancy-example"
COMMAND = ["diagnose", "scenarios/diagnose-example.toml", "--seed", "1", "--out", OUT]
DOC = ROOT / "docs/discrepancy.md"
#: the fenced block that quotes the printed summary
_BLOCK = re.compile(r"(It prints\n\n```\n)(.*?)(\n```\n)", re.S)


def summary_block(printed: str) -> str:
    """The summary lines of the command's output as the page quotes them: from ``base fit`` to the
    ``θ`` line, ``separated by:`` texts cut to "…"."""
    lines = printed.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("base fit"))
    stop = next(i for i, line in enumerate(lines) if line.startswith("θ "))
    out = []
    for line in lines[start : stop + 1]:
        if "; separated by: " in line:
            line = line.split("; separated by: ")[0] + "; separated by: …"
        out.append(line)
    return "\n".join(out)


def run(command=COMMAND, cwd=ROOT) -> str:
    """Run the ``boresight`` command in ``cwd``; returns what it printed (raises on a non-zero exit)."""
    from boresight.cli.main import main

    here = os.getcwd()
    buf = io.StringIO()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(buf):
            rc = main(list(command))
    finally:
        os.chdir(here)
    if rc != 0:
        raise SystemExit(f"boresight {' '.join(command)} exited {rc}:\n{buf.getvalue()}")
    return buf.getvalue()


def main() -> int:
    out = ROOT / OUT
    for p in out.glob("*.png"):  # the run writes every figure it makes; none of an earlier run stays
        p.unlink()
    printed = run()
    block = summary_block(printed)
    text = DOC.read_text(encoding="utf-8")
    if not _BLOCK.search(text):
        raise SystemExit(f"{DOC}: no fenced block after 'It prints' to replace")
    DOC.write_text(_BLOCK.sub(lambda m: m.group(1) + block + m.group(3), text, count=1), encoding="utf-8")
    print(printed, end="")
    print(f"updated {OUT}/ and the printed block of {DOC.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
