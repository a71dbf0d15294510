"""The plain-text progress bar of the study commands."""

from __future__ import annotations

import sys
import time

from boresight.studies.montecarlo.preflight import format_preflight


class ProgressBar:
    """A plain-text progress bar with ETA on stderr: ``progress(done, total)``.

    >>> import io
    >>> buf = io.StringIO()
    >>> bar = ProgressBar(stream=buf, width=10)
    >>> bar(50, 100); bar(100, 100)
    >>> buf.getvalue().splitlines()[-1].startswith("[##########] 100%")
    True
    """

    def __init__(self, stream=None, width: int = 30, label: str = ""):
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.label = label
        self.t0 = time.perf_counter()

    def preflight(self, pf: dict):
        """Print the study's pre-flight line (``format_preflight``; ``montecarlo_study(preflight=…)``) before the bar."""
        self.stream.write(format_preflight(pf) + "\n")
        self.stream.flush()
        self.t0 = time.perf_counter()

    def __call__(self, done, total):
        el = time.perf_counter() - self.t0
        frac = done / total if total else 1.0
        eta = el * (1 - frac) / frac if frac > 0 else float("nan")
        n = int(round(self.width * frac))
        head = f"[{'#' * n}{'.' * (self.width - n)}] {100 * frac:3.0f}% {done}/{total} runs "
        tail = f" elapsed {el:.1f} s ETA {eta:.1f} s"
        room = max(0, 100 - len(head) - len(tail))  # the line stays ≤ 100 columns: a long label is shortened
        label = self.label if len(self.label) <= room else self.label[: max(0, room - 1)] + "…"
        msg = head + label + tail
        end = "\n" if done >= total else ""
        self.stream.write("\r" + msg + end)
        self.stream.flush()
