"""How the benchmarks time a computation: the median of repeated timings of one call.

The machine is shared (other processes come and go), so a single timing is noisy and a mean is pulled by
the slowest run; the median of ``repeats`` timings is what ``bench_effects.py``, ``bench_pushbroom.py``,
``bench_line_scan.py`` and ``bench_stars.py`` quote. ``clock`` chooses what is measured: ``time.perf_counter`` (wall time, the default)
or ``time.process_time`` (this process's CPU time, blind to what other processes take).

>>> median_time(lambda: None, 3) >= 0.0
True
>>> import math
>>> math.isnan(median_time(lambda: None, 0))
True
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def median_time(f: Callable[[], object], repeats: int, clock: Callable[[], float] = time.perf_counter) -> float:
    """The median of ``repeats`` timings (s, by ``clock``) of ``f()``; NaN when ``repeats`` is 0 (nothing timed)."""
    ts = []
    for _ in range(repeats):
        t = clock()
        f()
        ts.append(clock() - t)
    return float(np.median(ts)) if ts else float("nan")
