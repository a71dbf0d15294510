"""The one heartbeat of long commands without a progress bar (``reproduce``, ``diagnose``).

``with Heartbeat("reproduce kiev2012"):`` prints, on stderr, one line after ``first_s`` seconds and
then every ``every_s`` seconds — ``reproduce kiev2012: still working, 12 s elapsed`` — and a closing
``… done in 31 s`` if it printed anything. ``beat.stage("naming")`` names what is running; the lines
then read ``diagnose: naming … 12 s``. Work that finishes within ``first_s`` prints nothing, and
``quiet=True`` (``-q``) prints nothing at all. The lines go to stderr so stdout stays the command's
result.

DECISION: a daemon thread waiting on an Event (no signal handlers, nothing to clean up if the
command raises); the work itself is not touched, so its numbers cannot change.

>>> import io, time
>>> buf = io.StringIO()
>>> with Heartbeat("demo", first_s=0.01, every_s=10, stream=buf):
...     time.sleep(0.2)
>>> buf.getvalue().splitlines()[0].startswith("demo: still working, ")
True
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Literal

__all__ = ["Heartbeat", "heartbeat"]


class Heartbeat:
    """A progress line on ``stream`` (stderr) once the work has run ``first_s`` seconds, then every
    ``every_s`` seconds; ``stage(text)`` names what is running. A context manager."""

    def __init__(self, label: str, first_s: float = 2.0, every_s: float = 10.0, quiet: bool = False, stream: Any = None):
        self.label, self.first_s, self.every_s, self.quiet = label, first_s, every_s, quiet
        self.stream = sys.stderr if stream is None else stream
        self._stage: str | None = None
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = 0.0
        self.lines = 0

    def stage(self, text: str) -> None:
        """Name the stage now running (printed in the next line)."""
        self._stage = text

    def _line(self, text: str) -> None:
        print(text, file=self.stream, flush=True)
        self.lines += 1

    def _run(self) -> None:
        wait = self.first_s
        while not self._done.wait(wait):
            t = time.perf_counter() - self._t0
            self._line(
                f"{self.label}: {self._stage} … {t:.0f} s" if self._stage else f"{self.label}: still working, {t:.0f} s elapsed"
            )
            wait = self.every_s

    def __enter__(self) -> Heartbeat:
        self._t0 = time.perf_counter()
        if not self.quiet:
            self._thread = threading.Thread(target=self._run, name=f"{self.label}-heartbeat", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self._done.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            if self.lines:
                self._line(f"{self.label}: done in {time.perf_counter() - self._t0:.0f} s")
        return False


def heartbeat(label: str, first_s: float = 2.0, every_s: float = 10.0, stream: Any = None) -> Heartbeat:
    """``Heartbeat(label, first_s, every_s, stream=stream)``: a heartbeat with no named stages."""
    return Heartbeat(label, first_s, every_s, stream=stream)
