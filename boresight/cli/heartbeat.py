"""A heartbeat for commands that work for more than a couple of seconds without a progress bar.

``with heartbeat("reproduce kiev2012: eq 28 study and Kalman table"):`` prints, on stderr, one
line after ``first_s`` seconds and then every ``every_s`` seconds — ``… still working, 12 s
elapsed`` — and a closing ``… done in 31 s`` if it printed anything. A command that finishes
within ``first_s`` prints nothing. The lines go to stderr so stdout stays the command's result.

DECISION: a daemon thread waiting on an Event (no signal handlers, nothing to clean up if the
command raises); the work itself is not touched, so its numbers cannot change.

>>> import io, time
>>> buf = io.StringIO()
>>> with heartbeat("demo", first_s=0.01, every_s=10, stream=buf):
...     time.sleep(0.2)
>>> buf.getvalue().splitlines()[0].startswith("demo: still working, ")
True
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time

__all__ = ["heartbeat"]


@contextlib.contextmanager
def heartbeat(label: str, first_s: float = 2.0, every_s: float = 10.0, stream=None):
    out = sys.stderr if stream is None else stream
    stop = threading.Event()
    t0 = time.perf_counter()
    printed = []

    def beat():
        wait = first_s
        while not stop.wait(wait):
            print(f"{label}: still working, {time.perf_counter() - t0:.0f} s elapsed", file=out, flush=True)
            printed.append(True)
            wait = every_s

    th = threading.Thread(target=beat, name="boresight-heartbeat", daemon=True)
    th.start()
    try:
        yield
    finally:
        stop.set()
        th.join(timeout=1.0)
        if printed:
            print(f"{label}: done in {time.perf_counter() - t0:.0f} s", file=out, flush=True)
