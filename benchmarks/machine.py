"""Where a benchmark's figures were taken: CPU model, its widest SIMD level, the BLAS and its kernel.

A ratio measured on one machine is not a ratio on another: the eq 28 study measured 1.89× its
numba twin on one CPU and 4.2× on a CPU without AVX-512. Every ``benchmarks/bench_*.py`` prints
``machine_line()`` first, so a quoted figure always carries where it came from
(``tests/project/test_benchmarks.py`` checks that each prints it).

>>> line = machine_line()
>>> line.startswith("machine: CPU ") and "; SIMD " in line and "; BLAS " in line
True
"""

from __future__ import annotations

import os
import platform

#: the SIMD levels named, widest first, as /proc/cpuinfo's flags spell them
_SIMD = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2"), ("asimd", "NEON (ASIMD)"))


def _cpuinfo() -> dict:
    try:
        text = open("/proc/cpuinfo", encoding="utf-8").read()
    except OSError:
        return {}
    info: dict = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key in ("model name", "flags", "Features") and key not in info:
            info[key] = value.strip()
    return info


def cpu_model() -> str:
    return _cpuinfo().get("model name") or platform.processor() or platform.machine() or "unknown"


def simd_level() -> str:
    """The widest SIMD instruction set the CPU reports (Linux: /proc/cpuinfo), or "unknown"."""
    info = _cpuinfo()
    flags = set((info.get("flags") or info.get("Features") or "").split())
    return next((name for flag, name in _SIMD if flag in flags), "unknown")


def blas() -> str:
    """numpy's BLAS: library, version and the kernel it chose for this CPU (threadpoolctl)."""
    import numpy  # noqa: F401 - loads the BLAS threadpoolctl inspects

    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return "unknown (threadpoolctl not installed)"
    libs = [i for i in threadpool_info() if i.get("user_api") == "blas"]
    if not libs:
        return "unknown"
    b = libs[0]
    return f"{b.get('internal_api')} {b.get('version')} kernel {b.get('architecture') or '?'} ({b.get('num_threads')} threads)"


def machine_line() -> str:
    """One line: CPU model, logical CPUs, SIMD level, BLAS kernel, numpy version."""
    import numpy as np

    return (
        f"machine: CPU {cpu_model()} ({os.cpu_count()} logical); SIMD {simd_level()}; BLAS {blas()}; "
        f"numpy {np.__version__}, Python {platform.python_version()}"
    )


if __name__ == "__main__":
    print(machine_line())
